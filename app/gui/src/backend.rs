//! The backend: a named worker thread that reads, detects and writes, and replies over a channel.
//! The UI never waits on it; it asks for a repaint when a reply is ready.

use std::path::Path;
use std::sync::mpsc::{Receiver, Sender, channel};

use mimicgen_pipeline::annotate;

use crate::protocol::{DemoView, LoadedFile, ProposalView, Reply, Request};

/// Control rate of the recorded demos (robosuite's 20 Hz), for speeds.
const CONTROL_HZ: f64 = 20.0;

/// Reads `path` and turns every demo into what the timeline draws.
///
/// # Errors
/// The pipeline's error, whole (it names the file and field).
pub fn open(path: &Path) -> Result<LoadedFile, mimicgen_pipeline::PipelineError> {
    let found = annotate::propose(path, None, None)?;
    let spec = &found.spec;
    let demos = found
        .demos
        .iter()
        .zip(&found.sources.demos)
        .map(|(a, d)| {
            let eef: Vec<_> = d.eef_poses.iter().map(|p| p.translation.vector).collect();
            let mut eef_speed: Vec<f64> = eef.windows(2).map(|w| (w[1] - w[0]).norm() * CONTROL_HZ).collect();
            eef_speed.push(eef_speed.last().copied().unwrap_or_default());
            DemoView {
                name: a.demo.clone(),
                len: a.len,
                gripper: (0..d.len()).map(|t| d.gripper_actions.row(t).first().copied().unwrap_or_default()).collect(),
                finger_width_m: a.finger_width_m.clone(),
                eef_speed,
                distances: d
                    .object_poses
                    .iter()
                    .map(|(name, poses)| (name.clone(), poses.iter().zip(&eef).map(|(p, e)| (p.translation.vector - e).norm()).collect()))
                    .collect(),
                signals: d.subtask_term_signals.clone(),
                stored_ends: a.signal_ends.clone(),
                proposals: a
                    .proposals
                    .iter()
                    .map(|p| ProposalView { end: p.end, confidence: p.confidence, reason: p.reason.clone() })
                    .collect(),
            }
        })
        .collect();
    let last = spec.subtasks.len().saturating_sub(1);
    Ok(LoadedFile {
        path: path.to_path_buf(),
        task: spec.name.clone(),
        signal_names: spec.subtasks.iter().take(last).map(|s| s.term_signal.clone().unwrap_or_default()).collect(),
        subtask_objects: spec.subtasks.iter().map(|s| s.object_ref.clone()).collect(),
        demos,
    })
}

/// Answers one request.
#[must_use]
pub fn handle(request: Request) -> Reply {
    match request {
        Request::Open { path } => match open(&path) {
            Ok(file) => Reply::Opened(Box::new(file)),
            Err(e) => Reply::Failed { what: format!("opening {}", path.display()), error: e.to_string() },
        },
        Request::Save { source, out, ends, signal_names } => match annotate::write_signals(&source, &out, &signal_names, &ends) {
            Ok(()) => Reply::Saved { out, demos: ends.len() },
            Err(e) => Reply::Failed { what: format!("saving {}", out.display()), error: e.to_string() },
        },
    }
}

/// The UI's end of the backend.
#[derive(Debug)]
pub struct Backend {
    requests: Sender<Request>,
    replies: Receiver<Reply>,
}

impl Backend {
    /// Starts the worker thread; `repaint` is called after every reply.
    ///
    /// # Panics
    /// Never on purpose; if the OS cannot start a thread, replies report it.
    #[must_use]
    pub fn start(repaint: impl Fn() + Send + 'static) -> Self {
        let (requests, inbox) = channel::<Request>();
        let (outbox, replies) = channel::<Reply>();
        let failed = outbox.clone();
        let spawned = std::thread::Builder::new().name("mimicgen-gui-backend".to_owned()).spawn(move || {
            for request in inbox {
                if outbox.send(handle(request)).is_err() {
                    break;
                }
                repaint();
            }
        });
        if let Err(e) = spawned {
            let _ = failed.send(Reply::Failed { what: "starting the backend thread".to_owned(), error: e.to_string() });
        }
        Self { requests, replies }
    }

    /// Queues a request.
    pub fn send(&self, request: Request) {
        let _ = self.requests.send(request);
    }

    /// Replies that have arrived (never blocks).
    pub fn try_replies(&self) -> Vec<Reply> {
        self.replies.try_iter().collect()
    }
}
