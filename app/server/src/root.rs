//! The folder a server's requests stay inside: every path a request names is resolved against it,
//! and `..`, absolute paths outside it and symlinks that lead out of it are refused, naming the
//! path. One folder outside it may be read: the server's prepared copies of plain robomimic files
//! (`$MIMICGEN_CACHE/prepared`), which a tab names as `@prepared/<file>` and never by its place
//! on the server's disk; nothing is written there on a tab's request.

use std::path::{Component, Path, PathBuf};

use mimicgen_ui::protocol::{Listing, PreviewRequest, Reply, Request, ViewerSink};

use crate::ServerError;

/// How a tab names a prepared copy: `@prepared/<file name>`.
pub const PREPARED_ALIAS: &str = "@prepared";

/// The root folder (canonical), and the folder of prepared copies readable through the alias.
#[derive(Debug, Clone)]
pub struct Root {
    dir: PathBuf,
    prepared: Option<PathBuf>,
    names: PreparedNames,
}

/// Every spelling of the prepared copies' folder a message may carry: as the cache names it
/// (`$MIMICGEN_CACHE/prepared`, which may lie behind a symlink) and canonical. A tab reads the
/// alias instead of either.
#[derive(Debug, Clone, Default)]
pub struct PreparedNames(Vec<PathBuf>);

impl PreparedNames {
    /// `text` with each spelling of the folder replaced by [`PREPARED_ALIAS`].
    #[must_use]
    pub fn hide(&self, text: String) -> String {
        self.0.iter().fold(text, |text, dir| {
            let dir = dir.to_string_lossy();
            if text.contains(&*dir) { text.replace(&*dir, PREPARED_ALIAS) } else { text }
        })
    }

    /// Whether `dir` is one spelling of the folder.
    fn is(&self, dir: &Path) -> bool {
        self.0.iter().any(|d| d == dir)
    }
}

impl Root {
    /// `dir`, which must exist.
    ///
    /// # Errors
    /// [`ServerError::Root`] when it does not exist or is not a folder.
    pub fn new(dir: &Path) -> Result<Self, ServerError> {
        let root_error = |reason: String| ServerError::Root { path: dir.to_path_buf(), reason };
        let dir = dir.canonicalize().map_err(|e| root_error(e.to_string()))?;
        if !dir.is_dir() {
            return Err(root_error("not a folder".to_owned()));
        }
        Ok(Self { dir, prepared: None, names: PreparedNames::default() })
    }

    /// Lets requests read the prepared copies in `dir` (made if missing) as
    /// `@prepared/<file>`; without it (or when `dir` cannot be made) they are refused.
    #[must_use]
    pub fn with_prepared(self, dir: &Path) -> Self {
        let Ok(canonical) = std::fs::create_dir_all(dir).and_then(|()| dir.canonicalize()) else {
            return Self { prepared: None, names: PreparedNames::default(), ..self };
        };
        let mut names: Vec<PathBuf> = std::path::absolute(dir).into_iter().chain([canonical.clone()]).collect();
        // The longest first, so that no spelling is cut short by another that begins it.
        names.sort_by_key(|d| std::cmp::Reverse(d.as_os_str().len()));
        names.dedup();
        Self { prepared: Some(canonical), names: PreparedNames(names), ..self }
    }

    /// The folder.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// `path` (relative to the root, or absolute inside it) as a path inside the root, following
    /// symlinks of the part that exists.
    ///
    /// # Errors
    /// A message naming `path`: `..` in it, or it leads outside the root.
    pub fn resolve(&self, path: &Path) -> Result<PathBuf, String> {
        let outside = || format!("{}: outside the served folder {} (paths stay inside --root)", path.display(), self.dir.display());
        if path.components().any(|c| c == Component::ParentDir) {
            return Err(format!("{}: `..` is not allowed (paths stay inside --root {})", path.display(), self.dir.display()));
        }
        if path.as_os_str().is_empty() {
            return Err("an empty path".to_owned());
        }
        if path.components().next() == Some(Component::Normal(PREPARED_ALIAS.as_ref())) {
            return Err(format!("{}: `{PREPARED_ALIAS}` names the server's prepared copies, which are only read", path.display()));
        }
        let joined = if path.is_absolute() { path.to_path_buf() } else { self.dir.join(path) };
        // The longest part that exists, with its symlinks followed, and the rest (which does not
        // exist yet, so holds no symlink).
        let mut existing = joined.as_path();
        let mut rest = Vec::new();
        let canonical = loop {
            match existing.canonicalize() {
                Ok(c) => break c,
                Err(_) => {
                    rest.push(existing.file_name().ok_or_else(outside)?.to_owned());
                    existing = existing.parent().ok_or_else(outside)?;
                }
            }
        };
        if !canonical.starts_with(&self.dir) {
            return Err(outside());
        }
        Ok(rest.into_iter().rev().fold(canonical, |p, name| p.join(name)))
    }

    /// The folder of prepared copies (canonical), when requests may read them.
    #[must_use]
    pub fn prepared(&self) -> Option<&Path> {
        self.prepared.as_deref()
    }

    /// The spellings of the prepared copies' folder that messages to a tab hide.
    #[must_use]
    pub fn prepared_names(&self) -> &PreparedNames {
        &self.names
    }

    /// A file to read: `@prepared/<file>` (a prepared copy), else as [`Root::resolve`].
    ///
    /// # Errors
    /// As [`Root::resolve`]; and for `@prepared/...`, a message naming it when it is not one
    /// file name or no such copy exists.
    pub fn resolve_input(&self, path: &Path) -> Result<PathBuf, String> {
        let mut parts = path.components();
        if parts.next() != Some(Component::Normal(PREPARED_ALIAS.as_ref())) {
            return self.resolve(path);
        }
        let missing = || format!("{}: no such prepared copy (open the original file again to prepare it)", path.display());
        let (Some(Component::Normal(name)), None, Some(dir)) = (parts.next(), parts.next(), &self.prepared) else {
            return Err(missing());
        };
        let file = dir.join(name).canonicalize().map_err(|_| missing())?;
        if !file.starts_with(dir) || !file.is_file() {
            return Err(missing());
        }
        Ok(file)
    }

    /// How a tab sees `path`: a prepared copy as `@prepared/<file>`, anything else as it is.
    #[must_use]
    pub fn outward(&self, path: &Path) -> PathBuf {
        match (path.parent(), path.file_name()) {
            (Some(dir), Some(name)) if self.names.is(dir) => Path::new(PREPARED_ALIAS).join(name),
            _ => path.to_path_buf(),
        }
    }

    /// `request` with each of its paths inside the root; the 3D view streams to `viewer` (the
    /// server's own Rerun web viewer), never to a viewer the request names.
    ///
    /// # Errors
    /// A message naming the path or field refused.
    pub fn confine(&self, request: Request, viewer: Option<&str>) -> Result<Request, String> {
        let preview =
            |r: PreviewRequest| -> Result<PreviewRequest, String> { Ok(PreviewRequest { source: self.resolve_input(&r.source)?, ..r }) };
        Ok(match request {
            Request::Open { path } => Request::Open { path: self.resolve_input(&path)? },
            Request::ListDir { path } => Request::ListDir { path: self.resolve(&path)? },
            Request::OpenCompare { path } => Request::OpenCompare { path: self.resolve_input(&path)? },
            Request::OpenRun { path } => Request::OpenRun { path: self.resolve(&path)? },
            Request::Doctor { run, budget, top } => Request::Doctor { run: self.resolve(&run)?, budget, top },
            Request::Save { source, out, marks, signal_names, overwrite } => {
                Request::Save { source: self.resolve_input(&source)?, out: self.resolve(&out)?, marks, signal_names, overwrite }
            }
            Request::SaveArms { source, out, arms, overwrite } => {
                Request::SaveArms { source: self.resolve_input(&source)?, out: self.resolve(&out)?, arms, overwrite }
            }
            Request::Preview(r) => Request::Preview(Box::new(preview(*r)?)),
            Request::SideBySide(pair) => {
                let [a, b] = *pair;
                Request::SideBySide(Box::new([preview(a)?, preview(b)?]))
            }
            Request::Run(mut config) => {
                config.out = self.resolve(&config.out)?;
                config.source = config.source.map(|p| self.resolve_input(&p)).transpose()?;
                config.config = config.config.map(|p| self.resolve(&p)).transpose()?;
                Request::Run(config)
            }
            Request::Open3d { sink, demo } => {
                let sink = match sink {
                    ViewerSink::Save(path) => ViewerSink::Save(self.resolve(&path)?),
                    _ => ViewerSink::Connect(
                        viewer.ok_or("this server has no 3D view (the Rerun viewer from the rerun-sdk wheel was not found)")?.to_owned(),
                    ),
                };
                Request::Open3d { sink, demo }
            }
            other @ (Request::ShowDemo { .. } | Request::CancelRun | Request::CancelDoctor) => other,
        })
    }

    /// `reply` without what lies outside the root (a listing's parent above it, the prepared
    /// copies' folder) or means nothing to a browser (the 3D stream's loopback address).
    #[must_use]
    pub fn filter(&self, reply: Reply) -> Reply {
        match reply {
            Reply::Opened(mut file) => {
                file.path = self.outward(&file.path);
                Reply::Opened(file)
            }
            Reply::MoreDemos { path, last, demos } => Reply::MoreDemos { path: self.outward(&path), last, demos },
            Reply::Failed { what, error } => Reply::Failed { what, error: self.names.hide(error) },
            Reply::Listing(listing) => {
                let parent = listing.parent.filter(|p| p.starts_with(&self.dir));
                Reply::Listing(Box::new(Listing { parent, ..*listing }))
            }
            // The stream's loopback address means nothing in the browser: the view is beside it.
            Reply::Streaming { .. } => Reply::Streaming { to: "the viewer beside the app".to_owned() },
            other => other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_inside_resolve_and_those_leading_out_are_refused() {
        let outside = tempfile::tempdir().unwrap();
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        std::fs::write(dir.path().join("data/a.hdf5"), b"x").unwrap();
        std::fs::write(outside.path().join("secret.hdf5"), b"x").unwrap();
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(outside.path(), dir.path().join("escape")).unwrap();
            std::os::unix::fs::symlink(dir.path().join("data"), dir.path().join("inside")).unwrap();
        }
        let root = Root::new(dir.path()).unwrap();
        let canonical = dir.path().canonicalize().unwrap();
        assert_eq!(root.resolve(Path::new("data/a.hdf5")).unwrap(), canonical.join("data/a.hdf5"));
        assert_eq!(root.resolve(&canonical.join("data/a.hdf5")).unwrap(), canonical.join("data/a.hdf5"));
        // Outputs that do not exist yet, in folders that do not either.
        assert_eq!(root.resolve(Path::new("out/new/run.hdf5")).unwrap(), canonical.join("out/new/run.hdf5"));
        assert_eq!(root.resolve(Path::new(".")).unwrap(), canonical);
        for bad in ["../secret.hdf5", "data/../../x", "/etc/passwd", "/"] {
            let err = root.resolve(Path::new(bad)).unwrap_err();
            assert!(err.starts_with(bad), "{bad}: {err}");
        }
        let err = root.resolve(&outside.path().join("secret.hdf5")).unwrap_err();
        assert!(err.contains("outside the served folder"), "{err}");
        #[cfg(unix)]
        {
            for bad in ["escape/secret.hdf5", "escape", "escape/new.hdf5"] {
                let err = root.resolve(Path::new(bad)).unwrap_err();
                assert!(err.contains("outside the served folder"), "{bad}: {err}");
            }
            assert_eq!(root.resolve(Path::new("inside/a.hdf5")).unwrap(), canonical.join("data/a.hdf5"));
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_prepared_copy_is_named_by_its_alias_however_its_folder_is_spelled() {
        // The cache behind a symlink (as `~/.cache/mimicgen` may be): the backend names the copy
        // through the link, the root holds the canonical folder, and a tab sees neither.
        let dir = tempfile::tempdir().unwrap();
        let cache = tempfile::tempdir().unwrap();
        std::fs::create_dir(cache.path().join("real")).unwrap();
        std::os::unix::fs::symlink(cache.path().join("real"), cache.path().join("link")).unwrap();
        let through_link = cache.path().join("link/prepared");
        let root = Root::new(dir.path()).unwrap().with_prepared(&through_link);
        let canonical = root.prepared().unwrap().to_path_buf();
        assert_ne!(canonical, through_link);
        std::fs::write(canonical.join("lift-1.hdf5"), b"x").unwrap();
        for spelling in [&through_link, &canonical] {
            let copy = spelling.join("lift-1.hdf5");
            assert_eq!(root.outward(&copy), Path::new("@prepared/lift-1.hdf5"), "{}", copy.display());
            let said = root.prepared_names().hide(format!("{}: damaged", copy.display()));
            assert_eq!(said, "@prepared/lift-1.hdf5: damaged");
        }
        assert_eq!(root.resolve_input(Path::new("@prepared/lift-1.hdf5")).unwrap(), canonical.join("lift-1.hdf5"));
        assert_eq!(root.outward(&dir.path().join("a.hdf5")), dir.path().join("a.hdf5"), "anything else as it is");
    }

    #[test]
    fn every_path_of_a_request_is_confined_and_viewers_are_the_server_s() {
        let dir = tempfile::tempdir().unwrap();
        let root = Root::new(dir.path()).unwrap();
        let run = |out: &str, source: Option<&str>| {
            let config = mimicgen_run::RunConfig { out: out.into(), source: source.map(Into::into), ..Default::default() };
            root.confine(Request::Run(Box::new(config)), None)
        };
        assert!(run("out/a.hdf5", None).is_ok());
        assert!(run("../a.hdf5", None).unwrap_err().contains(".."));
        assert!(run("out/a.hdf5", Some("/etc/hosts")).unwrap_err().contains("/etc/hosts"));
        let save = Request::Save {
            source: "a.hdf5".into(),
            out: "/tmp/../etc/x.hdf5".into(),
            marks: Default::default(),
            signal_names: Vec::new(),
            overwrite: false,
        };
        assert!(root.confine(save, None).is_err());
        let spawn = Request::Open3d { sink: ViewerSink::Spawn, demo: 0 };
        assert!(root.confine(spawn.clone(), None).unwrap_err().contains("no 3D view"));
        let Ok(Request::Open3d { sink: ViewerSink::Connect(url), .. }) = root.confine(spawn, Some("rerun+http://127.0.0.1:1/proxy")) else {
            panic!("the server's viewer")
        };
        assert_eq!(url, "rerun+http://127.0.0.1:1/proxy");
        let connect = Request::Open3d { sink: ViewerSink::Connect("rerun+http://10.0.0.1:9876/proxy".into()), demo: 0 };
        let Ok(Request::Open3d { sink: ViewerSink::Connect(url), .. }) = root.confine(connect, Some("rerun+http://127.0.0.1:1/proxy"))
        else {
            panic!("the server's viewer")
        };
        assert!(url.starts_with("rerun+http://127.0.0.1"), "a request never picks where the server connects");
    }
}
