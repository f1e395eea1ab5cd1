//! Exports a robomimic dataset as a LeRobot dataset (format v3.0, what `lerobot` and
//! `lerobot-dataset` load): parquet frames under `data/`, camera streams as H.264 MP4 under
//! `videos/` (episodes one after another in a file, as LeRobot stores them), and `meta/` (info,
//! tasks, episodes, stats).
//!
//! Frames: `observation.state` (the chosen low-dim observations, concatenated, float32), `action`
//! (float32), `next.reward`, `next.done`, `timestamp` (`frame_index / fps`), `frame_index`,
//! `episode_index`, `index` (across the dataset) and `task_index`, and with subtasks given,
//! `subtask_index` (its text in `meta/subtasks.parquet`, see [`SubtaskLabel`]). Cameras: every `obs/<cam>_image`
//! (uint8 `(T, H, W, 3)`) becomes the video feature `observation.images.<cam>`, encoded by ffmpeg
//! (`libx264`, `yuv420p`, a keyframe every 2 frames, as LeRobot's own encoder spaces them).
//!
//! A dataset card, when given, is the dataset's `README.md` (what the Hugging Face Hub shows).
//!
//! The export is written to `<out>.partial/` and renamed to `<out>` when complete.
//!
//! One exporter (episodes into parquet chunks, MP4 files and the metadata that indexes both)
//! whose parts share its running file slots and statistics.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::Arc;

use arrow_array::builder::{FixedSizeListBuilder, Float32Builder};
use arrow_array::{Array as _, ArrayRef, BooleanArray, Float32Array, Float64Array, Int64Array, ListArray, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;
use serde::Serialize;
use serde_json::{Value, json};

use crate::dataset::DemoSource;
use crate::error::{IoError, Result};
use crate::tree::{Group, Values};

mod parts;
mod subtasks;
use parts::{FileSlot, Stats};
pub use subtasks::SubtaskLabel;

/// LeRobot's format version written.
pub const CODEBASE_VERSION: &str = "v3.0";
/// Files per chunk directory (LeRobot's default).
const CHUNK_SIZE: usize = 1000;
/// Data file size (MB, uncompressed estimate) after which a new file starts.
const DATA_FILE_MB: usize = 100;
/// Video file size (MB, raw frames) after which a new file starts.
const VIDEO_FILE_MB: usize = 200;

/// The low-dim observations robomimic's image policies use besides the cameras.
pub const DEFAULT_STATE_KEYS: [&str; 4] = ["robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object"];

/// How to export.
#[derive(Debug, Clone, PartialEq)]
pub struct LeRobotOptions {
    /// Observation keys concatenated, in order, into `observation.state`.
    pub state_keys: Vec<String>,
    /// Frames per second (robosuite's control rate: 20).
    pub fps: u32,
    /// The task's instruction, LeRobot's `task` of every frame.
    pub task: String,
    /// `robot_type` in `meta/info.json`.
    pub robot_type: String,
    /// The ffmpeg program that encodes camera streams.
    pub ffmpeg: PathBuf,
    /// Replace an existing `out`.
    pub overwrite: bool,
    /// The task's subtasks in order; empty for no `subtask_index` column.
    pub subtasks: Vec<SubtaskLabel>,
    /// The dataset card (Markdown), written as `README.md`.
    pub card: Option<String>,
}

impl LeRobotOptions {
    /// The ffmpeg to encode with: `$MIMICGEN_FFMPEG`, else the one `scripts/setup.sh` unpacked
    /// into the project's cache (`$MIMICGEN_CACHE`, default `~/.cache/mimicgen`), else `ffmpeg`
    /// on the `PATH`.
    #[must_use]
    pub fn default_ffmpeg() -> PathBuf {
        if let Some(path) = std::env::var_os("MIMICGEN_FFMPEG") {
            return PathBuf::from(path);
        }
        let cache = std::env::var_os("MIMICGEN_CACHE")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/mimicgen")));
        match cache.map(|c| c.join("ffmpeg-9.0.2/ffmpeg")) {
            Some(cached) if cached.is_file() => cached,
            _ => PathBuf::from("ffmpeg"),
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct LeRobotSummary {
    /// Episodes (demos) written.
    pub episodes: usize,
    /// Frames written.
    pub frames: usize,
    /// `observation.state` width and what it is made of.
    pub state: Vec<(String, usize)>,
    /// Video features written.
    pub videos: Vec<String>,
    /// The task of every frame.
    pub task: String,
    /// The subtasks frames are labelled with (`subtask_index`), in order.
    pub subtasks: Vec<String>,
    /// The dataset directory.
    pub out: String,
}

/// Exports every demo of `source` (in robomimic order) as the LeRobot dataset `out`, calling
/// `on_episode(done, total)` after each.
///
/// # Errors
/// [`IoError::Exists`] when `out` exists without `overwrite`; [`IoError::Fs`] on write and
/// ffmpeg failures;
/// [`IoError::Invalid`] naming the demo and field when a demo lacks a state key, has a NaN or
/// disagrees with the first demo's shapes.
pub fn export_lerobot(
    source: &impl DemoSource,
    out: &Path,
    options: &LeRobotOptions,
    mut on_episode: impl FnMut(usize, usize),
) -> Result<LeRobotSummary> {
    let label = source.file().to_owned();
    if out.exists() && !options.overwrite {
        return Err(IoError::Exists { file: out.display().to_string() });
    }
    let names = source.demo_names().to_vec();
    let invalid = |group: &str, field: &str, reason: String| IoError::Invalid {
        file: label.clone(),
        group: group.into(),
        field: field.into(),
        reason,
    };
    let Some(first_name) = names.first() else { return Err(invalid("data", "", "has no demos to export".into())) };
    let first = source.load_demo(first_name)?;
    let group = format!("data/{first_name}");
    let obs = first.group("obs").ok_or_else(|| invalid(&group, "obs", "missing (the state is made of observations)".into()))?;
    let mut state_widths = Vec::new();
    for key in &options.state_keys {
        let d = obs.dataset(key).ok_or_else(|| {
            let keys: Vec<&str> = obs.members.keys().map(String::as_str).collect();
            invalid(&group, &format!("obs/{key}"), format!("missing: the observations are {}", keys.join(", ")))
        })?;
        let width = d.array.shape.get(1..).unwrap_or_default().iter().product::<usize>();
        if width == 0 {
            return Err(invalid(&group, &format!("obs/{key}"), format!("has shape {:?}: no values per step", d.array.shape)));
        }
        state_widths.push(width);
    }
    let action_dim = first.dataset("actions").and_then(|d| d.array.shape.get(1).copied()).unwrap_or(0);
    if action_dim == 0 {
        return Err(invalid(&group, "actions", "missing or not (T, D)".into()));
    }
    let mut videos = Vec::new();
    for (key, node) in &obs.members {
        let crate::tree::Node::Dataset(d) = node else { continue };
        let (Some(camera), Values::U8(_), [_, h, w, 3]) = (key.strip_suffix("_image"), &d.array.values, d.array.shape.as_slice()) else {
            continue;
        };
        if *h == 0 || *w == 0 || h % 2 != 0 || w % 2 != 0 {
            return Err(invalid(
                &group,
                &format!("obs/{key}"),
                format!("is {h}x{w}: H.264 in yuv420p needs even, non-zero heights and widths"),
            ));
        }
        videos.push(VideoStream {
            key: key.clone(),
            feature: format!("observation.images.{camera}"),
            shape: [*h, *w, 3],
            slot: FileSlot::default(),
            encoder: None,
            frames_in_file: 0,
            stats: Stats::default(),
        });
    }
    drop(first);
    let state_dim: usize = state_widths.iter().sum();
    if state_dim == 0 {
        return Err(invalid(&group, "obs", "no state keys were given: the state would be empty".into()));
    }
    let list = |name: &str, n: usize| {
        Field::new(
            name,
            DataType::FixedSizeList(Arc::new(Field::new("item", DataType::Float32, true)), i32::try_from(n).unwrap_or(i32::MAX)),
            false,
        )
    };
    let schema = Arc::new(Schema::new(
        [
            list("observation.state", state_dim),
            list("action", action_dim),
            Field::new("next.reward", DataType::Float32, false),
            Field::new("next.done", DataType::Boolean, false),
            Field::new("timestamp", DataType::Float32, false),
            Field::new("frame_index", DataType::Int64, false),
            Field::new("episode_index", DataType::Int64, false),
            Field::new("index", DataType::Int64, false),
            Field::new("task_index", DataType::Int64, false),
        ]
        .into_iter()
        .chain((!options.subtasks.is_empty()).then(|| Field::new("subtask_index", DataType::Int64, false)))
        .collect::<Vec<_>>(),
    ));
    let partial = PathBuf::from(format!("{}.partial", out.display()));
    if partial.exists() {
        std::fs::remove_dir_all(&partial).map_err(|e| fs_error(&partial, "removing an earlier unfinished export", &e))?;
    }
    let mut exporter = Exporter {
        options,
        root: partial.clone(),
        label,
        schema,
        data_slot: FileSlot::default(),
        data_writer: None,
        data_bytes: 0,
        state_dim,
        state_widths,
        action_dim,
        videos,
        episodes: Vec::new(),
        frames: 0,
        state_stats: Stats::default(),
        action_stats: Stats::default(),
        scalar_stats: BTreeMap::new(),
    };
    for (i, name) in names.iter().enumerate() {
        let demo = source.load_demo(name)?;
        exporter.add_episode(name, &demo)?;
        on_episode(i + 1, names.len());
    }
    exporter.close_data_file()?;
    for video in &mut exporter.videos {
        Exporter::finish_video(video, &options.ffmpeg)?;
    }
    exporter.write_meta()?;
    if out.exists() {
        std::fs::remove_dir_all(out).map_err(|e| fs_error(out, "replacing it", &e))?;
    }
    std::fs::rename(&partial, out).map_err(|e| fs_error(out, &format!("moving {} into place", partial.display()), &e))?;
    Ok(LeRobotSummary {
        episodes: exporter.episodes.len(),
        frames: exporter.frames,
        state: exporter.state_layout(),
        videos: exporter.videos.iter().map(|v| v.feature.clone()).collect(),
        task: options.task.clone(),
        subtasks: options.subtasks.iter().map(|s| s.name.clone()).collect(),
        out: out.display().to_string(),
    })
}

/// One camera's video files: the ffmpeg process encoding the current one.
struct VideoStream {
    key: String,
    feature: String,
    shape: [usize; 3],
    slot: FileSlot,
    encoder: Option<(Child, ChildStdin, String)>,
    frames_in_file: usize,
    stats: Stats,
}

/// Writes a LeRobot dataset into a directory.
struct Exporter<'a> {
    options: &'a LeRobotOptions,
    root: PathBuf,
    label: String,
    schema: Arc<Schema>,
    data_slot: FileSlot,
    data_writer: Option<ArrowWriter<File>>,
    data_bytes: usize,
    state_dim: usize,
    state_widths: Vec<usize>,
    action_dim: usize,
    videos: Vec<VideoStream>,
    episodes: Vec<Value>,
    frames: usize,
    state_stats: Stats,
    action_stats: Stats,
    scalar_stats: BTreeMap<&'static str, Stats>,
}

fn fs_error(path: &Path, what: &str, e: &impl std::fmt::Display) -> IoError {
    IoError::Fs { file: path.display().to_string(), reason: format!("{what}: {e}") }
}

impl Exporter<'_> {
    fn error(&self, field: &str, reason: impl Into<String>) -> IoError {
        IoError::Invalid { file: self.label.clone(), group: "data".into(), field: field.into(), reason: reason.into() }
    }

    fn open_data_file(&mut self) -> Result<()> {
        let path = self.root.join(self.data_slot.path("data", "parquet"));
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| fs_error(dir, "creating the directory", &e))?;
        }
        let file = File::create(&path).map_err(|e| fs_error(&path, "creating the file", &e))?;
        let props = WriterProperties::builder().set_compression(Compression::SNAPPY).build();
        let writer =
            ArrowWriter::try_new(file, Arc::clone(&self.schema), Some(props)).map_err(|e| fs_error(&path, "starting parquet", &e))?;
        self.data_writer = Some(writer);
        self.data_bytes = 0;
        Ok(())
    }

    fn close_data_file(&mut self) -> Result<()> {
        if let Some(writer) = self.data_writer.take() {
            let path = self.root.join(self.data_slot.path("data", "parquet"));
            writer.close().map_err(|e| fs_error(&path, "finishing parquet", &e))?;
        }
        Ok(())
    }

    fn start_video(&self, video: &mut VideoStream) -> Result<()> {
        let rel = format!("videos/{}/chunk-{:03}/file-{:03}.mp4", video.feature, video.slot.chunk, video.slot.file);
        let path = self.root.join(&rel);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| fs_error(dir, "creating the directory", &e))?;
        }
        let [h, w, _] = video.shape;
        let mut child = Command::new(&self.options.ffmpeg)
            .args(["-hide_banner", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s"])
            .arg(format!("{w}x{h}"))
            .arg("-r")
            .arg(self.options.fps.to_string())
            .args(["-i", "-", "-c:v", "libx264", "-pix_fmt", "yuv420p", "-g", "2", "-crf", "18", "-preset", "medium"])
            .args(["-movflags", "+faststart", "-y"])
            .arg(&path)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| IoError::Fs {
                file: self.options.ffmpeg.display().to_string(),
                reason: format!(
                    "cannot run ffmpeg to encode the camera streams ({e}); scripts/setup.sh installs one, or pass --ffmpeg PATH"
                ),
            })?;
        let stdin = child.stdin.take().ok_or_else(|| fs_error(&self.options.ffmpeg, "ffmpeg", &"no stdin"))?;
        video.encoder = Some((child, stdin, rel));
        video.frames_in_file = 0;
        Ok(())
    }

    fn finish_video(video: &mut VideoStream, ffmpeg: &Path) -> Result<()> {
        if let Some((child, stdin, rel)) = video.encoder.take() {
            drop(stdin);
            let out = child.wait_with_output().map_err(|e| fs_error(ffmpeg, "waiting for ffmpeg", &e))?;
            if !out.status.success() {
                return Err(IoError::Fs {
                    file: rel,
                    reason: format!("ffmpeg failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr).trim()),
                });
            }
        }
        Ok(())
    }

    #[allow(clippy::cast_precision_loss, clippy::too_many_lines)]
    fn add_episode(&mut self, name: &str, demo: &Group) -> Result<()> {
        let group = format!("data/{name}");
        let label = self.label.clone();
        let err = |field: &str, reason: String| IoError::Invalid { file: label.clone(), group: group.clone(), field: field.into(), reason };
        let actions = demo.dataset("actions").ok_or_else(|| err("actions", "missing".into()))?;
        let steps = actions.array.shape.first().copied().unwrap_or(0);
        let action_values = actions.array.values.to_f64().ok_or_else(|| err("actions", "is not numeric".into()))?;
        if steps == 0 || action_values.len() != steps * self.action_dim {
            return Err(err("actions", format!("shape {:?}, expected (T > 0, {})", actions.array.shape, self.action_dim)));
        }
        let obs = demo.group("obs").ok_or_else(|| err("obs", "missing (the state is made of observations)".into()))?;
        let mut state = vec![0.0f64; steps * self.state_dim];
        let mut offset = 0;
        for key in &self.options.state_keys {
            let field = format!("obs/{key}");
            let d = obs.dataset(key).ok_or_else(|| err(&field, "missing".into()))?;
            let v = d.array.values.to_f64().ok_or_else(|| err(&field, "is not numeric".into()))?;
            let width = v.len() / steps.max(1);
            if d.array.shape.first() != Some(&steps) || width == 0 || width * steps != v.len() || offset + width > self.state_dim {
                return Err(err(&field, format!("shape {:?} does not fit {steps} steps of the first demo's width", d.array.shape)));
            }
            for (state_row, values) in state.chunks_exact_mut(self.state_dim).zip(v.chunks_exact(width)) {
                #[allow(clippy::indexing_slicing, reason = "offset + width <= state_dim, checked above")]
                state_row[offset..offset + width].copy_from_slice(values);
            }
            offset += width;
        }
        if offset != self.state_dim {
            return Err(err("obs", format!("the state keys make {offset} values per step, the first demo's {}", self.state_dim)));
        }
        if let Some(bad) = state.iter().chain(&action_values).position(|v| !v.is_finite()) {
            let field = if bad < state.len() { "obs" } else { "actions" };
            return Err(err(field, "holds a NaN or infinite value".into()));
        }
        let rewards = demo.dataset("rewards").and_then(|d| d.array.values.to_f64()).filter(|r| r.len() == steps);
        let dones = demo.dataset("dones").and_then(|d| d.array.values.to_i64()).filter(|r| r.len() == steps);
        let rewards = rewards.unwrap_or_else(|| vec![0.0; steps]);
        let dones: Vec<bool> = dones.map_or_else(|| (0..steps).map(|t| t + 1 == steps).collect(), |d| d.iter().map(|&x| x != 0).collect());
        let subtask_labels = if self.options.subtasks.is_empty() {
            None
        } else {
            Some(subtasks::subtask_of_each_step(demo, &self.options.subtasks, steps).map_err(|(field, reason)| err(&field, reason))?)
        };

        // Frames.
        let episode_index = self.episodes.len();
        let from = self.frames;
        let fps = f64::from(self.options.fps);
        let mut state_col = FixedSizeListBuilder::new(Float32Builder::new(), i32::try_from(self.state_dim).unwrap_or(i32::MAX));
        let mut action_col = FixedSizeListBuilder::new(Float32Builder::new(), i32::try_from(self.action_dim).unwrap_or(i32::MAX));
        for (state_row, action_row) in state.chunks_exact(self.state_dim).zip(action_values.chunks_exact(self.action_dim)) {
            #[allow(clippy::cast_possible_truncation)]
            state_col.values().append_slice(&state_row.iter().map(|&v| v as f32).collect::<Vec<_>>());
            state_col.append(true);
            self.state_stats.add(state_row);
            #[allow(clippy::cast_possible_truncation)]
            action_col.values().append_slice(&action_row.iter().map(|&v| v as f32).collect::<Vec<_>>());
            action_col.append(true);
            self.action_stats.add(action_row);
        }
        let timestamps: Vec<f32> = (0..steps).map(|t| (t as f64 / fps) as f32).collect();
        let index = |offset: usize| (0..steps).map(|t| i64::try_from(offset + t).unwrap_or(i64::MAX)).collect::<Vec<i64>>();
        for (t, ((&timestamp, &reward), &done)) in timestamps.iter().zip(&rewards).zip(&dones).enumerate() {
            let ep = episode_index as f64;
            for (key, value) in [
                ("timestamp", f64::from(timestamp)),
                ("frame_index", t as f64),
                ("episode_index", ep),
                ("index", (from + t) as f64),
                ("task_index", 0.0),
                ("next.reward", reward),
                ("next.done", f64::from(u8::from(done))),
            ] {
                self.scalar_stats.entry(key).or_default().add(&[value]);
            }
            if let Some(label) = subtask_labels.as_ref().and_then(|l| l.get(t)) {
                self.scalar_stats.entry("subtask_index").or_default().add(&[*label as f64]);
            }
        }
        #[allow(clippy::cast_possible_truncation)]
        let columns: Vec<ArrayRef> = vec![
            Arc::new(state_col.finish()),
            Arc::new(action_col.finish()),
            Arc::new(Float32Array::from(rewards.iter().map(|&r| r as f32).collect::<Vec<_>>())),
            Arc::new(BooleanArray::from(dones)),
            Arc::new(Float32Array::from(timestamps)),
            Arc::new(Int64Array::from(index(0))),
            Arc::new(Int64Array::from(vec![i64::try_from(episode_index).unwrap_or(i64::MAX); steps])),
            Arc::new(Int64Array::from(index(from))),
            Arc::new(Int64Array::from(vec![0i64; steps])),
        ];
        let columns: Vec<ArrayRef> = columns.into_iter().chain(subtask_labels.map(|l| Arc::new(Int64Array::from(l)) as ArrayRef)).collect();
        let batch = RecordBatch::try_new(Arc::clone(&self.schema), columns).map_err(|e| err("actions", format!("arrow: {e}")))?;
        let approx_bytes = steps * (4 * (self.state_dim + self.action_dim) + 41);
        if self.data_writer.is_some() && self.data_bytes + approx_bytes > DATA_FILE_MB << 20 {
            self.close_data_file()?;
            self.data_slot = self.data_slot.next();
        }
        if self.data_writer.is_none() {
            self.open_data_file()?;
        }
        let data_path = self.root.join(self.data_slot.path("data", "parquet"));
        if let Some(w) = self.data_writer.as_mut() {
            w.write(&batch).map_err(|e| fs_error(&data_path, "writing parquet", &e))?;
        }
        self.data_bytes += approx_bytes;

        // Episode metadata, videos included.
        let mut meta = json!({
            "episode_index": episode_index,
            "tasks": [self.options.task],
            "length": steps,
            "data/chunk_index": self.data_slot.chunk,
            "data/file_index": self.data_slot.file,
            "dataset_from_index": from,
            "dataset_to_index": from + steps,
        });
        let mut videos = std::mem::take(&mut self.videos);
        let result = (|| -> Result<()> {
            for video in &mut videos {
                let field = format!("obs/{}", video.key);
                let d = obs.dataset(&video.key).ok_or_else(|| err(&field, "missing (the first demo has it)".into()))?;
                let Values::U8(pixels) = &d.array.values else { return Err(err(&field, "is not uint8".into())) };
                let [h, w, c] = video.shape;
                if d.array.shape != [steps, h, w, c] {
                    return Err(err(&field, format!("shape {:?}, expected ({steps}, {h}, {w}, {c})", d.array.shape)));
                }
                let frame_bytes = h * w * c;
                if video.encoder.is_some() && (video.frames_in_file + steps) * frame_bytes > VIDEO_FILE_MB << 20 {
                    Self::finish_video(video, &self.options.ffmpeg)?;
                    video.slot = video.slot.next();
                }
                if video.encoder.is_none() {
                    self.start_video(video)?;
                }
                let start = video.frames_in_file;
                if let Some((_, stdin, rel)) = video.encoder.as_mut() {
                    let rel = rel.clone();
                    stdin.write_all(pixels).map_err(|e| IoError::Fs { file: rel, reason: format!("feeding ffmpeg: {e}") })?;
                }
                for frame in pixels.chunks(frame_bytes).step_by(5) {
                    let mut means = [0.0f64; 3];
                    for px in frame.chunks(3) {
                        for (m, &v) in means.iter_mut().zip(px) {
                            *m += f64::from(v) / 255.0;
                        }
                    }
                    let n = (h * w) as f64;
                    video.stats.add(&means.map(|m| m / n));
                }
                video.frames_in_file += steps;
                set(&mut meta, format!("videos/{}/chunk_index", video.feature), json!(video.slot.chunk));
                set(&mut meta, format!("videos/{}/file_index", video.feature), json!(video.slot.file));
                set(&mut meta, format!("videos/{}/from_timestamp", video.feature), json!(start as f64 / fps));
                set(&mut meta, format!("videos/{}/to_timestamp", video.feature), json!((start + steps) as f64 / fps));
            }
            Ok(())
        })();
        self.videos = videos;
        result?;
        set(&mut meta, "meta/episodes/chunk_index".to_owned(), json!(0));
        set(&mut meta, "meta/episodes/file_index".to_owned(), json!(0));
        self.episodes.push(meta);
        self.frames += steps;
        Ok(())
    }

    fn write_meta(&self) -> Result<()> {
        let meta = self.root.join("meta");
        let write_json = |name: &str, value: &Value| -> Result<()> {
            let path = meta.join(name);
            let text = serde_json::to_string_pretty(value).map_err(|e| fs_error(&path, "encoding", &e))?;
            std::fs::write(&path, text).map_err(|e| fs_error(&path, "writing", &e))
        };
        std::fs::create_dir_all(&meta).map_err(|e| fs_error(&meta, "creating the directory", &e))?;
        let names = |prefix: &str, n: usize| (0..n).map(|i| format!("{prefix}_{i}")).collect::<Vec<_>>();
        let mut state_names = Vec::new();
        let mut features = serde_json::Map::new();
        for (key, width) in self.state_layout() {
            state_names.extend(names(&key, width));
        }
        features.insert("observation.state".into(), json!({"dtype": "float32", "shape": [self.state_dim], "names": state_names}));
        let action_names: Vec<String> = ["dx", "dy", "dz", "droll", "dpitch", "dyaw", "gripper"]
            .iter()
            .take(self.action_dim)
            .map(|s| (*s).to_owned())
            .chain(names("action", self.action_dim.saturating_sub(7)))
            .collect();
        features.insert("action".into(), json!({"dtype": "float32", "shape": [self.action_dim], "names": action_names}));
        features.insert("next.reward".into(), json!({"dtype": "float32", "shape": [1], "names": null}));
        features.insert("next.done".into(), json!({"dtype": "bool", "shape": [1], "names": null}));
        for (key, dtype) in
            [("timestamp", "float32"), ("frame_index", "int64"), ("episode_index", "int64"), ("index", "int64"), ("task_index", "int64")]
        {
            features.insert(key.into(), json!({"dtype": dtype, "shape": [1], "names": null}));
        }
        if !self.options.subtasks.is_empty() {
            features.insert("subtask_index".into(), json!({"dtype": "int64", "shape": [1], "names": null}));
        }
        for video in &self.videos {
            let [h, w, c] = video.shape;
            features.insert(
                video.feature.clone(),
                json!({
                    "dtype": "video",
                    "shape": [h, w, c],
                    "names": ["height", "width", "channels"],
                    "info": {
                        "video.height": h, "video.width": w, "video.codec": "h264", "video.pix_fmt": "yuv420p",
                        "video.is_depth_map": false, "video.fps": self.options.fps, "video.channels": c, "has_audio": false
                    }
                }),
            );
        }
        let episodes = self.episodes.len();
        write_json(
            "info.json",
            &json!({
                "codebase_version": CODEBASE_VERSION,
                "robot_type": self.options.robot_type,
                "total_episodes": episodes,
                "total_frames": self.frames,
                "total_tasks": 1,
                "chunks_size": CHUNK_SIZE,
                "data_files_size_in_mb": DATA_FILE_MB,
                "video_files_size_in_mb": VIDEO_FILE_MB,
                "fps": self.options.fps,
                "splits": {"train": format!("0:{episodes}")},
                "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
                "video_path": (!self.videos.is_empty()).then_some("videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"),
                "features": features,
            }),
        )?;
        let mut stats = serde_json::Map::new();
        stats.insert("observation.state".into(), self.state_stats.to_json(false));
        stats.insert("action".into(), self.action_stats.to_json(false));
        for (key, s) in &self.scalar_stats {
            stats.insert((*key).to_owned(), s.to_json(false));
        }
        for video in &self.videos {
            stats.insert(video.feature.clone(), video.stats.to_json(true));
        }
        write_json("stats.json", &Value::Object(stats))?;
        let tasks = meta.join("tasks.parquet");
        let table = subtasks::indexed_strings("task_index", std::slice::from_ref(&self.options.task));
        write_parquet(&tasks, &table.map_err(|e| fs_error(&tasks, "arrow", &e))?)?;
        if !self.options.subtasks.is_empty() {
            let path = subtasks::table_path(&meta);
            let names: Vec<String> = self.options.subtasks.iter().map(|s| s.name.clone()).collect();
            write_parquet(&path, &subtasks::indexed_strings("subtask_index", &names).map_err(|e| fs_error(&path, "arrow", &e))?)?;
        }
        if let Some(card) = &self.options.card {
            let path = self.root.join("README.md");
            std::fs::write(&path, card).map_err(|e| fs_error(&path, "writing the dataset card", &e))?;
        }
        self.write_episodes(&meta.join("episodes/chunk-000/file-000.parquet"))
    }

    fn state_layout(&self) -> Vec<(String, usize)> {
        self.options.state_keys.iter().cloned().zip(self.state_widths.iter().copied()).collect()
    }

    /// `meta/episodes/chunk-000/file-000.parquet`: one row per episode.
    fn write_episodes(&self, path: &Path) -> Result<()> {
        let Some(first) = self.episodes.first().and_then(Value::as_object) else { return Err(self.error("", "no demos to export")) };
        let mut fields = Vec::new();
        let mut columns: Vec<ArrayRef> = Vec::new();
        for key in first.keys() {
            let values: Vec<&Value> = self.episodes.iter().map(|e| &e[key]).collect();
            if key == "tasks" {
                let tasks: Vec<Option<Vec<Option<String>>>> = values
                    .iter()
                    .map(|v| Some(v.as_array().into_iter().flatten().map(|t| t.as_str().map(str::to_owned)).collect()))
                    .collect();
                let array = ListArray::from_iter_primitive_strings(tasks);
                fields.push(Field::new(key, array.data_type().clone(), true));
                columns.push(Arc::new(array));
            } else if values.iter().all(|v| v.is_u64()) {
                fields.push(Field::new(key, DataType::Int64, false));
                columns.push(Arc::new(Int64Array::from(values.iter().map(|v| v.as_i64().unwrap_or_default()).collect::<Vec<_>>())));
            } else {
                fields.push(Field::new(key, DataType::Float64, false));
                columns.push(Arc::new(Float64Array::from(values.iter().map(|v| v.as_f64().unwrap_or_default()).collect::<Vec<_>>())));
            }
        }
        let batch = RecordBatch::try_new(Arc::new(Schema::new(fields)), columns).map_err(|e| fs_error(path, "arrow", &e))?;
        write_parquet(path, &batch)
    }
}

/// A list-of-strings column.
trait StringLists {
    fn from_iter_primitive_strings(values: Vec<Option<Vec<Option<String>>>>) -> ListArray;
}

impl StringLists for ListArray {
    fn from_iter_primitive_strings(values: Vec<Option<Vec<Option<String>>>>) -> ListArray {
        let mut builder = arrow_array::builder::ListBuilder::new(arrow_array::builder::StringBuilder::new());
        for list in values {
            match list {
                Some(items) => {
                    for item in items {
                        builder.values().append_option(item);
                    }
                    builder.append(true);
                }
                None => builder.append(false),
            }
        }
        builder.finish()
    }
}

fn write_parquet(path: &Path, batch: &RecordBatch) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| fs_error(dir, "creating the directory", &e))?;
    }
    let file = File::create(path).map_err(|e| fs_error(path, "creating the file", &e))?;
    let props = WriterProperties::builder().set_compression(Compression::SNAPPY).build();
    let mut writer = ArrowWriter::try_new(file, batch.schema(), Some(props)).map_err(|e| fs_error(path, "starting parquet", &e))?;
    writer.write(batch).map_err(|e| fs_error(path, "writing parquet", &e))?;
    writer.close().map_err(|e| fs_error(path, "finishing parquet", &e))?;
    Ok(())
}

/// Sets `key` in a JSON object (what `meta` is built as); does nothing to any other value.
fn set(meta: &mut serde_json::Value, key: String, value: serde_json::Value) {
    if let serde_json::Value::Object(map) = meta {
        map.insert(key, value);
    }
}
