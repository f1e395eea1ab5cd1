//! Proposing subtask ends from what any recorded demo has, without the simulator's privileged
//! signals: the gripper command, the finger opening, and where the gripper is.
//!
//! A subtask that starts with the gripper open ends in a grasp: after the next close command the
//! fingers travel until the object blocks them, and the subtask ends on the step they stop (where
//! robosuite's grasp check turns on). A subtask that starts holding ends in a release: after the
//! next open command the fingers part, and it ends once they are clear of the object (10 mm wider
//! than they held it). Without finger openings the Panda's closing and opening times stand in
//! (8 and 7 control steps at 20 Hz), with a lower confidence.

use crate::EngineError;
use crate::demo::SourceDemo;
use crate::spec::TaskSpec;

/// Finger opening change per step under which the fingers count as stopped (m).
const STOPPED_M: f64 = 0.0015;
/// Narrowest opening that counts as blocked by an object rather than closed on nothing (m).
const MIN_GRASP_WIDTH_M: f64 = 0.005;
/// How much wider than they held the object the fingers must be to have let go (m).
const CLEAR_M: f64 = 0.010;
/// Control steps the Panda gripper takes to close on, or open off, a cube at 20 Hz.
const CLOSE_STEPS: usize = 8;
const OPEN_STEPS: usize = 7;
/// Gripper-to-object-frame distance within which a grasp is on the subtask's object (m); a
/// handle can be several cm from its object's frame (robosuite's square nut: 5.5 cm).
const NEAR_M: f64 = 0.08;

/// A proposed end of one subtask.
#[derive(Debug, Clone, PartialEq)]
pub struct Proposal {
    /// The subtask it ends.
    pub subtask: usize,
    /// The end (exclusive): the subtask's last step is `end - 1`, as segmentation reads it.
    pub end: usize,
    /// 0 to 1: how much the cues agree.
    pub confidence: f64,
    /// Why, in words a user can check against the plots.
    pub reason: String,
}

/// Whether a gripper command closes the gripper (robosuite's: positive closes).
pub(crate) fn closed(command: f64) -> bool {
    command > 0.0
}

/// Proposes the end of every subtask but the last of `demo` (which runs to the demo's end).
/// `finger_width_m` is the distance between the fingers at every step, when known.
///
/// # Errors
/// [`EngineError::Segmentation`] naming the demo and subtask when the gripper commands do not
/// show the close or open a subtask needs, or the demo has no gripper actions.
#[allow(
    clippy::indexing_slicing,
    reason = "`command` and `w` have n entries (checked at the top); every step indexed is below n: the searches run \
              below n, `still` to n - 2, and `start` is 0 or an earlier proposal's end, at most n - 1"
)]
pub fn propose_subtask_ends(demo: &SourceDemo, spec: &TaskSpec, finger_width_m: Option<&[f64]>) -> Result<Vec<Proposal>, EngineError> {
    let n = demo.len();
    let fail = |subtask: usize, reason: String| EngineError::Segmentation { demo: demo.name.clone(), subtask, reason };
    if demo.gripper_actions.width() == 0 || demo.gripper_actions.len() != n {
        return Err(fail(0, "has no gripper actions to read open and close commands from".to_owned()));
    }
    let command: Vec<f64> = demo.gripper_actions.iter().filter_map(|row| row.first().copied()).collect();
    let width = finger_width_m.filter(|w| w.len() == n);
    let mut proposals = Vec::new();
    let mut start = 0usize;
    for (i, subtask) in spec.subtasks.iter().enumerate().take(spec.subtasks.len().saturating_sub(1)) {
        let holding = closed(command[start]);
        let Some(switch) = (start.max(1)..n).find(|&t| closed(command[t]) != holding && closed(command[t - 1]) == holding) else {
            return Err(fail(i, format!("no {} command after step {start}", if holding { "open" } else { "close" })));
        };
        let proposal = match (holding, width) {
            (false, Some(w)) => {
                // The fingers start closing a step or two after the command; look for the stop once
                // they have moved.
                let moving = (switch..n).find(|&t| w[t] < w[switch] - 2.0 * STOPPED_M).unwrap_or(n);
                // Stopped for two steps: a finger that pauses for one while sliding along the object
                // has not closed on it yet.
                let still = |t: usize| (w[t + 1] - w[t]).abs() < STOPPED_M;
                let stop = (moving..n.saturating_sub(2)).find(|&t| still(t) && still(t + 1) && w[t] > MIN_GRASP_WIDTH_M);
                match stop {
                    Some(t) => {
                        let near =
                            subtask.object_ref.as_ref().and_then(|name| demo.object_poses.get(name)).and_then(|poses| {
                                Some((demo.eef_poses.get(t)?.translation.vector - poses.get(t)?.translation.vector).norm())
                            });
                        let (confidence, where_) = match near {
                            Some(d) if d < NEAR_M => {
                                (0.9, format!(", {:.0} mm from {}", d * 1e3, subtask.object_ref.as_deref().unwrap_or("")))
                            }
                            Some(d) => (0.5, format!(", but {:.0} mm from {}", d * 1e3, subtask.object_ref.as_deref().unwrap_or(""))),
                            None => (0.7, String::new()),
                        };
                        Proposal {
                            subtask: i,
                            end: t + 1,
                            confidence,
                            reason: format!(
                                "gripper closed at step {switch}; the fingers stopped at step {t}, {:.0} mm apart{where_}",
                                w[t] * 1e3
                            ),
                        }
                    }
                    None => Proposal {
                        subtask: i,
                        end: (switch + CLOSE_STEPS).min(n - 1),
                        confidence: 0.3,
                        reason: format!(
                            "gripper closed at step {switch} but the fingers never stopped on an object; assumed {CLOSE_STEPS} steps to close"
                        ),
                    },
                }
            }
            (true, Some(w)) => {
                let held = w[switch];
                match (switch..n).find(|&t| w[t] > held + CLEAR_M) {
                    Some(t) => Proposal {
                        subtask: i,
                        end: t + 1,
                        confidence: 0.9,
                        reason: format!(
                            "gripper opened at step {switch}; by step {t} the fingers were {:.0} mm apart, clear of the {:.0} mm they held",
                            w[t] * 1e3,
                            held * 1e3
                        ),
                    },
                    None => Proposal {
                        subtask: i,
                        end: (switch + OPEN_STEPS).min(n - 1),
                        confidence: 0.3,
                        reason: format!("gripper opened at step {switch} but the fingers did not part; assumed {OPEN_STEPS} steps to open"),
                    },
                }
            }
            (false, None) => Proposal {
                subtask: i,
                end: (switch + CLOSE_STEPS).min(n - 1),
                confidence: 0.5,
                reason: format!("gripper closed at step {switch}; no finger openings recorded, assumed {CLOSE_STEPS} steps to close"),
            },
            (true, None) => Proposal {
                subtask: i,
                end: (switch + OPEN_STEPS).min(n - 1),
                confidence: 0.5,
                reason: format!("gripper opened at step {switch}; no finger openings recorded, assumed {OPEN_STEPS} steps to open"),
            },
        };
        start = proposal.end;
        proposals.push(proposal);
    }
    Ok(proposals)
}

/// A subtask-end signal as MimicGen's annotation script writes it: 0 before the annotated step,
/// 1 from it on. For a subtask that ends at `end` (exclusive), that step is `end - 1`, so MimicGen
/// and our segmentation both read the segment as `[start, end)`.
#[must_use]
pub fn signal_for_end(end: usize, len: usize) -> Vec<i64> {
    (0..len).map(|t| i64::from(t + 1 >= end)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segment::subtask_end_from_signal;
    use crate::testing::demo_with_object_at;

    fn spec() -> TaskSpec {
        crate::kinematic::pick_place_spec(1, 1)
    }

    #[test]
    fn written_signals_read_back_as_the_same_end() {
        for end in 1..10 {
            let signal = signal_for_end(end, 10);
            assert_eq!(subtask_end_from_signal(&signal, 0), if end == 1 { None } else { Some(end) }, "{signal:?}");
        }
    }

    #[test]
    fn a_grasp_ends_where_the_fingers_stop_and_a_release_where_they_clear() {
        let mut demo = demo_with_object_at("cubeA", 0.0);
        let n = demo.len();
        let closes_at = 3;
        let rows: Vec<f64> = (0..n).map(|t| if t >= closes_at { 1.0 } else { -1.0 }).collect();
        demo.gripper_actions = crate::Rows::from_vec(1, rows, "gripper").unwrap();
        // Open 80 mm, closing 13 mm a step from step 4, blocked by a 41 mm object from step 6.
        let width: Vec<f64> = (0..n).map(|t| if t < 3 { 0.080 } else { (0.080 - 0.013 * (t - 3) as f64).max(0.041) }).collect();
        let p = propose_subtask_ends(&demo, &spec(), Some(&width)).unwrap();
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].end, 7, "{p:?}");
        assert!(p[0].confidence > 0.8 && p[0].reason.contains("stopped at step 6"), "{p:?}");
        let fallback = propose_subtask_ends(&demo, &spec(), None).unwrap();
        assert_eq!(fallback[0].end, (closes_at + CLOSE_STEPS).min(n - 1));
        assert!(fallback[0].confidence < p[0].confidence);
    }

    #[test]
    fn a_demo_that_never_closes_is_an_error_naming_it() {
        let demo = demo_with_object_at("cubeA", 0.0);
        let mut open = demo.clone();
        open.gripper_actions = crate::Rows::from_vec(1, vec![-1.0; demo.len()], "gripper").unwrap();
        let err = propose_subtask_ends(&open, &spec(), None).unwrap_err().to_string();
        assert!(err.contains(&demo.name) && err.contains("close"), "{err}");
    }
}
