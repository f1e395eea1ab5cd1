//! Compiled scenes kept on disk in MuJoCo's binary model format (MJB), so that a scene is compiled
//! from its MJCF once per machine, not once per run, worker process or Ray shard.
//!
//! Compiling robosuite's Stack scene takes about 0.5 s and, while MuJoCo processes its 64 meshes
//! (168 000 visual triangles, a bounding-volume tree each), about 300 MB of memory that the process
//! keeps afterwards (BENCHMARKS.md, "Memory"). Loading the same model from its MJB takes a few
//! milliseconds and only the model's own 44 MB. The MJB holds every array of the compiled model, so
//! the physics is bit for bit that of the compiled scene (tests: `a_cached_model_is_the_compiled_one`).
//!
//! Files live in `$MIMICGEN_CACHE/models/<key>.mjb`, the key a hash of the MJCF, the MuJoCo version
//! and this format's version. Written to a temporary name and renamed, so a reader never sees half
//! a file; the least recently used are removed beyond [`LIMIT_BYTES`]. Any failure (no cache
//! directory, full disk, a file MuJoCo does not load) falls back to compiling: the cache can only
//! make a run faster, never stop it. `MIMICGEN_MODEL_CACHE=0` turns it off.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use mujoco_rs::prelude::*;

/// The cache's size beyond which the least recently used models are removed.
pub const LIMIT_BYTES: u64 = 2 << 30;

/// Bumped when what goes into a cached model changes.
const FORMAT: &str = "mjb-1";

/// Where the model compiled from `xml` is kept in `dir`.
fn path_in(dir: &Path, xml: &str) -> PathBuf {
    let key = format!("{FORMAT} {} {}\n{xml}", mujoco_rs::mujoco_c::mjVERSION_HEADER, env!("CARGO_PKG_VERSION"));
    dir.join(format!("{}.mjb", hash128(key.as_bytes())))
}

/// Two 64-bit FNV-1a hashes with different offsets: a 128-bit key, collisions out of reach for a
/// cache of a few hundred files.
fn hash128(bytes: &[u8]) -> String {
    use mimicgen_engine::fingerprint::{FNV_OFFSET_BASIS, fnv1a};
    format!("{:016x}{:016x}", fnv1a(bytes, FNV_OFFSET_BASIS), fnv1a(bytes, 0x8422_2325_cbf2_9ce4 ^ bytes.len() as u64))
}

/// The model `xml` compiles to: from the cache when it is there, else `compile(xml)`, then kept.
///
/// # Errors
/// What `compile` returns.
pub(crate) fn load_or_compile(xml: &str, compile: impl FnOnce(&str) -> Result<MjModel, String>) -> Result<MjModel, String> {
    if std::env::var_os("MIMICGEN_MODEL_CACHE").is_some_and(|v| v == "0") {
        return compile(xml);
    }
    load_or_compile_in(&crate::assets::cache_dir().join("models"), xml, CHILD.get().is_some(), compile)
}

/// How a scene is compiled in another process, when one is set (see [`compile_in_child`]).
static CHILD: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();

/// Compile scenes missing from the cache in a child process: `program compile-model`, which reads
/// the MJCF on stdin and stores the model in the cache ([`crate::scene::store_compiled`]). MuJoCo's compiler
/// uses about 300 MB for robosuite's scenes (meshes, bounding-volume trees) and this process would
/// keep most of it; the child gives it back when it exits. The command-line program sets itself.
/// Without it, or when the child fails, scenes compile in this process as before.
pub fn compile_in_child(program: PathBuf) {
    let _ = CHILD.set(program);
}

/// Compiles `xml` with `compile` and stores the model in the cache (see
/// [`crate::scene::store_compiled`]).
///
/// # Errors
/// `compile`'s message, or why the model could not be stored.
pub(crate) fn store_compiled_with(xml: &str, compile: impl FnOnce(&str) -> Result<MjModel, String>) -> Result<(), String> {
    let path = path_in(&crate::assets::cache_dir().join("models"), xml);
    let model = compile(xml)?;
    store(&model, &path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Runs the child compiler on `xml`; true when it stored the model.
fn compiled_by_child(xml: &str) -> bool {
    let Some(program) = CHILD.get() else { return false };
    let child = std::process::Command::new(program)
        .arg("compile-model")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn();
    let Ok(mut child) = child else { return false };
    let fed = child.stdin.take().is_some_and(|mut stdin| stdin.write_all(xml.as_bytes()).is_ok());
    child.wait().is_ok_and(|status| status.success()) && fed
}

/// [`load_or_compile`] with the cache in `dir`; `via_child`: on a miss, ask the child compiler
/// first (it stores into the default cache, so only with that `dir`).
///
/// # Errors
/// What `compile` returns.
pub(crate) fn load_or_compile_in(
    dir: &Path,
    xml: &str,
    via_child: bool,
    compile: impl FnOnce(&str) -> Result<MjModel, String>,
) -> Result<MjModel, String> {
    let path = path_in(dir, xml);
    if let Some(model) = load(&path) {
        return Ok(model);
    }
    if via_child
        && compiled_by_child(xml)
        && let Some(model) = load(&path)
    {
        return Ok(model);
    }
    let model = compile(xml)?;
    // Best effort: a cache that cannot be written costs the next run a compile, nothing more.
    let _ = store(&model, &path);
    Ok(model)
}

fn load(path: &Path) -> Option<MjModel> {
    let bytes = std::fs::read(path).ok()?;
    let model = MjModel::from_buffer(&bytes).ok()?;
    // Mark it used (least recently used are removed first).
    if let Ok(file) = std::fs::File::options().append(true).open(path) {
        let _ = file.set_modified(std::time::SystemTime::now());
    }
    Some(model)
}

fn store(model: &MjModel, path: &Path) -> std::io::Result<()> {
    let dir = path.parent().ok_or_else(|| std::io::Error::other("no parent"))?;
    std::fs::create_dir_all(dir)?;
    let mut bytes = vec![0u8; model.size()];
    model.save_to_buffer(&mut bytes).map_err(|e| std::io::Error::other(format!("{e:?}")))?;
    // A name of this writer's own: other processes and threads may be storing the same model.
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("model");
    let temp = dir.join(format!(".{name}.{}.{n}.tmp", std::process::id()));
    let written = std::fs::File::create(&temp).and_then(|mut f| {
        f.write_all(&bytes)?;
        f.sync_all()
    });
    if let Err(e) = written.and_then(|()| std::fs::rename(&temp, path)) {
        let _ = std::fs::remove_file(&temp);
        return Err(e);
    }
    evict(dir, LIMIT_BYTES);
    Ok(())
}

/// Removes the least recently used models until the cache holds at most `limit` bytes.
fn evict(dir: &Path, limit: u64) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = entries
        .filter_map(Result::ok)
        .filter(|e| e.path().extension().is_some_and(|x| x == "mjb"))
        .filter_map(|e| {
            let meta = e.metadata().ok()?;
            Some((meta.modified().ok()?, meta.len(), e.path()))
        })
        .collect();
    let mut total: u64 = files.iter().map(|f| f.1).sum();
    files.sort();
    for (_, len, path) in files {
        if total <= limit {
            break;
        }
        if std::fs::remove_file(&path).is_ok() {
            total = total.saturating_sub(len);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_differ_with_the_scene_and_are_stable() {
        assert_eq!(hash128(b"<mujoco/>"), hash128(b"<mujoco/>"));
        assert_ne!(hash128(b"<mujoco/>"), hash128(b"<mujoco />"));
        assert_eq!(hash128(b"").len(), 32);
    }

    /// The model loaded from the cache is the compiled one: the same MJB bytes, and the same
    /// physics bit for bit.
    #[test]
    fn a_cached_model_is_the_compiled_one() {
        let task = crate::registry::task("stack", "D0").unwrap_or_else(|e| panic!("{e}"));
        let scene = crate::Scene::for_task(task.as_ref()).unwrap_or_else(|e| panic!("{e}"));
        let xml = crate::mjcf_edit::with_arena(&crate::mjcf_edit::without_image_textures(&scene.xml), "32M");
        let dir = std::env::temp_dir().join(format!("mimicgen_model_cache_same_{}", std::process::id()));
        let compiled = crate::scene::compile_uncached(&xml).unwrap_or_else(|e| panic!("{e}"));
        let first = load_or_compile_in(&dir, &xml, false, crate::scene::compile_uncached).unwrap_or_else(|e| panic!("{e}"));
        assert!(path_in(&dir, &xml).exists(), "the compiled model was kept");
        let cached =
            load_or_compile_in(&dir, &xml, false, |_| Err("compiled again instead of loaded".to_owned())).unwrap_or_else(|e| panic!("{e}"));
        std::fs::remove_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        let mjb = |m: &MjModel| {
            let mut bytes = vec![0u8; m.size()];
            m.save_to_buffer(&mut bytes).unwrap_or_else(|e| panic!("{e:?}"));
            bytes
        };
        assert!(mjb(&compiled) == mjb(&first) && mjb(&first) == mjb(&cached), "the MJB bytes differ");
        let run = |m: &MjModel| {
            let mut data = MjData::new(m);
            for step in 0..200 {
                data.ctrl_mut().iter_mut().enumerate().for_each(|(i, c)| *c = ((step * 7 + i) as f64 * 0.37).sin());
                data.step();
            }
            data.qpos().iter().map(|q| q.to_bits()).collect::<Vec<u64>>()
        };
        assert_eq!(run(&compiled), run(&cached));
    }

    #[test]
    fn eviction_removes_the_least_recently_used_first() {
        let dir = std::env::temp_dir().join(format!("mimicgen_model_cache_test_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        let t0 = std::time::SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_000_000);
        for (i, name) in ["old.mjb", "mid.mjb", "new.mjb"].iter().enumerate() {
            let path = dir.join(name);
            std::fs::write(&path, [0u8; 100]).unwrap_or_else(|e| panic!("{e}"));
            let file = std::fs::File::options().append(true).open(&path).unwrap_or_else(|e| panic!("{e}"));
            file.set_modified(t0 + std::time::Duration::from_secs(i as u64)).unwrap_or_else(|e| panic!("{e}"));
        }
        std::fs::write(dir.join("notes.txt"), [0u8; 1000]).unwrap_or_else(|e| panic!("{e}"));
        evict(&dir, 200);
        let left: Vec<bool> = ["old.mjb", "mid.mjb", "new.mjb", "notes.txt"].iter().map(|n| dir.join(n).exists()).collect();
        std::fs::remove_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(left, [false, true, true, true]);
    }
}
