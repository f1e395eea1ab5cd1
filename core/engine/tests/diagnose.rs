//! Each cause class of a failed attempt, built from a real attempt of the kinematic environment
//! (a success) edited where the cause would show, and read back by `diagnose::cause`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, missing_docs)]

use mimicgen_engine::diagnose::{self, Cause};
use mimicgen_engine::generate::{Attempt, Failure, FailureReason};
use mimicgen_engine::pose::Vec3;
use mimicgen_engine::{Generator, kinematic};

/// The generator and its first successful attempt.
fn success() -> (Generator, Attempt) {
    let generator = Generator::new(kinematic::pick_place_spec(20, 7), kinematic::scripted_dataset(4, 1).unwrap()).unwrap();
    let mut env = kinematic::PickPlace::new(0.1);
    let attempt = (0..20).map(|i| generator.attempt(&mut env, i).unwrap()).find(|a| a.success).expect("a success in 20");
    assert_eq!(attempt.cause, None, "a success has no cause");
    (generator, attempt)
}

fn failed(mut attempt: Attempt, subtask: usize, reason: FailureReason) -> Attempt {
    attempt.success = false;
    attempt.failure = Some(Failure { subtask, reason });
    attempt
}

fn grasp_never_on(attempt: Attempt) -> Attempt {
    failed(attempt, 0, FailureReason::SignalNeverOn { signal: "grasp".to_owned() })
}

fn cause(generator: &Generator, attempt: &Attempt) -> Cause {
    diagnose::cause(generator.spec(), generator.dataset(), attempt).expect("a failure has a cause")
}

/// Steps of subtask `s`: `(first, end)`.
fn span(attempt: &Attempt, s: usize) -> (usize, usize) {
    (attempt.plans[s].first_step, attempt.plans.get(s + 1).map_or(attempt.trajectory.len(), |p| p.first_step))
}

/// The step the gripper first closes at in `from..to`.
fn close_step(attempt: &Attempt, from: usize, to: usize) -> usize {
    let closed = |t: usize| attempt.trajectory.gripper_actions.row(t)[0] > 0.0;
    (from..to).find(|&t| closed(t) && !closed(t - 1)).expect("the gripper closes")
}

#[test]
fn an_object_moved_before_the_grasp_where_the_source_s_stayed() {
    let (generator, mut attempt) = success();
    let (start, end) = span(&attempt, 0);
    let close = close_step(&attempt, start + 1, end);
    // The cube pushed 3 cm along x from a few steps before the close on.
    let from = close - 4;
    for pose in &mut attempt.trajectory.object_poses.get_mut("cubeA").unwrap()[from..] {
        pose.translation.vector += Vec3::new(0.03, 0.0, 0.0);
    }
    let attempt = grasp_never_on(attempt);
    match cause(&generator, &attempt) {
        Cause::ObjectMoved { object, step, moved_m, .. } => {
            assert_eq!((object.as_str(), step), ("cubeA", from));
            assert!((moved_m - 0.03).abs() < 0.005, "{moved_m}");
        }
        other => panic!("{other:?}"),
    }
}

/// Holds the hand 6 cm back from where the source's was for `steps` steps, from a few steps into
/// the subtask with the longest transformed segment: `(that subtask, the first step held back)`.
fn hold_back(generator: &Generator, attempt: &mut Attempt, steps: usize) -> (usize, usize) {
    let errors = |attempt: &Attempt, s| diagnose::tracking_errors(generator.dataset(), attempt, s);
    let s = (0..attempt.plans.len()).max_by_key(|&s| errors(attempt, s).len()).unwrap();
    let errors = errors(attempt, s);
    assert!(errors.len() > diagnose::LAG_STEPS + 5, "{} transformed steps", errors.len());
    assert!(errors.iter().all(|(_, e)| *e < 0.01), "the kinematic hand follows the source's: {errors:?}");
    // A step's error is the hand after it.
    let from = errors[2].0;
    for t in from + 1..=from + steps {
        attempt.trajectory.eef_poses[t].translation.vector += Vec3::new(0.0, 0.0, 0.06);
    }
    (s, from)
}

#[test]
fn an_arm_behind_the_source_s_hand_for_a_stretch_lagged() {
    let (generator, mut attempt) = success();
    let (s, from) = hold_back(&generator, &mut attempt, diagnose::LAG_STEPS + 1);
    let attempt = failed(attempt, s, FailureReason::SignalNeverOn { signal: "grasp".to_owned() });
    match cause(&generator, &attempt) {
        Cause::ArmLagged { step, error_m, joint } => {
            assert_eq!(joint, None, "diagnose::cause alone knows no joints");
            assert_eq!(step, from);
            assert!((error_m - 0.06).abs() < 0.01, "{error_m}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_stretch_behind_shorter_than_the_bound_is_no_lag() {
    let (generator, mut attempt) = success();
    let (s, _) = hold_back(&generator, &mut attempt, diagnose::LAG_STEPS - 1);
    let attempt = failed(attempt, s, FailureReason::TaskNotAchieved { unmet: None });
    assert!(!matches!(cause(&generator, &attempt), Cause::ArmLagged { .. }));
}

#[test]
fn a_gripper_that_closed_on_nothing_missed_the_grasp() {
    let (generator, mut attempt) = success();
    let (start, end) = span(&attempt, 0);
    let close = close_step(&attempt, start + 1, end);
    // The cube stays where it was at the close: the hand leaves without it.
    let cube = attempt.trajectory.object_poses.get_mut("cubeA").unwrap();
    let stay = cube[close];
    for pose in &mut cube[close..] {
        *pose = stay;
    }
    let attempt = grasp_never_on(attempt);
    match cause(&generator, &attempt) {
        Cause::GraspMissed { object, step, .. } => assert_eq!((object.as_str(), step), ("cubeA", close)),
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_object_left_behind_by_the_closed_hand_slipped() {
    let (generator, mut attempt) = success();
    let (start, end) = span(&attempt, 1);
    // Partway through the place, the cube stops following the hand though the gripper is closed.
    let closed = |t: usize| attempt.trajectory.gripper_actions.row(t)[0] > 0.0;
    let drop = (start + 5..end).find(|&t| closed(t)).unwrap();
    assert!((drop..drop + 15).all(closed), "the hand stays closed after {drop}");
    let cube = attempt.trajectory.object_poses.get_mut("cubeA").unwrap();
    let stay = cube[drop];
    for pose in &mut cube[drop..] {
        *pose = stay;
    }
    let attempt = failed(attempt, 1, FailureReason::TaskNotAchieved { unmet: None });
    match cause(&generator, &attempt) {
        Cause::GraspSlipped { object, held_from, lost_at } => {
            assert_eq!(object, "cubeA");
            assert!(held_from < drop && lost_at > drop && lost_at < end, "held {held_from}, lost {lost_at}, drop {drop}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn with_nothing_else_seen_the_segment_ran_out_or_the_check_failed() {
    let (generator, attempt) = success();
    let (start, end) = span(&attempt, 0);
    assert_eq!(cause(&generator, &grasp_never_on(attempt.clone())), Cause::RanOutOfSteps { steps: end - start });
    let unmet = Some("cubeA on cubeB".to_owned());
    let attempt = failed(attempt, 1, FailureReason::TaskNotAchieved { unmet: unmet.clone() });
    assert_eq!(cause(&generator, &attempt), Cause::SuccessUnmet { clause: unmet });
    let unstable = failed(attempt, 1, FailureReason::Unstable { reason: "nan".to_owned() });
    assert_eq!(cause(&generator, &unstable), Cause::Simulation);
}

#[test]
fn every_failed_attempt_of_a_run_has_a_cause_and_every_success_none() {
    let mut spec = kinematic::pick_place_spec(40, 3);
    // Noise large enough to miss some grasps.
    spec.subtasks[0].action_noise = 0.6;
    let generator = Generator::new(spec, kinematic::scripted_dataset(4, 1).unwrap()).unwrap();
    let mut env = kinematic::PickPlace::new(0.1);
    let attempts: Vec<Attempt> = (0..40).map(|i| generator.attempt(&mut env, i).unwrap()).collect();
    let failures = attempts.iter().filter(|a| !a.success).count();
    assert!(failures > 0, "noise fails some attempts");
    for a in &attempts {
        assert_eq!(a.cause.is_some(), !a.success, "attempt {}: {:?} {:?}", a.index, a.failure, a.cause);
    }
}
