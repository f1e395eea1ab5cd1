//! What the UI and its backend say to each other: plain, serializable requests and replies, so
//! the same UI can later talk to a backend over a WebSocket from a browser.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// A request to the backend (file reads, detection, writes: everything that may take time).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Request {
    /// Read a source file and propose its subtask ends.
    Open {
        /// The file.
        path: PathBuf,
    },
    /// Write `source` to `out` with these subtask ends (exclusive, per demo).
    Save {
        /// The file the demos came from.
        source: PathBuf,
        /// Where to write.
        out: PathBuf,
        /// Ends per demo.
        ends: BTreeMap<String, Vec<usize>>,
        /// The signal each subtask end is written to.
        signal_names: Vec<String>,
    },
}

/// A reply from the backend.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    /// A file was read.
    Opened(Box<LoadedFile>),
    /// A file was written.
    Saved {
        /// Where.
        out: PathBuf,
        /// How many demos carry annotations.
        demos: usize,
    },
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
    /// The file.
    pub path: PathBuf,
    /// The task it was recorded in.
    pub task: String,
    /// The signal each subtask but the last ends with (the names written on save).
    pub signal_names: Vec<String>,
    /// The object each subtask is relative to.
    pub subtask_objects: Vec<Option<String>>,
    /// The demos, in file order.
    pub demos: Vec<DemoView>,
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
    /// Proposed ends.
    pub proposals: Vec<ProposalView>,
}
