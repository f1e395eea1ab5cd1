//! Where robosuite's model assets live locally, and re-pointing a dataset's scene XML at them.

use std::path::{Path, PathBuf};

use crate::SimError;

/// The marker every robosuite asset path contains.
const ASSETS_MARKER: &str = "robosuite/models/assets/";

/// The local copy of robosuite 1.4.1's `models/assets` unpacked by `scripts/setup.sh`:
/// `$MIMICGEN_ASSETS` if set, else `$MIMICGEN_CACHE/robosuite-1.4.1/robosuite/models/assets`, else
/// `~/.cache/mimicgen/robosuite-1.4.1/robosuite/models/assets`.
///
/// # Errors
/// [`SimError::Assets`] if the directory does not exist (with the command that creates it).
pub fn robosuite_assets_dir() -> Result<PathBuf, SimError> {
    let dir = match std::env::var_os("MIMICGEN_ASSETS") {
        Some(dir) => PathBuf::from(dir),
        None => cache_dir().join("robosuite-1.4.1/robosuite/models/assets"),
    };
    if dir.join("robots/panda/robot.xml").is_file() {
        Ok(dir)
    } else {
        Err(SimError::Assets {
            path: dir.display().to_string(),
            reason: "robosuite assets not found; run scripts/setup.sh (or set MIMICGEN_ASSETS)".to_owned(),
        })
    }
}

/// The project's cache: `$MIMICGEN_CACHE`, else `~/.cache/mimicgen` (what `scripts/setup.sh` fills).
#[must_use]
pub fn cache_dir() -> PathBuf {
    std::env::var_os("MIMICGEN_CACHE")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/mimicgen")))
        .unwrap_or_else(|| PathBuf::from(".cache/mimicgen"))
}

/// Where the robosuite asset paths of a `model_file` we write point: a machine-independent
/// location that robosuite's and MimicGen's `edit_model_xml` re-point at their own install (by the
/// last path component named `robosuite`), as we do on load. It holds no component named
/// `mimicgen`, which MimicGen's envs would re-point into the mimicgen package instead.
pub const PORTABLE_ASSETS_DIR: &str = "/robosuite/models/assets";

/// `xml` with every robosuite asset path re-pointed at [`PORTABLE_ASSETS_DIR`], so the file is the
/// same on every machine and loads in robosuite and MimicGen. Other paths are left alone.
#[must_use]
pub fn portable_asset_paths(xml: &str) -> String {
    remap_asset_paths(xml, Path::new(PORTABLE_ASSETS_DIR))
}

/// Rewrites every `file="..."` attribute that points into some machine's robosuite install so it
/// points into `assets_dir` instead. Other paths are left alone.
#[must_use]
pub fn remap_asset_paths(xml: &str, assets_dir: &Path) -> String {
    let mut out = String::with_capacity(xml.len());
    let mut rest = xml;
    let local = format!("{}/", assets_dir.display().to_string().trim_end_matches('/'));
    while let Some(start) = rest.find("file=\"") {
        let value_start = start + "file=\"".len();
        out.push_str(&rest[..value_start]);
        rest = &rest[value_start..];
        let end = rest.find('"').unwrap_or(rest.len());
        let value = &rest[..end];
        match value.find(ASSETS_MARKER) {
            Some(i) => {
                out.push_str(&local);
                out.push_str(&value[i + ASSETS_MARKER.len()..]);
            }
            None => out.push_str(value),
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn portable_paths_have_no_mimicgen_component() {
        let xml = r#"<mesh file="/root/.cache/mimicgen/robosuite-1.4.1/robosuite/models/assets/robots/panda/meshes/link0.stl"/><texture file="/x/mimicgen/models/robosuite/assets/textures/a.png"/>"#;
        let out = portable_asset_paths(xml);
        assert_eq!(
            out,
            r#"<mesh file="/robosuite/models/assets/robots/panda/meshes/link0.stl"/><texture file="/x/mimicgen/models/robosuite/assets/textures/a.png"/>"#
        );
    }

    #[test]
    fn remaps_only_robosuite_paths() {
        let xml = r#"<mesh file="/home/u/venv/lib/python3.8/site-packages/robosuite/models/assets/robots/panda/meshes/link0.stl"/><texture file="/elsewhere/x.png"/>"#;
        let out = remap_asset_paths(xml, Path::new("/cache/assets/"));
        assert_eq!(out, r#"<mesh file="/cache/assets/robots/panda/meshes/link0.stl"/><texture file="/elsewhere/x.png"/>"#);
    }
}
