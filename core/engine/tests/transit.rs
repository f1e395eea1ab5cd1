//! Planned transit (SkillGen) end to end on the kinematic pick-and-place environment, with and
//! without a post standing between the cubes.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;

use mimicgen_engine::generate::FailureReason;
use mimicgen_engine::kinematic::{self, PickPlace};
use mimicgen_engine::spec::Transit;
use mimicgen_engine::transform::WaypointKind;
use mimicgen_engine::{Attempt, Generator, RunStats, TaskSpec, run};

fn spec(transit: Transit, trials: usize) -> TaskSpec {
    let mut spec = kinematic::pick_place_spec(trials, 5);
    for subtask in &mut spec.subtasks {
        subtask.transit = transit;
        subtask.approach_m = 0.06;
    }
    // Segments end soon after the grasp (SkillGen's skills end with the contact), so that the
    // way from the grasp to the place is planned, not replayed.
    spec.subtasks[0].term_offset_range = Some((0, 2));
    // The kinematic space's joints are metres: check every 5 mm.
    spec.generation.planner.check_rad = 0.005;
    spec
}

fn collect(spec: TaskSpec, workers: usize, env: &PickPlace) -> (Vec<Attempt>, RunStats) {
    let generator = Generator::new(spec, kinematic::scripted_dataset(6, 11).unwrap()).unwrap();
    let mut envs: Vec<PickPlace> = (0..workers).map(|_| env.clone()).collect();
    let mut attempts = Vec::new();
    let stats = run(&generator, &mut envs, |a, _| {
        attempts.push(a);
        ControlFlow::Continue(())
    })
    .unwrap();
    attempts.sort_by_key(|a| a.index);
    (attempts, stats)
}

fn cluttered() -> PickPlace {
    PickPlace::new(0.15).with_post(0.015, 0.3)
}

#[test]
fn planned_transit_goes_round_a_post_that_interpolation_hits() {
    let (interpolated, interp_stats) = collect(spec(Transit::Interpolate, 40), 1, &cluttered());
    let (planned, plan_stats) = collect(spec(Transit::Plan, 40), 1, &cluttered());
    let touched = |attempts: &[Attempt]| attempts.iter().filter(|a| a.obstacle_contact_steps > 0).count();
    assert!(touched(&interpolated) > 20, "interpolation touched the post in only {} of 40", touched(&interpolated));
    assert!(touched(&planned) <= 2, "planned transit touched the post in {} of 40", touched(&planned));
    assert!(
        plan_stats.rate() > interp_stats.rate() + 0.4,
        "planned {} against interpolated {} ({:?})",
        plan_stats.rate(),
        interp_stats.rate(),
        plan_stats.failures
    );
    for attempt in &planned {
        for plan in &attempt.plans {
            assert!(plan.transit.is_some(), "a planned subtask without planner statistics");
            // The segment starts at the approach: what comes before it is planned transit.
            let t = &attempt.trajectory;
            let end = (plan.first_step..t.len()).find(|&k| t.subtask_labels[k] != t.subtask_labels[plan.first_step]).unwrap_or(t.len());
            let kinds = &t.kinds[plan.first_step..end];
            let transit = kinds.iter().take_while(|k| **k == WaypointKind::Transit).count();
            assert!(kinds[transit..].iter().all(|k| *k != WaypointKind::Transit));
        }
        assert!(!attempt.trajectory.kinds.contains(&WaypointKind::Interpolation));
        assert!(attempt.trajectory.kinds.contains(&WaypointKind::Transit));
    }
}

#[test]
fn without_obstacles_planned_transit_keeps_the_rate() {
    let (_, interp) = collect(spec(Transit::Interpolate, 30), 1, &PickPlace::new(0.1));
    let (_, planned) = collect(spec(Transit::Plan, 30), 1, &PickPlace::new(0.1));
    assert!(planned.rate() >= interp.rate() - 0.05, "planned {} against interpolated {}", planned.rate(), interp.rate());
}

#[test]
fn the_same_seed_gives_the_same_plans_with_any_number_of_workers() {
    let (one, _) = collect(spec(Transit::Plan, 12), 1, &cluttered());
    let (two, _) = collect(spec(Transit::Plan, 12), 2, &cluttered());
    assert_eq!(one.len(), two.len());
    for (a, b) in one.iter().zip(&two) {
        assert_eq!(a.trajectory.actions, b.trajectory.actions, "attempt {}", a.index);
        assert_eq!(a.trajectory.kinds, b.trajectory.kinds);
        assert_eq!(
            a.plans.iter().map(|p| p.transit.map(|t| t.samples)).collect::<Vec<_>>(),
            b.plans.iter().map(|p| p.transit.map(|t| t.samples)).collect::<Vec<_>>()
        );
    }
    let mut other = spec(Transit::Plan, 12);
    other.generation.seed = 6;
    let (three, _) = collect(other, 1, &cluttered());
    assert_ne!(one[0].trajectory.actions, three[0].trajectory.actions);
}

#[test]
fn a_goal_inside_an_obstacle_fails_the_attempt_with_a_reason_of_its_own() {
    // A post wide enough to cover the whole table: no configuration at a segment start is free.
    let (attempts, stats) = collect(spec(Transit::Plan, 4), 1, &PickPlace::new(0.15).with_post(1.0, 0.3));
    assert_eq!(stats.successes, 0);
    for attempt in &attempts {
        let failure = attempt.failure.as_ref().unwrap();
        assert_eq!(failure.subtask, 0);
        assert!(
            matches!(&failure.reason, FailureReason::NoTransitPath { detail, .. } if detail.contains("inverse-kinematics")),
            "{failure:?}"
        );
        assert!(failure.reason.to_string().starts_with("no collision-free path found in"), "{}", failure.reason);
        assert!(attempt.trajectory.is_empty(), "an attempt without a path executed {} steps", attempt.trajectory.len());
    }
}
