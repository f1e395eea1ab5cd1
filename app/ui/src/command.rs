//! Everything the user can do: what the UI (or a test) sends [`crate::AppModel::apply`], and the
//! screens it can show.

use std::path::PathBuf;

use crate::protocol::ViewerSink;
use crate::run_state::RunForm;

/// The app's screens.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Screen {
    /// Demo timelines and subtask ends.
    #[default]
    Annotate,
    /// A transformed attempt over a new scene, and "try it".
    Preview,
    /// A generation run: its form, live progress and attempts.
    Generate,
}

/// Everything the user can do.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// Open a source file.
    Open(PathBuf),
    /// Show demo `index`.
    SelectDemo(usize),
    /// Put the time cursor at a step.
    SetCursor(usize),
    /// Move the time cursor by this many steps.
    StepCursor(i64),
    /// Choose which subtask end the keyboard and "set at cursor" move.
    SelectBoundary(usize),
    /// In a two-arm file, annotate arm `k` (its timeline, plots and ends).
    SelectArm(usize),
    /// Set the end of `subtask` (its last step is `end - 1`) in the shown demo.
    SetEnd {
        /// The subtask.
        subtask: usize,
        /// The end (exclusive).
        end: usize,
    },
    /// Set the selected boundary so that the step under the cursor is its subtask's last.
    SetEndAtCursor,
    /// Mark where the segment of `subtask` starts in the shown demo (`None`: unmark, so the
    /// approach detector decides). Matters for subtasks whose transit is planned.
    SetStart {
        /// The subtask.
        subtask: usize,
        /// The first step of its segment.
        start: Option<usize>,
    },
    /// Mark the step under the cursor as the start of the segment of the subtask it lies in.
    SetStartAtCursor,
    /// Replace the shown demo's ends with the proposals.
    AcceptProposals,
    /// Replace every demo's ends with the proposals.
    AcceptAllProposals,
    /// Undo the last change of ends.
    Undo,
    /// Redo what was undone.
    Redo,
    /// Write the annotations to a new file (an existing one only with [`Command::SetSaveOverwrite`]).
    Save(PathBuf),
    /// Whether "Save as" may replace an existing file.
    SetSaveOverwrite(bool),
    /// Start or stop playing the shown demo.
    TogglePlay,
    /// Advance playback by one step (the UI sends it at the control rate while playing).
    Tick,
    /// Show a screen (the preview screen asks for a fresh preview).
    Show(Screen),
    /// Preview the scenes of a run with this seed.
    SetPreviewSeed(u64),
    /// Preview attempt `index` of the run.
    SetPreviewIndex(u64),
    /// Preview the next attempt's scene.
    NextScene,
    /// Force the source demo of a subtask (`None`: let the selection strategy pick).
    SetPreviewSource {
        /// The subtask.
        subtask: usize,
        /// The demo index.
        demo: Option<usize>,
    },
    /// Execute the previewed attempt in simulation.
    TryIt,
    /// Move an object of the previewed scene to (x, y) on the table.
    MoveObject {
        /// The object.
        name: String,
        /// Where (m, world frame).
        xy: [f64; 2],
    },
    /// Put every moved object back where the scene had it.
    ResetObjects,
    /// Change the run form.
    SetRunForm(Box<RunForm>),
    /// Start a run as the form says, over the open file.
    StartRun,
    /// Stop the run (after the attempts already decided).
    CancelRun,
    /// Show attempt `index` of the run on the preview screen and try it again.
    ReRun(u64),
    /// Re-run a failed attempt and a successful one of the run and show them side by side.
    SideBySide {
        /// The failed attempt's index.
        failed: u64,
        /// The successful attempt's index (`None`: the nearest success, see [`crate::run_state::nearest_success`]).
        success: Option<u64>,
    },
    /// Stop showing two attempts side by side.
    CloseSideBySide,
    /// Select an attempt of the run (the 3D view stays on it: following the latest stops).
    SelectAttempt(u64),
    /// Let the 3D view follow the run's latest attempt (or stay on the selected one).
    FollowLatest(bool),
    /// Read a finished run's outputs (the dataset `generate` wrote, its `_failed.hdf5` and report).
    OpenRun(PathBuf),
    /// Read a finished run's outputs to compare the current run's coverage with.
    OpenCompare(PathBuf),
    /// Stop comparing.
    CloseCompare,
    /// Show the file browser at a directory.
    Browse(PathBuf),
    /// Close the file browser.
    CloseBrowser,
    /// Stream the shown demo, and every demo shown and attempt tried after, to Rerun.
    Open3d(ViewerSink),
    /// Set the doctor's budget (attempts in all) and how many suggestions it tests.
    SetDoctor {
        /// Attempts to simulate in all.
        budget: usize,
        /// Suggestions to test.
        top: usize,
    },
    /// Unfold (or fold) the Doctor panel.
    ShowDoctor(bool),
    /// Diagnose the finished run shown (`mimicgen doctor`).
    Diagnose,
    /// Stop the doctor.
    CancelDoctor,
    /// Put a tested change into the run form, over the diagnosed run's spec fields.
    UseSuggestion(usize),
}
