//! How a run is scheduled: attempts over several workers, handed back strictly in index order,
//! shards of a run, and the run's statistics.

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, mpsc};

use serde::{Deserialize, Serialize};

use super::attempt::Generator;
use super::records::{Attempt, Failure, FailureReason};
use crate::EngineError;
use crate::env::Environment;

/// Attempts and successes that used one source demo.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DemoUse {
    /// Attempts in which this demo supplied at least one segment.
    pub attempts: usize,
    /// Of those, how many succeeded.
    pub successes: usize,
}

/// How many attempts failed in one subtask for one reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FailureCount {
    /// The subtask.
    pub subtask: usize,
    /// The reason.
    pub reason: FailureReason,
    /// The count.
    pub count: usize,
}

/// How many attempts failed in one subtask for one cause class ([`crate::diagnose::Cause::class`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CauseCount {
    /// The subtask.
    pub subtask: usize,
    /// The cause's class (`grasp_missed`).
    pub class: String,
    /// The count.
    pub count: usize,
}

/// Running statistics of a generation run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RunStats {
    /// Attempts accepted so far.
    pub attempts: usize,
    /// Successful attempts so far.
    pub successes: usize,
    /// Per source demo, by dataset index.
    pub per_source_demo: Vec<DemoUse>,
    /// The success matrix: per subtask, per source demo (by dataset index), the attempts whose
    /// segment for that subtask came from that demo, and their successes.
    #[serde(default)]
    pub per_subtask_source: Vec<Vec<DemoUse>>,
    /// Failures by subtask and reason, sorted.
    pub failures: Vec<FailureCount>,
    /// Failures by subtask and cause class, sorted.
    #[serde(default)]
    pub causes: Vec<CauseCount>,
    /// Planned transits and obstacle contacts (all zero in a run without either).
    #[serde(default)]
    pub transit: TransitTotals,
}

/// What planned transit and clutter did over a run.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct TransitTotals {
    /// Transits planned (found or not).
    pub planned: usize,
    /// Of those, how many found no collision-free path.
    pub no_path: usize,
    /// Planning time over all of them (s).
    pub planning_s: f64,
    /// Attempts in which the robot, or what it held, touched an obstacle.
    pub obstacle_attempts: usize,
    /// Control steps with such a contact, over all attempts.
    pub obstacle_steps: usize,
}

impl TransitTotals {
    /// Whether nothing was planned or touched.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

impl RunStats {
    /// Statistics for a dataset of `num_demos` source demos.
    #[must_use]
    pub fn new(num_demos: usize) -> Self {
        Self { per_source_demo: vec![DemoUse::default(); num_demos], ..Self::default() }
    }

    /// The data generation rate: successes / attempts (0 before any attempt).
    #[must_use]
    pub fn rate(&self) -> f64 {
        #[allow(clippy::cast_precision_loss)] // counts are far below 2^52
        if self.attempts == 0 { 0.0 } else { self.successes as f64 / self.attempts as f64 }
    }

    /// The source demos that supplied a segment to at least `min_uses` attempts and never to a
    /// success, by dataset index.
    #[must_use]
    pub fn never_succeeded(&self, min_uses: usize) -> Vec<usize> {
        self.per_source_demo.iter().enumerate().filter(|(_, d)| d.attempts >= min_uses && d.successes == 0).map(|(demo, _)| demo).collect()
    }

    /// Counts one attempt.
    pub fn record(&mut self, attempt: &Attempt) {
        self.record_outcome(attempt.success, &attempt.src_demo_per_subtask, attempt.failure.as_ref(), attempt.cause.as_ref());
        for stats in attempt.plans.iter().filter_map(|p| p.transit) {
            self.transit.planned += 1;
            self.transit.planning_s += stats.seconds;
        }
        self.transit.no_path +=
            usize::from(attempt.failure.as_ref().is_some_and(|f| matches!(f.reason, FailureReason::NoTransitPath { .. })));
        self.transit.obstacle_attempts += usize::from(attempt.obstacle_contact_steps > 0);
        self.transit.obstacle_steps += attempt.obstacle_contact_steps;
    }

    /// Counts one attempt from its outcome: whether it succeeded, the source demo of each subtask,
    /// where it failed and why (what [`Self::record`] reads of an [`Attempt`]).
    pub fn record_outcome(&mut self, success: bool, sources: &[usize], failure: Option<&Failure>, cause: Option<&crate::diagnose::Cause>) {
        self.record_sources(success, sources.iter().copied().enumerate(), failure, cause);
    }

    /// As [`Self::record_outcome`], the source demo given per subtask index as `(subtask, demo)`
    /// pairs: subtasks that did not run are left out (a two-arm attempt numbers arm 1's subtasks
    /// after arm 0's).
    pub fn record_sources(
        &mut self,
        success: bool,
        sources: impl IntoIterator<Item = (usize, usize)>,
        failure: Option<&Failure>,
        cause: Option<&crate::diagnose::Cause>,
    ) {
        self.attempts += 1;
        self.successes += usize::from(success);
        let sources: Vec<(usize, usize)> = sources.into_iter().collect();
        for &(subtask, d) in &sources {
            if subtask >= self.per_subtask_source.len() {
                self.per_subtask_source.resize(subtask + 1, Vec::new());
            }
            if let Some(row) = self.per_subtask_source.get_mut(subtask) {
                if d >= row.len() {
                    row.resize(d.max(self.per_source_demo.len().saturating_sub(1)) + 1, DemoUse::default());
                }
                if let Some(cell) = row.get_mut(d) {
                    cell.attempts += 1;
                    cell.successes += usize::from(success);
                }
            }
        }
        let mut used: Vec<usize> = sources.iter().map(|&(_, d)| d).collect();
        used.sort_unstable();
        used.dedup();
        for d in used {
            if d >= self.per_source_demo.len() {
                self.per_source_demo.resize(d + 1, DemoUse::default());
            }
            if let Some(demo) = self.per_source_demo.get_mut(d) {
                demo.attempts += 1;
                demo.successes += usize::from(success);
            }
        }
        if let Some(failure) = failure {
            match self.failures.iter_mut().find(|f| f.subtask == failure.subtask && f.reason == failure.reason) {
                Some(f) => f.count += 1,
                None => {
                    self.failures.push(FailureCount { subtask: failure.subtask, reason: failure.reason.clone(), count: 1 });
                    self.failures.sort_by(|a, b| (a.subtask, &a.reason).cmp(&(b.subtask, &b.reason)));
                }
            }
            if let Some(class) = cause.map(crate::diagnose::Cause::class) {
                match self.causes.iter_mut().find(|c| c.subtask == failure.subtask && c.class == class) {
                    Some(c) => c.count += 1,
                    None => {
                        self.causes.push(CauseCount { subtask: failure.subtask, class: class.to_owned(), count: 1 });
                        self.causes.sort_by(|a, b| (a.subtask, &a.class).cmp(&(b.subtask, &b.class)));
                    }
                }
            }
        }
    }
}

/// One share of a run's attempt indices: those with `index % count == part`. Every attempt's
/// randomness depends only on the run seed and its index, so shards run anywhere make the
/// attempts a single run makes, and joined in index order they give its dataset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "ShardParts")]
pub struct Shard {
    /// Which share, `0..count`.
    pub part: usize,
    /// How many shares.
    pub count: usize,
}

impl Default for Shard {
    fn default() -> Self {
        Self::WHOLE
    }
}

impl Shard {
    /// Every index.
    pub const WHOLE: Self = Self { part: 0, count: 1 };

    /// Share `part` of `count`.
    ///
    /// # Errors
    /// A message when `count` is 0 or `part` is not below it.
    pub fn new(part: usize, count: usize) -> Result<Self, String> {
        if count == 0 || part >= count {
            return Err(format!("shard {part}/{count} does not exist: the shards of K are 0/K to {}/K", count.max(1) - 1));
        }
        Ok(Self { part, count })
    }

    /// Whether attempt `index` is in this share.
    #[must_use]
    pub fn contains(&self, index: usize) -> bool {
        index % self.count == self.part
    }

    /// The first index of this share at or after `start`.
    #[must_use]
    pub fn first_at_or_after(&self, start: usize) -> usize {
        start + (self.part + self.count - start % self.count) % self.count
    }
}

/// A shard as a file stores it, checked by [`Shard::new`] when read (a count of 0 would divide by 0).
#[derive(Deserialize)]
struct ShardParts {
    part: usize,
    count: usize,
}

impl TryFrom<ShardParts> for Shard {
    type Error = String;

    fn try_from(parts: ShardParts) -> Result<Self, String> {
        Self::new(parts.part, parts.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (part, count) = s.split_once('/').ok_or_else(|| format!("{s:?}: expected PART/COUNT, e.g. 0/4"))?;
        let number = |v: &str| v.trim().parse::<usize>().map_err(|e| format!("{s:?}: {v:?}: {e}"));
        Self::new(number(part)?, number(count)?)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.part, self.count)
    }
}

/// Where a run starts and what can stop it early, beyond the spec's own stopping rule.
#[derive(Debug, Default)]
pub struct RunControl<'a> {
    /// Index of the first attempt to run (a resumed run starts where the interrupted one stopped).
    pub start: usize,
    /// Statistics of the attempts before `start`.
    pub stats: Option<RunStats>,
    /// Set to stop after the attempts already handed back: every attempt before the stop has been
    /// passed to the callback, in order, none after it.
    pub cancel: Option<&'a AtomicBool>,
    /// Run only this share of the attempt indices. With `guarantee`, the share stops at its own
    /// `num_trials` successes: then it holds every one of its attempts up to the single run's
    /// last (that run reaches its successes no later than any share does).
    pub shard: Shard,
}

/// How many attempts per worker may be finished and waiting for an earlier one.
pub const REORDER_WINDOW_PER_WORKER: usize = 4;

/// The oldest attempt index not yet handed on, which workers wait on.
struct Frontier {
    oldest: Mutex<usize>,
    moved: Condvar,
}

impl Frontier {
    /// Blocks until `index` is less than `window` past the oldest attempt not handed on; false
    /// when the run stops meanwhile.
    fn wait_until_within(&self, index: usize, window: usize, stop: &AtomicBool) -> bool {
        // A poisoned lock means the receiving side panicked: stop.
        let Ok(mut oldest) = self.oldest.lock() else { return false };
        while index >= oldest.saturating_add(window) && !stop.load(Ordering::Relaxed) {
            oldest = match self.moved.wait(oldest) {
                Ok(guard) => guard,
                Err(_) => return false,
            };
        }
        !stop.load(Ordering::Relaxed)
    }

    /// Records that every attempt before `index` has been handed on, waking the workers.
    fn advance_to(&self, index: usize) {
        if let Ok(mut oldest) = self.oldest.lock() {
            *oldest = index;
        }
        self.moved.notify_all();
    }
}

/// Runs attempts on every environment in `envs` in parallel (one worker thread each) and passes
/// them to `on_attempt` in index order, until the spec's stopping rule is met or `on_attempt`
/// breaks. The attempts seen, and so the dataset, do not depend on `envs.len()`.
///
/// # Errors
/// The first fatal environment error, or the error `on_attempt` breaks with.
pub fn run<E, F>(generator: &Generator, envs: &mut [E], mut on_attempt: F) -> Result<RunStats, EngineError>
where
    E: Environment + Send,
    F: FnMut(Attempt, &RunStats) -> ControlFlow<Result<(), EngineError>>,
{
    run_with(generator, envs, RunControl::default(), |_, _| Ok(()), |attempt, (), stats| on_attempt(attempt, stats))
}

/// [`run`], resumable and cancellable, with a step `finish` that each worker applies to its own
/// attempts on its own environment before handing them back (computing observations, say), so
/// that work runs in parallel too. `on_attempt` gets each attempt with what `finish` made of it.
///
/// # Errors
/// The first fatal environment error, the first error of `finish`, or the error `on_attempt`
/// breaks with.
pub fn run_with<E, P, W, F>(
    generator: &Generator,
    envs: &mut [E],
    control: RunControl<'_>,
    finish: W,
    mut on_attempt: F,
) -> Result<RunStats, EngineError>
where
    E: Environment + Send,
    P: Send,
    W: Fn(&mut E, &Attempt) -> Result<P, EngineError> + Sync,
    F: FnMut(Attempt, P, &RunStats) -> ControlFlow<Result<(), EngineError>>,
{
    let settings = &generator.spec().generation;
    let cap = settings.attempt_cap();
    let mut stats = control.stats.unwrap_or_else(|| RunStats::new(generator.dataset().demos.len()));
    if envs.is_empty() {
        return Err(EngineError::Config {
            file: String::new(),
            field: "workers".to_owned(),
            reason: "at least one environment is needed".to_owned(),
        });
    }
    let cancelled = || control.cancel.is_some_and(|c| c.load(Ordering::Relaxed));
    let done = |stats: &RunStats| settings.guarantee && stats.successes >= settings.num_trials;
    if done(&stats) || control.shard.first_at_or_after(control.start) >= cap || cancelled() {
        return Ok(stats);
    }
    let shard = control.shard;
    let first = shard.first_at_or_after(control.start);
    // Workers take this share's indices in order: `first`, `first + count`, ...
    let next = AtomicUsize::new(first);
    let stop = AtomicBool::new(false);
    // Attempts are handed on in index order, so a finished attempt waits for those before it. A
    // worker starts no attempt more than `window` shares past the oldest one not yet handed on:
    // one slow attempt cannot pile up the others' results (each with its images) without bound.
    let window = REORDER_WINDOW_PER_WORKER * envs.len() * shard.count;
    let frontier = Frontier { oldest: Mutex::new(first), moved: Condvar::new() };
    type Outcome<P> = Result<(Attempt, P), EngineError>;
    let (sender, receiver) = mpsc::sync_channel::<(usize, Outcome<P>)>(envs.len() * 2);
    std::thread::scope(|scope| {
        for (worker, env) in envs.iter_mut().enumerate() {
            let sender = sender.clone();
            let (next, stop, finish, frontier) = (&next, &stop, &finish, &frontier);
            let spawned = std::thread::Builder::new().name(format!("mimicgen-worker-{worker}")).spawn_scoped(scope, move || {
                loop {
                    let index = next.fetch_add(shard.count, Ordering::Relaxed);
                    if index >= cap || !frontier.wait_until_within(index, window, stop) {
                        break;
                    }
                    let result = generator.attempt(env, index as u64).and_then(|a| finish(env, &a).map(|p| (a, p)));
                    if sender.send((index, result)).is_err() {
                        break;
                    }
                }
            });
            if let Err(e) = spawned {
                stop.store(true, Ordering::Relaxed);
                frontier.advance_to(usize::MAX);
                return Err(EngineError::Io { path: "worker thread".to_owned(), reason: e.to_string() });
            }
        }
        drop(sender);
        let mut pending: BTreeMap<usize, Outcome<P>> = BTreeMap::new();
        let mut expected = first;
        let outcome = 'receive: loop {
            if expected >= cap || done(&stats) || cancelled() {
                break Ok(());
            }
            let (index, result) = match receiver.recv_timeout(std::time::Duration::from_millis(50)) {
                Ok(message) => message,
                Err(mpsc::RecvTimeoutError::Timeout) => continue,
                Err(mpsc::RecvTimeoutError::Disconnected) => break Ok(()),
            };
            pending.insert(index, result);
            while let Some(result) = pending.remove(&expected) {
                expected += shard.count;
                let (attempt, payload) = match result {
                    Ok(a) => a,
                    Err(e) => break 'receive Err(e),
                };
                stats.record(&attempt);
                if let ControlFlow::Break(result) = on_attempt(attempt, payload, &stats) {
                    break 'receive result;
                }
                frontier.advance_to(expected);
                if done(&stats) || cancelled() {
                    break 'receive Ok(());
                }
            }
        };
        stop.store(true, Ordering::Relaxed);
        frontier.advance_to(usize::MAX);
        // Drain so blocked workers can see `stop` and exit.
        while receiver.recv().is_ok() {}
        outcome
    })?;
    Ok(stats)
}
