//! Fuzz harnesses: what each `cargo fuzz` target (`fuzz/fuzz_targets/`) runs on one input, and
//! what `tests/fuzz_corpus.rs` runs on every saved corpus file and crash reproducer in CI. Each
//! harness panics when the reader does (a bug) or when it refuses the input without naming the
//! file (the errors' contract); a refusal that names it is a pass.
#![allow(
    clippy::indexing_slicing,
    reason = "test support: the edits index arrays they just sized, and a panic fails the run as a bug would"
)]

use std::path::Path;

use mimicgen_engine::TaskSpec;
use mimicgen_engine::spec::SourceSelection;
use mimicgen_io::RobomimicDataset;
use mimicgen_io::tree::{Array, Group, Node, Values};
use mimicgen_sim::task::Task as _;
use mimicgen_sim::{DataTask, TaskFile};
use rand::SeedableRng as _;

/// The name the text harnesses give their input; every refusal must name it.
pub const ORIGIN_TOML: &str = "fuzz_input.toml";
/// As [`ORIGIN_TOML`], for MimicGen JSON.
pub const ORIGIN_JSON: &str = "fuzz_input.json";
/// As [`ORIGIN_TOML`], for task files.
pub const ORIGIN_TASK: &str = "fuzz_input.task.toml";

/// Fails (panics) when `error`, a refusal by `what`, does not name `origin`.
///
/// # Panics
/// As said.
pub fn check_names(what: &str, error: &str, origin: &str) {
    assert!(error.contains(origin), "{what} refused the input without naming it ({origin}): {error}");
}

/// Our TOML spec reader on `data`.
pub fn spec_toml(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Err(e) = TaskSpec::from_toml_str(text, ORIGIN_TOML) {
        check_names("the TOML spec reader", &e.to_string(), ORIGIN_TOML);
    }
}

/// The MimicGen experiment JSON reader on `data`; what it accepts must also write as TOML and read
/// back the same.
pub fn spec_json(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match TaskSpec::from_mimicgen_json_str(text, ORIGIN_JSON) {
        Err(e) => check_names("the MimicGen JSON reader", &e.to_string(), ORIGIN_JSON),
        Ok(spec) => {
            let toml = spec.to_toml_string().unwrap_or_else(|e| panic!("an accepted spec does not write as TOML: {e}"));
            let back = TaskSpec::from_toml_str(&toml, ORIGIN_TOML).unwrap_or_else(|e| panic!("its TOML does not read back: {e}\n{toml}"));
            assert_eq!(back, spec, "the TOML of an accepted spec reads back differently");
        }
    }
}

/// The task-file reader on `data`; every variant of a file it accepts is made a task and draws
/// a scene.
pub fn task_file(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let file = match TaskFile::from_toml_str(text, ORIGIN_TASK) {
        Ok(file) => file,
        Err(e) => return check_names("the task-file reader", &e, ORIGIN_TASK),
    };
    for variant in file.variants.clone() {
        let Ok(task) = DataTask::new(file.clone(), &variant) else { continue };
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let _ = task.sample_scene(&mut rng, None);
        let _ = task.objects();
    }
}

/// Reads bytes as a list of small choices.
struct Choices<'a>(&'a [u8]);

impl Choices<'_> {
    fn next(&mut self) -> Option<usize> {
        let (&first, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(usize::from(first))
    }
}

/// Every node path below `group` (`data/demo_0/actions`), groups before their members.
fn paths(group: &Group, prefix: &str, out: &mut Vec<String>) {
    for (name, node) in &group.members {
        let path = if prefix.is_empty() { name.clone() } else { format!("{prefix}/{name}") };
        out.push(path.clone());
        if let Node::Group(g) = node {
            paths(g, &path, out);
        }
    }
}

/// The parent group of `path` and its last name.
fn parent_mut<'a>(root: &'a mut Group, path: &'a str) -> Option<(&'a mut Group, &'a str)> {
    let (dirs, leaf) = path.rsplit_once('/').map_or(("", path), |(d, l)| (d, l));
    let mut group = root;
    for part in dirs.split('/').filter(|p| !p.is_empty()) {
        group = match group.members.get_mut(part)? {
            Node::Group(g) => g,
            Node::Dataset(_) => return None,
        };
    }
    Some((group, leaf))
}

/// Keeps the first `rows` rows of `array` (a shape and values that still agree).
fn truncate(array: &mut Array, rows: usize) {
    let Some(&n) = array.shape.first() else { return };
    let per_row: usize = array.shape[1..].iter().product();
    let keep = rows.min(n);
    let len = keep * per_row;
    macro_rules! cut {
        ($($v:ident),*) => {
            match &mut array.values {
                $(Values::$v(v) => v.truncate(len),)*
                Values::Fixed { strings, .. } => strings.truncate(len),
            }
        };
    }
    cut!(F64, F32, I64, I32, I16, I8, U64, U32, U16, U8, Bool, Utf8, Ascii);
    array.shape[0] = keep;
}

/// Applies up to four edits that `choices` pick to `root`: what a broken or hand-edited file
/// holds, always a file HDF5 can store (shapes agree with values).
fn mutate(root: &mut Group, choices: &mut Choices<'_>) {
    for _ in 0..4 {
        let mut all = Vec::new();
        paths(root, "", &mut all);
        let (Some(op), Some(which), Some(arg)) = (choices.next(), choices.next(), choices.next()) else { return };
        let Some(path) = all.get(which * all.len() / 256).cloned() else { return };
        let Some((parent, leaf)) = parent_mut(root, &path) else { continue };
        let leaf = leaf.to_owned();
        match (op % 8, parent.members.get_mut(&leaf)) {
            (0, Some(_)) => {
                parent.members.remove(&leaf);
            }
            (1, Some(Node::Dataset(d))) => truncate(&mut d.array, arg % 4),
            (2, Some(Node::Dataset(d))) => {
                let bad = [f64::NAN, f64::INFINITY, -1.0e300, 0.0][arg % 4];
                let at = arg % d.array.values.len().max(1);
                match &mut d.array.values {
                    Values::F64(v) => v.get_mut(at).into_iter().for_each(|x| *x = bad),
                    #[allow(clippy::cast_possible_truncation)]
                    Values::F32(v) => v.get_mut(at).into_iter().for_each(|x| *x = bad as f32),
                    Values::I64(v) => v.get_mut(at).into_iter().for_each(|x| *x = [-1, i64::MAX, i64::MIN, 1 << 40][arg % 4]),
                    _ => {}
                }
            }
            (3, Some(Node::Dataset(d))) => d.array = Array::string("not a number"),
            (4, Some(node)) => {
                let attrs = match node {
                    Node::Group(g) => &mut g.attrs,
                    Node::Dataset(d) => &mut d.attrs,
                };
                if let Some(key) = attrs.keys().nth(arg % attrs.len().max(1)).cloned() {
                    attrs.remove(&key);
                }
            }
            (5, Some(node)) => {
                let attrs = match node {
                    Node::Group(g) => &mut g.attrs,
                    Node::Dataset(d) => &mut d.attrs,
                };
                let junk = [Array::string("{not json"), Array::int(-7), Array::f64(vec![2], vec![f64::NAN, 1.0])][arg % 3].clone();
                if let Some(key) = attrs.keys().nth(arg % attrs.len().max(1)).cloned() {
                    attrs.insert(key, junk);
                }
            }
            (6, Some(Node::Dataset(d))) => {
                let len = d.array.values.len();
                d.array.shape = vec![len];
            }
            (7, Some(_)) => {
                if let Some(node) = parent.members.remove(&leaf) {
                    parent.members.insert(format!("{leaf}_{arg}"), node);
                }
            }
            _ => {}
        }
    }
}

/// The HDF5 dataset reader on a mutated copy of `seed` (a source-demo file): `data` picks the
/// edits (see `mutate`: drop, cut, poison, retype, rename); the copy is written to `scratch` and read back as a whole file and as
/// MimicGen source demos. Refusals must name the file.
///
/// # Panics
/// When the reader panics, or refuses without naming the file.
pub fn dataset(seed: &Group, data: &[u8], scratch: &Path) {
    let mut root = seed.clone();
    mutate(&mut root, &mut Choices(data));
    if data.is_empty() {
        // The unedited seed is a valid source file: it must read back whole.
        mimicgen_io::dataset::write_tree(scratch, &root).unwrap_or_else(|e| panic!("{e}"));
        let read = RobomimicDataset::open(scratch).and_then(|d| d.to_source_dataset(&SourceSelection::default()));
        let demos = read.unwrap_or_else(|e| panic!("the seed does not read back: {e}")).demos;
        assert_eq!(demos.iter().map(mimicgen_engine::SourceDemo::len).collect::<Vec<_>>(), [SEED_STEPS, SEED_STEPS]);
        return;
    }
    if let Err(e) = mimicgen_io::dataset::write_tree(scratch, &root) {
        // Our writer refusing what the edits made is not the reader's business; it must still say where.
        return check_names("the tree writer", &e.to_string(), &scratch.display().to_string());
    }
    read_back(scratch);
}

/// Most byte edits [`dataset_bytes`] applies to one copy.
const MAX_BYTE_EDITS: usize = 64;

/// The HDF5 reader on a byte-level mutation of `seed`, the bytes of the [`dataset_seed`] file as
/// our writer wrote it ([`dataset_seed_bytes`]): `data` is a list of 5-byte edits, each a
/// little-endian offset (wrapped to the file's length) and the byte to write there. Unlike
/// [`dataset`]'s edits, which our writer turns into well-formed files, these reach libhdf5's own
/// parser (superblock, object headers, B-trees, heaps) before ours. Refusals must name the file.
///
/// # Panics
/// When a reader panics, refuses without naming the file, or the unedited seed does not read
/// back whole.
pub fn dataset_bytes(seed: &[u8], data: &[u8], scratch: &Path) {
    let mut bytes = seed.to_vec();
    let len = bytes.len().max(1);
    for edit in data.chunks_exact(5).take(MAX_BYTE_EDITS) {
        if let &[a, b, c, d, value] = edit
            && let Some(byte) = bytes.get_mut(usize::try_from(u32::from_le_bytes([a, b, c, d])).unwrap_or_default() % len)
        {
            *byte = value;
        }
    }
    std::fs::write(scratch, &bytes).unwrap_or_else(|e| panic!("writing the scratch file {}: {e}", scratch.display()));
    if data.len() < 5 {
        let read = RobomimicDataset::open(scratch).and_then(|d| d.to_source_dataset(&SourceSelection::default()));
        let demos = read.unwrap_or_else(|e| panic!("the seed's bytes do not read back: {e}")).demos;
        assert_eq!(demos.iter().map(mimicgen_engine::SourceDemo::len).collect::<Vec<_>>(), [SEED_STEPS, SEED_STEPS]);
        return;
    }
    read_back(scratch);
}

/// Reads the file at `scratch` every way a user's file is read: whole, as MimicGen source demos,
/// and demo by demo as a run streams them.
fn read_back(scratch: &Path) {
    let file = scratch.display().to_string();
    let opened = match RobomimicDataset::open(scratch) {
        Ok(d) => d,
        Err(e) => return check_names("the dataset reader", &e.to_string(), &file),
    };
    if let Err(e) = opened.to_source_dataset(&SourceSelection::default()) {
        check_names("the source-demo reader", &e.to_string(), &file);
    }
    match mimicgen_io::DemoReader::open_with(scratch, mimicgen_io::ReadOptions::default()) {
        Ok(reader) => {
            use mimicgen_io::DemoSource as _;
            for name in reader.demo_names().to_vec() {
                match reader.load_demo(&name) {
                    Ok(group) => {
                        if let Err(e) = mimicgen_io::source_demo_from_group(&file, &name, &group) {
                            check_names("the streaming source-demo reader", &e.to_string(), &file);
                        }
                    }
                    Err(e) => check_names("the streaming reader", &e.to_string(), &file),
                }
            }
        }
        Err(e) => check_names("the streaming reader", &e.to_string(), &file),
    }
}

/// What [`dataset`] and [`dataset_bytes`] mutate, and where they write each copy.
#[derive(Debug)]
pub struct Seed {
    /// The seed file's tree (see [`dataset_seed`]).
    pub root: Group,
    /// The seed file's bytes (see [`dataset_seed_bytes`]).
    pub bytes: Vec<u8>,
    /// A scratch file of this process.
    pub scratch: std::path::PathBuf,
}

impl Seed {
    /// The seed and a scratch file in the system's temporary folder.
    ///
    /// # Panics
    /// As [`dataset_seed`].
    #[must_use]
    pub fn new() -> Self {
        let scratch = std::env::temp_dir().join(format!("mimicgen_fuzz_{}.hdf5", std::process::id()));
        Self { root: dataset_seed(), bytes: dataset_seed_bytes(&scratch), scratch }
    }
}

impl Default for Seed {
    fn default() -> Self {
        Self::new()
    }
}

/// Steps each demo of the [`dataset_seed`] keeps.
const SEED_STEPS: usize = 24;

/// Every per-step dataset below `group` (first dimension `steps`) cut to [`SEED_STEPS`] rows.
fn cut_steps(group: &mut Group, steps: usize) {
    for node in group.members.values_mut() {
        match node {
            Node::Group(g) => cut_steps(g, steps),
            Node::Dataset(d) if d.array.shape.first() == Some(&steps) => truncate(&mut d.array, SEED_STEPS),
            Node::Dataset(_) => {}
        }
    }
}

/// The bytes of the [`dataset_seed`] file as our writer writes it (through `scratch`).
///
/// # Panics
/// As [`dataset_seed`], or when `scratch` cannot be written and read.
#[must_use]
pub fn dataset_seed_bytes(scratch: &Path) -> Vec<u8> {
    mimicgen_io::dataset::write_tree(scratch, &dataset_seed()).unwrap_or_else(|e| panic!("{e}"));
    std::fs::read(scratch).unwrap_or_else(|e| panic!("reading {}: {e}", scratch.display()))
}

/// The seed file of [`dataset`]: the bundled prepared source demos cut to two demos of
/// `SEED_STEPS` steps: a valid source file, small, whose edits reach every field the readers
/// check.
///
/// # Panics
/// When the fixture is missing or unreadable (a broken checkout).
#[must_use]
pub fn dataset_seed() -> Group {
    let path = crate::repo_path("core/io/tests/data/source_D0_prepared.hdf5");
    let mut root = RobomimicDataset::open(&path).unwrap_or_else(|e| panic!("{e}")).root;
    if let Some(Node::Group(data)) = root.members.get_mut("data") {
        let keep = ["demo_0", "demo_1"];
        data.members.retain(|name, _| keep.contains(&name.as_str()));
        for demo in data.members.values_mut() {
            if let Node::Group(demo) = demo {
                let steps = mimicgen_io::dataset::demo_steps(demo);
                cut_steps(demo, steps);
                demo.attrs.insert("num_samples".to_owned(), Array::int(i64::try_from(SEED_STEPS).unwrap_or_default()));
            }
        }
    }
    root.members.remove("mask");
    root
}

/// Every path `request` names, read or written.
fn request_paths(request: &mimicgen_ui::protocol::Request) -> Vec<std::path::PathBuf> {
    use mimicgen_ui::protocol::{Request, ViewerSink};
    match request {
        Request::Open { path }
        | Request::ListDir { path }
        | Request::OpenCompare { path }
        | Request::OpenRun { path }
        | Request::Doctor { run: path, .. } => {
            vec![path.clone()]
        }
        Request::Save { source, out, .. } | Request::SaveArms { source, out, .. } => vec![source.clone(), out.clone()],
        Request::Preview(r) => vec![r.source.clone()],
        Request::SideBySide(pair) => pair.iter().map(|r| r.source.clone()).collect(),
        Request::Run(config) => [Some(config.out.clone()), config.source.clone(), config.config.clone()].into_iter().flatten().collect(),
        Request::Open3d { sink: ViewerSink::Save(path), .. } => vec![path.clone()],
        Request::Open3d { .. } | Request::ShowDemo { .. } | Request::CancelRun | Request::CancelDoctor => Vec::new(),
    }
}

/// A served folder for [`client_message`]: empty but for `data/`, with a folder of prepared copies
/// beside it, and a backend worker with nothing open.
#[derive(Debug)]
pub struct ServedRoot {
    /// The confinement under test.
    pub root: mimicgen_server::root::Root,
    _dir: tempfile::TempDir,
}

impl ServedRoot {
    /// A new one in the system's temporary folder.
    ///
    /// # Panics
    /// When the folder cannot be made.
    #[must_use]
    pub fn new() -> Self {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("a temporary folder: {e}"));
        std::fs::create_dir_all(dir.path().join("root/data")).unwrap_or_else(|e| panic!("{e}"));
        std::fs::create_dir_all(dir.path().join("prepared")).unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(dir.path().join("prepared/copy.hdf5"), b"").unwrap_or_else(|e| panic!("{e}"));
        let root = mimicgen_server::root::Root::new(&dir.path().join("root"))
            .unwrap_or_else(|e| panic!("{e}"))
            .with_prepared(&dir.path().join("prepared"));
        Self { root, _dir: dir }
    }
}

impl Default for ServedRoot {
    fn default() -> Self {
        Self::new()
    }
}

/// A tab's message as `mimicgen serve` takes it: read as JSON (what does not read closes the
/// tab's connection, no more), confined to the served folder, then answered by a backend worker
/// with nothing open (all but runs and the doctor, which start a thread). A refusal must name the path or field
/// it refuses; every path of a request let through must lie inside the root (or be a prepared
/// copy); nothing may panic, in the server or in the worker (which would answer "internal error").
///
/// # Panics
/// As said.
pub fn client_message(data: &[u8], served: &ServedRoot) -> Handled {
    use mimicgen_ui::protocol::{ClientMessage, Reply, Request};
    let Ok(ClientMessage { request, .. }) = serde_json::from_slice::<ClientMessage>(data) else { return Handled::Unread };
    let named = request_paths(&request);
    let root = &served.root;
    match root.confine(request, Some("rerun+http://127.0.0.1:1/proxy")) {
        Err(error) => {
            let names = named.iter().any(|p| !p.as_os_str().is_empty() && error.contains(&*p.to_string_lossy()));
            assert!(names || error.contains("an empty path"), "a refusal that names no path of the request {named:?}: {error}");
            Handled::Refused
        }
        Ok(confined) => {
            for path in request_paths(&confined) {
                let inside = path.starts_with(root.dir()) || root.prepared().is_some_and(|p| path.starts_with(p));
                assert!(inside, "{} let through, outside {}", path.display(), root.dir().display());
            }
            if matches!(confined, Request::Run(_) | Request::Doctor { .. }) {
                return Handled::Confined;
            }
            let mut worker = mimicgen_backend::Worker::new(std::sync::Arc::new(|_| {}), None);
            if let Reply::Failed { error, .. } = worker.handle_guarded(confined) {
                assert!(!error.contains("internal error"), "the backend panicked: {error}");
            }
            Handled::Answered
        }
    }
}

/// What [`client_message`] did with an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Handled {
    /// Not a message (the server closes the tab's connection).
    Unread,
    /// Refused by the confinement, naming the path.
    Refused,
    /// Let through and not answered here (a run).
    Confined,
    /// Let through and answered by the worker.
    Answered,
}
