//! What the UI and its backend say to each other: plain, serializable requests and replies, the
//! same in the desktop window (over a channel) and in the browser (as JSON over a WebSocket, in
//! the [`ClientMessage`] and [`ServerMessage`] envelopes).
//!
//! Every message type in one place, so the UI, the backend and the server read the protocol
//! alike.

use std::collections::BTreeMap;
use std::path::PathBuf;

use mimicgen_engine::coverage::Dimension;
use mimicgen_engine::{RunStats, SubtaskMarks};
use mimicgen_run::{Report, RunConfig, RunInfo, SpecOverrides};
use serde::{Deserialize, Serialize};

/// A request to the backend (file reads, detection, writes: everything that may take time).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Request {
    /// Read a source file and propose its subtask ends.
    Open {
        /// The file.
        path: PathBuf,
    },
    /// Write `source` to `out` with these subtask ends (exclusive, per demo) and segment starts.
    Save {
        /// The file the demos came from.
        source: PathBuf,
        /// Where to write.
        out: PathBuf,
        /// Ends and starts per demo.
        marks: SubtaskMarks,
        /// The signal each subtask end is written to.
        signal_names: Vec<String>,
        /// Replace `out` if it exists (else an existing `out` is refused).
        overwrite: bool,
    },
    /// Write a two-arm `source` to `out` with each arm's subtask ends as its signals.
    SaveArms {
        /// The file the demos came from.
        source: PathBuf,
        /// Where to write.
        out: PathBuf,
        /// Per arm, in the file's order: its signal names and its ends per demo.
        arms: Vec<ArmMarks>,
        /// Replace `out` if it exists (else an existing `out` is refused).
        overwrite: bool,
    },
    /// Plan attempt `index` of a run seeded `seed` over `source` with these ends, and with
    /// `execute` also run it in simulation ("try it").
    Preview(Box<PreviewRequest>),
    /// Execute two attempts (a failure and a success to compare), one reply with both.
    SideBySide(Box<[PreviewRequest; 2]>),
    /// Start streaming to Rerun: demo `demo` now, then every demo shown and attempt tried.
    Open3d {
        /// Where.
        sink: ViewerSink,
        /// The demo shown.
        demo: usize,
    },
    /// Show demo `demo` (index in the open file): its camera images (as [`Reply::Images`], when
    /// the file has camera observations) and, with `in_3d`, the demo in the 3D view.
    ShowDemo {
        /// The demo.
        demo: usize,
        /// Also send it to the 3D view.
        in_3d: bool,
    },
    /// Start a generation run (on its own thread; it reports through [`Reply::Run`]).
    Run(Box<RunConfig>),
    /// Stop the run after the attempts already decided; its outputs are finished as valid datasets.
    CancelRun,
    /// Read a finished run's outputs to show its coverage beside the run's.
    OpenCompare {
        /// The dataset `mimicgen generate` wrote.
        path: PathBuf,
    },
    /// List a directory (for the file browser).
    ListDir {
        /// The directory.
        path: PathBuf,
    },
    /// Read a finished run's outputs (dataset, `_failed.hdf5`, report) into the run views; they
    /// come as [`Reply::Run`] updates, as a live run's do.
    OpenRun {
        /// The dataset `mimicgen generate` wrote.
        path: PathBuf,
    },
    /// Diagnose a finished run (`mimicgen doctor`, on its own thread; it reports through
    /// [`Reply::Doctor`]).
    Doctor {
        /// The dataset `mimicgen generate` wrote (its report beside it), or the report.
        run: PathBuf,
        /// Attempts to simulate in all.
        budget: usize,
        /// Suggestions to test.
        top: usize,
    },
    /// Stop the doctor (it reports [`DoctorUpdate::Failed`]).
    CancelDoctor,
}

/// What the run doctor reports (after [`Request::Doctor`] was accepted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum DoctorUpdate {
    /// Suggestions ranked; `arms` arms of `attempts` attempts follow (the run's spec first).
    Started {
        /// Every suggestion, ranked.
        suggestions: Vec<mimicgen_run::doctor::Suggestion>,
        /// Arms to run.
        arms: usize,
        /// Attempts per arm.
        attempts: usize,
    },
    /// An attempt of arm `arm` was decided.
    Attempt {
        /// 0: the run's spec; k: the k-th suggestion.
        arm: usize,
        /// Attempts of the arm decided.
        done: usize,
        /// Of those, successes.
        successes: usize,
    },
    /// The diagnosis.
    Finished(Box<mimicgen_run::doctor::Diagnosis>),
    /// The doctor stopped on an error or a cancel.
    Failed(String),
}

/// What a running generation reports (after [`Request::Run`] was accepted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum RunUpdate {
    /// The run has started; `dimensions` are the task variant's reset region per object coordinate
    /// (what the coverage view bins, as `mimicgen coverage` does).
    Started {
        /// The run.
        info: Box<RunInfo>,
        /// The reset region per object coordinate.
        dimensions: Vec<Dimension>,
    },
    /// An attempt was decided (in index order).
    Attempt(Box<AttemptRow>),
    /// The run has ended (completed or cancelled); its outputs are complete.
    Finished(Box<Report>),
    /// A run of this config, started elsewhere (another browser tab, or before this tab was
    /// opened), is what the updates after this one are of.
    Joined(Box<RunConfig>),
    /// The run stopped on an error (naming the file and field).
    Failed(String),
}

/// One decided attempt of a run, as the attempt table shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttemptRow {
    /// Attempt index (its random stream).
    pub index: u64,
    /// Whether the task was achieved.
    pub success: bool,
    /// The subtask that went wrong, if it failed.
    pub failed_subtask: Option<usize>,
    /// Why, if it failed.
    pub reason: Option<String>,
    /// What went wrong there ([`mimicgen_engine::diagnose::Cause`], in words), if it failed and
    /// the run or file recorded it.
    #[serde(default)]
    pub cause: Option<String>,
    /// The source demo of each subtask.
    pub sources: Vec<usize>,
    /// Executed steps.
    pub steps: usize,
    /// Where it went: the demo written, the failed demo kept, or "discarded".
    pub outcome: String,
    /// Seconds since the run started.
    pub elapsed_s: f64,
    /// The scene's objects before the first action.
    pub objects: Vec<ObjectView>,
    /// The object instance its episode drew (object transfer: which mug); `None` for the other
    /// tasks.
    #[serde(default)]
    pub instance: Option<String>,
    /// Statistics of the run so far, this attempt included.
    pub stats: RunStats,
}

/// Where the 3D view streams.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum ViewerSink {
    /// Start the Rerun viewer from the `rerun-sdk` wheel the setup installs.
    Spawn,
    /// A running viewer at this gRPC URL.
    Connect(String),
    /// A `.rrd` file.
    Save(PathBuf),
    /// The viewer embedded in the app's window (builds with the `viewer` feature): a new recording
    /// per shown demo or tried attempt, on the `step` timeline the app's cursor drives.
    Embedded,
}

/// What a preview is of.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PreviewRequest {
    /// The source demos.
    pub source: PathBuf,
    /// Subtask ends and segment starts per demo, as annotated.
    pub marks: SubtaskMarks,
    /// Run seed.
    pub seed: u64,
    /// Attempt index (its scene and random draws).
    pub index: u64,
    /// The source demo forced for each subtask (`None`: the selection strategy picks).
    pub sources: Vec<Option<usize>>,
    /// Objects moved by hand: their new (x, y) on the table (height and rotation as sampled).
    pub moved: BTreeMap<String, [f64; 2]>,
    /// Also execute the attempt.
    pub execute: bool,
    /// Task variant (`None`: what the source file names).
    pub variant: Option<String>,
    /// Spec fields set over the task spec's (the run form's, or the re-run run's).
    pub spec: SpecOverrides,
    /// A two-arm file: each arm's subtask ends per demo (`marks` is then unused). A two-arm
    /// preview is always tried: an arm's later subtasks are planned as the schedule starts them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub arm_ends: Vec<BTreeMap<String, Vec<usize>>>,
}

/// A reply from the backend. Each request gets exactly one reply that [`Reply::ends_request`];
/// progress and the first parts of a streamed file come before it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    /// A file was opened: its first demos (the rest follow as [`Reply::MoreDemos`]).
    Opened(Box<LoadedFile>),
    /// More demos of the file being opened.
    MoreDemos {
        /// The file.
        path: PathBuf,
        /// The demos, in file order after those sent before.
        demos: Vec<DemoView>,
        /// Whether these are the file's last.
        last: bool,
    },
    /// A file was written.
    Saved {
        /// Where.
        out: PathBuf,
        /// How many demos carry annotations.
        demos: usize,
    },
    /// The 3D view streams to `to`.
    Streaming {
        /// Where (in words).
        to: String,
    },
    /// A demo was shown (and sent to the 3D view, when it is open).
    Shown {
        /// What.
        what: String,
    },
    /// A demo's camera observations (sent after opening, for the first demo, and on
    /// [`Request::ShowDemo`]; none when the file has no camera observations).
    Images {
        /// The demo (index in the open file).
        demo: usize,
        /// Its RGB cameras.
        cameras: Vec<CameraView>,
    },
    /// A preview (and, if asked, its execution) is ready.
    Previewed(Box<PreviewView>),
    /// Both attempts of a [`Request::SideBySide`], executed.
    SideBySide(Box<[PreviewView; 2]>),
    /// A run was started (its updates follow as [`Reply::Run`]).
    RunAccepted,
    /// A finished run's outputs were read (their updates came before).
    RunOpened,
    /// A directory's subdirectories and datasets.
    Listing(Box<Listing>),
    /// A run's outputs, read to compare with.
    Compared(Box<OpenedRun>),
    /// The run was asked to stop.
    Cancelling,
    /// What the running generation reports.
    Run(RunUpdate),
    /// The doctor was started (its updates follow as [`Reply::Doctor`]).
    DoctorAccepted,
    /// What the run doctor reports.
    Doctor(DoctorUpdate),
    /// Progress of a long request (the request's own reply comes after).
    Progress {
        /// What is being done.
        what: String,
        /// Units done.
        done: usize,
        /// Units in all.
        total: usize,
    },
    /// The backend greets the app when it connects (not a reply to a request).
    Welcome(Box<Welcome>),
    /// Something another tab did that changes this one's backend (not a reply to a request).
    Notice(String),
    /// A request failed; `error` names the file and field.
    Failed {
        /// What was being done.
        what: String,
        /// The error, whole.
        error: String,
    },
}

/// A source file as the UI shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoadedFile {
    /// The file (for a plain robomimic file, the prepared copy the app made of it).
    pub path: PathBuf,
    /// The plain robomimic file it was prepared from, if it was.
    pub prepared_from: Option<PathBuf>,
    /// The task it was recorded in.
    pub task: String,
    /// The task's variants (what a run or preview may draw scenes from).
    pub variants: Vec<String>,
    /// The signal each subtask but the last ends with (the names written on save).
    pub signal_names: Vec<String>,
    /// The object each subtask is relative to.
    pub subtask_objects: Vec<Option<String>>,
    /// Per subtask, how near its object the end effector must come for the segment to start
    /// there (m; the spec's `approach_m`, what the auto-detected start uses).
    pub approach_m: Vec<f64>,
    /// Per subtask, whether the spec plans its transit (only then does a segment start matter).
    pub planned: Vec<bool>,
    /// How many demos the file has (more than `demos` while it is still streaming in).
    pub total_demos: usize,
    /// The demos read so far, in file order.
    pub demos: Vec<DemoView>,
    /// A two-arm file's arms (empty for one arm): each arm's subtasks and its view of every demo.
    /// `signal_names`, `subtask_objects` and `demos` above are the first arm's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub arms: Vec<ArmFile>,
}

impl LoadedFile {
    /// The task of a two-arm file (`two_arm_lift`); `None` for one arm.
    #[must_use]
    pub fn two_arm_task(&self) -> Option<&str> {
        (!self.arms.is_empty()).then_some(self.task.as_str())
    }
}

/// One arm of a two-arm file: its subtasks and its view of the demos (its gripper, its end
/// effector, its proposals and stored ends).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArmFile {
    /// The arm (`robot0`).
    pub name: String,
    /// The signal each of its subtasks but the last ends with.
    pub signal_names: Vec<String>,
    /// The object each of its subtasks is relative to.
    pub subtask_objects: Vec<Option<String>>,
    /// Its view of every demo, in file order.
    pub demos: Vec<DemoView>,
}

/// One arm's annotation to save: its signal names and its ends per demo.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ArmMarks {
    /// The signal each subtask but the last ends with.
    pub signal_names: Vec<String>,
    /// Ends (exclusive) per demo.
    pub ends: BTreeMap<String, Vec<usize>>,
}

/// One camera's images of a demo, every step (`obs/<name>_image`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraView {
    /// The camera (`agentview`).
    pub name: String,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// RGB bytes of every step, one image after another.
    pub rgb: Vec<u8>,
}

impl CameraView {
    /// Step `t`'s image (the last one past the end; `None` without images).
    #[must_use]
    pub fn frame(&self, t: usize) -> Option<&[u8]> {
        let size = self.width * self.height * 3;
        let steps = self.rgb.len().checked_div(size)?;
        let t = t.min(steps.checked_sub(1)?);
        self.rgb.get(t * size..(t + 1) * size)
    }
}

/// A proposed subtask end.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProposalView {
    /// End (exclusive).
    pub end: usize,
    /// 0 to 1.
    pub confidence: f64,
    /// Why.
    pub reason: String,
}

/// One demo's timeline: what the plots draw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DemoView {
    /// Its name.
    pub name: String,
    /// Steps.
    pub len: usize,
    /// Gripper command per step (-1 open, +1 close).
    pub gripper: Vec<f64>,
    /// Finger opening per step (m), when the states hold it.
    pub finger_width_m: Option<Vec<f64>>,
    /// End-effector speed per step (m/s at 20 Hz).
    pub eef_speed: Vec<f64>,
    /// Distance from the gripper to each object per step (m).
    pub distances: BTreeMap<String, Vec<f64>>,
    /// The stored subtask-end signals.
    pub signals: BTreeMap<String, Vec<i64>>,
    /// The ends the stored signals give (exclusive), when they give all.
    pub stored_ends: Option<Vec<usize>>,
    /// The segment starts marked in the file (one per subtask, `None` where unmarked).
    pub stored_starts: Option<Vec<Option<usize>>>,
    /// Proposed ends.
    pub proposals: Vec<ProposalView>,
}

/// A position in the world frame (m).
pub type Point = [f64; 3];

/// An object of a previewed scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectView {
    /// Its name.
    pub name: String,
    /// Its position.
    pub position: Point,
    /// Its rotation about the vertical (rad).
    pub yaw: f64,
}

/// One source demo in the selection's ranking.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RankView {
    /// Demo index.
    pub demo: usize,
    /// Its name.
    pub name: String,
    /// The strategy's distance to the new scene.
    pub distance: f64,
}

/// One subtask of a previewed attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubtaskPreview {
    /// The object the segment is relative to.
    pub object: Option<String>,
    /// The source demo used.
    pub src_demo: usize,
    /// Its name.
    pub src_demo_name: String,
    /// The segment's steps in that demo (after this attempt's offsets).
    pub src_span: (usize, usize),
    /// Every demo by the strategy's distance, nearest first (empty when the source was kept from
    /// the previous subtask or the strategy is random).
    pub ranking: Vec<RankView>,
    /// The source segment's end-effector targets, in the source scene.
    pub source_path: Vec<Point>,
    /// The reference object in the source scene at the segment start.
    pub source_object: Option<Point>,
    /// The interpolation bridge (from the previous target to the transformed segment).
    pub bridge: Vec<Point>,
    /// The planned collision-free transit to the segment (`--transit plan`), empty otherwise; a
    /// later subtask's is known once the attempt is tried (its start is where the robot got to).
    #[serde(default)]
    pub transit: Vec<Point>,
    /// The hand's targets while a mobile base drives (its actions copied from the source, the
    /// hand held still on it): the base's path, lifted to the hand. Empty for an arm fixed in the
    /// world.
    #[serde(default)]
    pub drive: Vec<Point>,
    /// The transformed segment.
    pub transformed: Vec<Point>,
}

/// A previewed attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PreviewView {
    /// Task.
    pub task: String,
    /// Variant the scene was drawn from.
    pub variant: String,
    /// Run seed.
    pub seed: u64,
    /// Attempt index.
    pub index: u64,
    /// The end effector before the first action.
    pub eef: Point,
    /// The scene's objects.
    pub objects: Vec<ObjectView>,
    /// Per subtask.
    pub subtasks: Vec<SubtaskPreview>,
    /// The attempt as executed, when asked for.
    pub executed: Option<ExecutedView>,
    /// Why the executed attempt could not be sent to the 3D view, if it could not.
    pub failure_3d: Option<String>,
    /// A two-arm attempt: each arm's part (empty for one arm).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub arms: Vec<ArmPreview>,
    /// A two-arm attempt's ties, where both of their subtasks ran.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ties: Vec<TiePreview>,
}

/// One arm of a tried two-arm attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArmPreview {
    /// The arm (`robot0`).
    pub name: String,
    /// Its end effector at every step.
    pub path: Vec<Point>,
    /// Per subtask it started: its waypoints (interpolation, then the transformed segment).
    pub segments: Vec<Vec<Point>>,
    /// The source demo each of its subtasks used.
    pub sources: Vec<usize>,
}

/// A tie between two subtasks of a tried two-arm attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TiePreview {
    /// Coordinated (both ran together) or sequential (`to` waited for `from` to end).
    pub coordination: bool,
    /// `(arm, subtask)` of the first (the one waited for).
    pub from: (usize, usize),
    /// `(arm, subtask)` of the other.
    pub to: (usize, usize),
    /// Where the first's arm was: where the pair started, or where the first one ended.
    pub from_point: Point,
    /// Where the other's arm was when it started.
    pub to_point: Point,
    /// The steps: the pair's, or from the first's end to the other's start.
    pub steps: (usize, usize),
}

/// An executed attempt ("try it").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExecutedView {
    /// Whether the task was achieved.
    pub success: bool,
    /// Where and why it failed.
    pub failure: Option<String>,
    /// What went wrong there, in words ([`crate::protocol::AttemptRow::cause`]'s).
    #[serde(default)]
    pub cause: Option<String>,
    /// The end effector at every step.
    pub path: Vec<Point>,
    /// The targets the attempt planned (its own, subtask by subtask as it went).
    pub planned: Vec<Point>,
    /// The subtask of every step.
    pub subtask_of_step: Vec<usize>,
    /// The source demo each subtask used.
    pub sources: Vec<usize>,
    /// The objects where the attempt ended.
    pub final_objects: Vec<ObjectView>,
    /// What happened in each executed subtask, in numbers.
    pub diagnostics: Vec<SubtaskDiagnostics>,
}

/// One executed subtask in numbers: how close the arm got to the last target, whether the
/// subtask's object moved before the subtask ended (pushed before a grasp), and how far an object
/// held from the previous subtask slid in the gripper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubtaskDiagnostics {
    /// The subtask.
    pub subtask: usize,
    /// Its executed steps (first, end exclusive).
    pub steps: (usize, usize),
    /// Distance between the controller's last target and the end effector at the subtask's end (mm).
    pub target_error_mm: f64,
    /// How far the subtask's reference object moved during the subtask (mm).
    pub object_moved_mm: Option<f64>,
    /// How far the previous subtask's object moved relative to the gripper during this subtask (mm):
    /// slip of a held object.
    pub held_object_slip_mm: Option<f64>,
}

impl Reply {
    /// Whether this is the last reply to its request.
    #[must_use]
    pub fn ends_request(&self) -> bool {
        match self {
            Self::Progress { .. } | Self::Run(_) | Self::Doctor(_) | Self::Images { .. } | Self::Welcome(_) | Self::Notice(_) => false,
            Self::Opened(file) => file.demos.len() >= file.total_demos,
            Self::MoreDemos { last, .. } => *last,
            Self::Saved { .. }
            | Self::Streaming { .. }
            | Self::Shown { .. }
            | Self::Previewed(_)
            | Self::SideBySide(_)
            | Self::RunAccepted
            | Self::DoctorAccepted
            | Self::RunOpened
            | Self::Listing(_)
            | Self::Compared(_)
            | Self::Cancelling
            | Self::Failed { .. } => true,
        }
    }
}

/// A directory as the file browser shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Listing {
    /// The directory (absolute).
    pub dir: PathBuf,
    /// Its parent, if it has one.
    pub parent: Option<PathBuf>,
    /// Subdirectories (not hidden), sorted.
    pub dirs: Vec<PathBuf>,
    /// HDF5 files (`.hdf5`, `.h5`) with their sizes in bytes, sorted.
    pub files: Vec<(PathBuf, u64)>,
}

/// A finished run's outputs, read whole.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OpenedRun {
    /// The dataset.
    pub path: PathBuf,
    /// The run (from its report, or what the files say).
    pub info: RunInfo,
    /// The task variant's reset region per object coordinate.
    pub dimensions: Vec<Dimension>,
    /// Every attempt kept in the files, by index.
    pub rows: Vec<AttemptRow>,
    /// Its report (or one made from the files).
    pub report: Report,
}

/// What the backend tells the app when it connects.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Welcome {
    /// The backend machine's cores (the most workers a run should take).
    pub cores: usize,
    /// The folder every path is confined to (`mimicgen serve --root`); none on the desktop.
    pub root: Option<PathBuf>,
    /// A file to open (`mimicgen serve FILE`).
    pub file: Option<PathBuf>,
    /// Where the 3D view is, for a browser: the Rerun web viewer's page, when the server has one.
    pub viewer_url: Option<String>,
    /// The arms a run can use (`panda`, `sawyer`, ...).
    pub robots: Vec<String>,
}

/// A request as a browser sends it: with an id its replies carry back.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClientMessage {
    /// Chosen by the client, increasing.
    pub id: u64,
    /// The request.
    pub request: Request,
}

/// A reply as the server sends it: the id of the request it answers, or none for what nobody
/// asked for in this tab (the greeting, and the updates of a run every tab watches).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ServerMessage {
    /// The request's id.
    pub id: Option<u64>,
    /// The reply.
    pub reply: Reply,
}

/// A [`ServerMessage`] as it crosses the socket: JSON text, or for camera images one binary frame
/// (see [`ServerMessage::to_frame`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Frame {
    /// A text frame: the message's JSON.
    Text(String),
    /// A binary frame: `[u32 LE: n][n bytes of the message's JSON, images' bytes left out][the
    /// images' bytes, camera after camera]`.
    Binary(Vec<u8>),
}

impl ServerMessage {
    /// The message as a WebSocket frame: [`Reply::Images`] binary (its pixels as bytes, not
    /// JSON number arrays, which are about 3.6 bytes per byte), anything else JSON text.
    ///
    /// # Errors
    /// JSON's, for a message it cannot write (not expected: replies are plain data).
    pub fn to_frame(&self) -> Result<Frame, String> {
        let json = |m: &Self| serde_json::to_string(m).map_err(|e| e.to_string());
        let Reply::Images { demo, cameras } = &self.reply else { return json(self).map(Frame::Text) };
        let header = Self {
            id: self.id,
            reply: Reply::Images {
                demo: *demo,
                cameras: cameras.iter().map(|c| CameraView { rgb: Vec::new(), name: c.name.clone(), ..*c }).collect(),
            },
        };
        let header = json(&header)?;
        let len = u32::try_from(header.len()).map_err(|_| "a reply header over 4 GiB".to_owned())?;
        let mut bytes = Vec::with_capacity(4 + header.len() + cameras.iter().map(|c| c.rgb.len()).sum::<usize>());
        bytes.extend_from_slice(&len.to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        for camera in cameras {
            bytes.extend_from_slice(&u64::try_from(camera.rgb.len()).unwrap_or(u64::MAX).to_le_bytes());
            bytes.extend_from_slice(&camera.rgb);
        }
        Ok(Frame::Binary(bytes))
    }

    /// Reads a binary frame [`ServerMessage::to_frame`] wrote.
    ///
    /// # Errors
    /// What is wrong with it (too short, not JSON, bytes missing or left over).
    pub fn from_binary(bytes: &[u8]) -> Result<Self, String> {
        let take = |bytes: &mut &[u8], n: usize, what: &str| -> Result<Vec<u8>, String> {
            if bytes.len() < n {
                return Err(format!("a binary reply cut short in {what} ({} of {n} bytes)", bytes.len()));
            }
            let (head, rest) = bytes.split_at(n);
            *bytes = rest;
            Ok(head.to_vec())
        };
        let mut rest = bytes;
        let word = |b: Vec<u8>| b.iter().rev().fold(0_u64, |acc, &x| (acc << 8) | u64::from(x));
        let len = usize::try_from(word(take(&mut rest, 4, "its length")?)).map_err(|e| e.to_string())?;
        let header = take(&mut rest, len, "its header")?;
        let mut message: Self = serde_json::from_slice(&header).map_err(|e| format!("a binary reply's header: {e}"))?;
        let Reply::Images { cameras, .. } = &mut message.reply else { return Err("a binary reply that is not images".to_owned()) };
        for camera in cameras {
            let n = usize::try_from(word(take(&mut rest, 8, "an image's length")?)).map_err(|e| e.to_string())?;
            camera.rgb = take(&mut rest, n, &format!("camera {}", camera.name))?;
        }
        if !rest.is_empty() {
            return Err(format!("a binary reply with {} bytes left over", rest.len()));
        }
        Ok(message)
    }
}

#[cfg(test)]
mod frame_tests {
    use super::*;

    #[test]
    fn images_cross_as_bytes_and_read_back_and_everything_else_as_json() {
        // Two cameras of 84 x 84 over 50 steps, as a generated dataset has them.
        let camera = |name: &str, seed: u8| CameraView {
            name: name.to_owned(),
            width: 84,
            height: 84,
            rgb: (0..84 * 84 * 3 * 50).map(|i: usize| (i % 251) as u8 ^ seed).collect(),
        };
        let message =
            ServerMessage { id: Some(7), reply: Reply::Images { demo: 3, cameras: vec![camera("agentview", 0), camera("wrist", 99)] } };
        let Ok(Frame::Binary(bytes)) = message.to_frame() else { panic!("images are binary") };
        assert_eq!(ServerMessage::from_binary(&bytes).unwrap(), message);
        let json = serde_json::to_string(&message).unwrap().len();
        let pixels = 2 * 84 * 84 * 3 * 50;
        println!("images of 2 cameras x 50 steps (84 x 84): {pixels} pixel bytes; JSON {json} bytes, binary frame {} bytes", bytes.len());
        assert!(bytes.len() < pixels + 400, "binary: {} bytes for {pixels}", bytes.len());
        assert!(json > 3 * pixels, "JSON arrays: {json} bytes for {pixels}");
        // Damaged frames are refused, saying how.
        assert!(ServerMessage::from_binary(&bytes[..bytes.len() - 1]).unwrap_err().contains("cut short"));
        assert!(ServerMessage::from_binary(&[bytes.as_slice(), &[0]].concat()).unwrap_err().contains("left over"));
        assert!(ServerMessage::from_binary(&[9, 0, 0, 0, b'{']).unwrap_err().contains("cut short"));
        let other = ServerMessage { id: None, reply: Reply::Notice("hello".to_owned()) };
        assert_eq!(other.to_frame().unwrap(), Frame::Text(serde_json::to_string(&other).unwrap()));
    }
}
