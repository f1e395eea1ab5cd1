//! What a run reports as it goes, to every front end.

use mimicgen_engine::{Attempt, RunStats};

use crate::{Outcome, Report, RunInfo};

/// What a run reports as it goes. Front ends (the CLI's progress bar, the app, Python) consume
/// these; the run itself prints nothing.
#[derive(Debug, Clone)]
pub enum Event {
    /// The run has started.
    Started(Box<RunInfo>),
    /// An attempt was decided (in index order).
    Attempt(Box<AttemptEvent>),
    /// The run has ended (completed or cancelled) and its outputs are complete.
    Finished(Box<Report>),
}

/// One decided attempt.
#[derive(Debug, Clone)]
pub struct AttemptEvent {
    /// The attempt's full record.
    pub attempt: Attempt,
    /// Where it went.
    pub outcome: Outcome,
    /// The object instance its episode drew (object transfer: which mug); `None` for the other
    /// tasks.
    pub instance: Option<String>,
    /// Statistics of the run so far, this attempt included.
    pub stats: RunStats,
    /// Seconds since this session of the run started.
    pub elapsed_s: f64,
}
