//! Where a recording goes: a `.rrd` file, a running viewer, or a viewer we start.

use std::path::PathBuf;

use rerun::RecordingStream;

use crate::VizError;

/// Where a recording goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Sink {
    /// Save to this `.rrd` file.
    Save(PathBuf),
    /// Stream to a running viewer at this gRPC URL (`rerun+http://127.0.0.1:9876/proxy`).
    Connect(String),
    /// Start the viewer ([`viewer_path`]) and stream to it.
    Spawn,
}

/// The viewer binary: `$MIMICGEN_RERUN`, else `rerun` in the venv `scripts/setup.sh` makes
/// (`$MIMICGEN_CACHE/venv/bin/rerun`, default `~/.cache/mimicgen/venv/bin/rerun`).
#[must_use]
pub fn viewer_path() -> PathBuf {
    if let Some(path) = std::env::var_os("MIMICGEN_RERUN") {
        return PathBuf::from(path);
    }
    let cache = std::env::var_os("MIMICGEN_CACHE")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/mimicgen")))
        .unwrap_or_else(|| PathBuf::from(".cache/mimicgen"));
    cache.join("venv/bin/rerun")
}

impl Sink {
    /// Opens a recording of application `app_id` to this sink and sends the default blueprint.
    ///
    /// # Errors
    /// [`VizError::ViewerMissing`] for [`Sink::Spawn`] without a viewer; [`VizError::Rerun`] if the
    /// file cannot be created or the viewer not reached.
    pub fn open(&self, app_id: &'static str) -> Result<RecordingStream, VizError> {
        let builder = rerun::RecordingStreamBuilder::new(app_id);
        let rec = match self {
            Self::Save(path) => builder.save(path).map_err(|e| VizError::rerun(&path.display().to_string(), &e))?,
            Self::Connect(url) => builder.connect_grpc_opts(url.clone()).map_err(|e| VizError::rerun(url, &e))?,
            Self::Spawn => {
                let path = viewer_path();
                if !path.is_file() {
                    return Err(VizError::ViewerMissing {
                        path: path.display().to_string(),
                        hint: "run `bash scripts/setup.sh` (installs rerun-sdk into the venv), or set MIMICGEN_RERUN to a `rerun` binary"
                            .to_owned(),
                    });
                }
                let opts = rerun::SpawnOptions { executable_path: Some(path.display().to_string()), ..rerun::SpawnOptions::default() };
                builder.spawn_opts(&opts).map_err(|e| VizError::rerun("spawned viewer", &e))?
            }
        };
        send_blueprint(&rec, crate::default_blueprint())?;
        Ok(rec)
    }
}

/// Sends `blueprint` as the recording's active and default layout.
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
pub fn send_blueprint(rec: &RecordingStream, blueprint: rerun::blueprint::Blueprint) -> Result<(), VizError> {
    rec.send_blueprint_opts(&rerun::blueprint::BlueprintOpts {
        blueprint,
        activation: rerun::blueprint::BlueprintActivation { make_active: true, make_default: true },
    })
    .map_err(|e| VizError::rerun("blueprint", &e))
}
