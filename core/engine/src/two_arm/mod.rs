//! Two arms (DexMimicGen, Jiang et al. 2024): each arm has its own sequence of object-centric
//! subtasks, and a subtask may be tied to one of the other arm's:
//!
//! - **parallel** (no tie): each arm goes on with its own subtasks; an arm that has finished its
//!   last waits, holding its pose, for the other;
//! - **coordination**: two subtasks, one per arm, run together: they start on the same step and
//!   run in lockstep for the same number of steps (the arm that gets there first holds its pose
//!   until the other is ready);
//! - **sequential**: a subtask starts only after a subtask of the other arm has ended (receive
//!   only after the give).
//!
//! [`Schedule`] decides, step by step, which subtasks start and which end; it knows nothing of
//! poses, so the rules are tested on their own. [`TwoArmSpec`] is the task spec (`spec.rs`),
//! [`TwoArmGenerator`] runs attempts with both arms (`generate.rs`), [`TwoArmLiftScript`] records
//! scripted source demos (`demonstrator.rs`).

mod demonstrator;
mod generate;
mod spec;

pub use demonstrator::*;
pub use generate::*;
pub use spec::*;

use serde::{Deserialize, Serialize};

/// One arm's subtask: `(arm, subtask)`.
pub type ArmSubtask = (usize, usize);

/// A tie between two arms' subtasks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Constraint {
    /// The two run together: the same first step, the same number of steps.
    Coordination(ArmSubtask, ArmSubtask),
    /// `later` starts only after `first` has ended.
    Sequential {
        /// The subtask that must end first.
        first: ArmSubtask,
        /// The subtask that waits for it.
        later: ArmSubtask,
    },
}

/// Why a set of subtasks and constraints cannot be scheduled, in words naming the subtasks.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ScheduleError(pub String);

/// Where one arm is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ArmState {
    /// Holding its pose before `subtask` (which may not start yet).
    Waiting(usize),
    /// Running `subtask` with `remaining` steps to go.
    Running { subtask: usize, remaining: usize },
    /// Its last subtask has ended.
    Done,
}

/// What one arm does on a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmStep {
    /// Step `step` (from 0) of its `subtask`.
    Run {
        /// The subtask.
        subtask: usize,
        /// The step within the subtask.
        step: usize,
    },
    /// Holds its pose: waiting for the other arm, or done.
    Hold,
}

/// The state of both arms' subtasks as an attempt runs.
#[derive(Debug, Clone)]
pub struct Schedule {
    /// Subtasks per arm.
    counts: Vec<usize>,
    constraints: Vec<Constraint>,
    arms: Vec<ArmState>,
    /// Steps each running subtask was started with.
    lengths: Vec<usize>,
}

/// Where `arm` is once its subtask `k` has ended.
fn next_state(counts: &[usize], arm: usize, k: usize) -> ArmState {
    if k + 1 < counts.get(arm).copied().unwrap_or(0) { ArmState::Waiting(k + 1) } else { ArmState::Done }
}

pub(crate) fn name((arm, subtask): ArmSubtask) -> String {
    format!("arm {arm} subtask {subtask}")
}

impl Schedule {
    /// A schedule of `counts[a]` subtasks on arm `a` under `constraints`.
    ///
    /// # Errors
    /// A constraint naming a subtask that does not exist, tying an arm to itself, a subtask in two
    /// coordinations, or constraints that can never all be met (a cycle: each arm would wait for
    /// the other), naming the subtasks.
    pub fn new(counts: &[usize], constraints: &[Constraint]) -> Result<Self, ScheduleError> {
        let exists = |(a, k): ArmSubtask| counts.get(a).is_some_and(|&n| k < n);
        let mut coordinated: Vec<ArmSubtask> = Vec::new();
        for c in constraints {
            let (x, y) = match *c {
                Constraint::Coordination(x, y) => (x, y),
                Constraint::Sequential { first, later } => (first, later),
            };
            for s in [x, y] {
                if !exists(s) {
                    return Err(ScheduleError(format!("{c:?} names {}, which does not exist", name(s))));
                }
            }
            if x.0 == y.0 {
                return Err(ScheduleError(format!("{c:?} ties arm {} to itself; a tie is between the two arms", x.0)));
            }
            if let Constraint::Coordination(..) = c {
                for s in [x, y] {
                    if coordinated.contains(&s) {
                        return Err(ScheduleError(format!("{} is in two coordination subtasks", name(s))));
                    }
                    coordinated.push(s);
                }
            }
        }
        let schedule = Self {
            counts: counts.to_vec(),
            constraints: constraints.to_vec(),
            arms: counts.iter().map(|&n| if n == 0 { ArmState::Done } else { ArmState::Waiting(0) }).collect(),
            lengths: vec![0; counts.len()],
        };
        // Every subtask can be reached when every segment takes one step: otherwise some order of
        // lengths leaves both arms waiting for each other.
        let mut dry = schedule.clone();
        while !dry.is_done() {
            let groups = dry.ready();
            if groups.is_empty() {
                let waiting: Vec<String> = dry
                    .arms
                    .iter()
                    .enumerate()
                    .filter_map(|(a, s)| match *s {
                        ArmState::Waiting(k) => Some(name((a, k))),
                        _ => None,
                    })
                    .collect();
                return Err(ScheduleError(format!(
                    "the constraints can never all be met: {} would wait for each other for ever",
                    waiting.join(" and ")
                )));
            }
            for group in groups {
                dry.start(&group.iter().map(|&s| (s, 1)).collect::<Vec<_>>()).map_err(ScheduleError)?;
            }
            dry.advance();
        }
        Ok(schedule)
    }

    /// Subtasks per arm.
    #[must_use]
    pub fn counts(&self) -> &[usize] {
        &self.counts
    }

    /// Whether `s` has ended.
    #[must_use]
    pub fn ended(&self, (arm, subtask): ArmSubtask) -> bool {
        match self.arms.get(arm) {
            Some(ArmState::Done) => true,
            Some(ArmState::Waiting(k)) => subtask < *k,
            Some(ArmState::Running { subtask: k, .. }) => subtask < *k,
            None => false,
        }
    }

    /// The other subtask coordinated with `s`, if any.
    #[must_use]
    pub fn partner(&self, s: ArmSubtask) -> Option<ArmSubtask> {
        self.constraints.iter().find_map(|c| match *c {
            Constraint::Coordination(x, y) if x == s => Some(y),
            Constraint::Coordination(x, y) if y == s => Some(x),
            _ => None,
        })
    }

    /// Whether waiting subtask `s` has every subtask it waits for ended.
    fn free(&self, s: ArmSubtask) -> bool {
        self.constraints.iter().all(|c| match *c {
            Constraint::Sequential { first, later } if later == s => self.ended(first),
            _ => true,
        })
    }

    /// The subtasks that may start now, grouped: one alone, or a coordination pair (both arms
    /// waiting before it, both free). Empty when none may.
    #[must_use]
    pub fn ready(&self) -> Vec<Vec<ArmSubtask>> {
        let mut groups: Vec<Vec<ArmSubtask>> = Vec::new();
        for (arm, state) in self.arms.iter().enumerate() {
            let ArmState::Waiting(k) = *state else { continue };
            let s = (arm, k);
            if !self.free(s) || groups.iter().any(|g| g.contains(&s)) {
                continue;
            }
            match self.partner(s) {
                None => groups.push(vec![s]),
                Some(p) if self.arms.get(p.0) == Some(&ArmState::Waiting(p.1)) && self.free(p) => groups.push(vec![s, p]),
                Some(_) => {}
            }
        }
        groups
    }

    /// Starts a group [`Schedule::ready`] gave, each subtask with its number of steps. A subtask of
    /// no steps ends at once.
    ///
    /// # Errors
    /// A subtask that is not waiting to start, a coordination pair started apart or with
    /// different lengths, in words.
    pub fn start(&mut self, group: &[(ArmSubtask, usize)]) -> Result<(), String> {
        for &((arm, k), _) in group {
            if self.arms.get(arm) != Some(&ArmState::Waiting(k)) {
                return Err(format!("{} is not waiting to start", name((arm, k))));
            }
            if !self.free((arm, k)) {
                return Err(format!("{} started before the subtask it waits for ended", name((arm, k))));
            }
            if let Some(p) = self.partner((arm, k)) {
                match group.iter().find(|(s, _)| *s == p) {
                    None => return Err(format!("{} started without {}, its coordination partner", name((arm, k)), name(p))),
                    Some(&(_, n)) if group.iter().any(|&(s, m)| s == (arm, k) && m != n) => {
                        return Err(format!("{} and {} are coordinated but have different lengths", name((arm, k)), name(p)));
                    }
                    Some(_) => {}
                }
            }
        }
        for &((arm, k), steps) in group {
            let state = if steps == 0 { self.after(arm, k) } else { ArmState::Running { subtask: k, remaining: steps } };
            if let (Some(s), Some(len)) = (self.arms.get_mut(arm), self.lengths.get_mut(arm)) {
                (*s, *len) = (state, steps);
            }
        }
        Ok(())
    }

    fn after(&self, arm: usize, k: usize) -> ArmState {
        next_state(&self.counts, arm, k)
    }

    /// What each arm does on this step.
    #[must_use]
    pub fn steps(&self) -> Vec<ArmStep> {
        self.arms
            .iter()
            .zip(&self.lengths)
            .map(|(s, &len)| match *s {
                ArmState::Running { subtask, remaining } => ArmStep::Run { subtask, step: len - remaining },
                _ => ArmStep::Hold,
            })
            .collect()
    }

    /// Counts one control step; returns the subtasks that ended with it.
    pub fn advance(&mut self) -> Vec<ArmSubtask> {
        let mut ended = Vec::new();
        let counts = self.counts.clone();
        for (arm, state) in self.arms.iter_mut().enumerate() {
            if let ArmState::Running { subtask, remaining } = *state {
                *state = if remaining <= 1 {
                    ended.push((arm, subtask));
                    next_state(&counts, arm, subtask)
                } else {
                    ArmState::Running { subtask, remaining: remaining - 1 }
                };
            }
        }
        ended
    }

    /// Whether every arm has ended its last subtask.
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.arms.iter().all(|s| *s == ArmState::Done)
    }
}
