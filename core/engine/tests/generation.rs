//! The generation loop end to end on the kinematic pick-and-place environment.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::ops::ControlFlow;

use mimicgen_engine::demonstrator::{PickPlaceScript, Style};
use mimicgen_engine::generate::FailureReason;
use mimicgen_engine::kinematic::{self, PickPlace};
use mimicgen_engine::transform::WaypointKind;
use mimicgen_engine::{Attempt, Environment, Generator, Overrides, SelectionStrategy, TaskSpec, run};
use rand::SeedableRng as _;
use rand_chacha::ChaCha8Rng;

fn collect(generator: &Generator, workers: usize, half_range_m: f64) -> (Vec<Attempt>, mimicgen_engine::RunStats) {
    let mut envs: Vec<PickPlace> = (0..workers).map(|_| PickPlace::new(half_range_m)).collect();
    let mut attempts = Vec::new();
    let stats = run(generator, &mut envs, |a, _| {
        attempts.push(a);
        ControlFlow::Continue(())
    })
    .unwrap();
    (attempts, stats)
}

fn generator(spec: TaskSpec) -> Generator {
    Generator::new(spec, kinematic::scripted_dataset(6, 11).unwrap()).unwrap()
}

#[test]
fn generates_successful_demos_in_new_scenes() {
    let (attempts, stats) = collect(&generator(kinematic::pick_place_spec(40, 3)), 1, 0.1);
    assert_eq!(stats.attempts, 40);
    assert_eq!(attempts.len(), 40);
    assert!(stats.rate() > 0.9, "rate {} {:?}", stats.rate(), stats.failures);
    for a in attempts.iter().filter(|a| a.success) {
        assert!(a.failure.is_none());
        let t = &a.trajectory;
        assert_eq!(t.actions.len(), t.len());
        assert_eq!(t.states.len(), t.len());
        assert_eq!(t.src_demo_labels.len(), t.len());
        // Each step's source label is the demo chosen for that step's subtask.
        for (label, subtask) in t.src_demo_labels.iter().zip(&t.subtask_labels) {
            assert_eq!(*label, a.src_demo_per_subtask[*subtask]);
        }
        // Actions stay in [-1, 1] even with noise.
        assert!(t.actions.as_slice().iter().all(|v| (-1.0..=1.0).contains(v)));
        // Each subtask begins with 5 interpolation steps plus the segment's first pose.
        for plan in &a.plans {
            assert_eq!(t.kinds[plan.first_step..plan.first_step + 6], [WaypointKind::Interpolation; 6]);
        }
    }
    // The new scenes differ from every source scene: generation is not replay.
    let first_scene = &attempts[0].initial_object_poses["cubeA"];
    assert!(
        attempts
            .iter()
            .skip(1)
            .all(|a| (a.initial_object_poses["cubeA"].translation.vector - first_scene.translation.vector).norm() > 1e-9)
    );
    let used: usize = stats.per_source_demo.iter().map(|d| d.attempts).sum();
    assert!(used >= 40 && stats.per_source_demo.iter().filter(|d| d.attempts > 0).count() > 1);
}

/// The success matrix counts, per subtask and source demo, the attempts whose segment for that
/// subtask came from that demo and their successes: what the attempts themselves say.
#[test]
fn the_success_matrix_counts_each_subtask_s_source() {
    let mut spec = kinematic::pick_place_spec(60, 5);
    spec.subtasks[0].action_noise = 0.6;
    let (attempts, stats) = collect(&generator(spec), 2, 0.1);
    assert!(stats.successes > 0 && stats.successes < stats.attempts, "{} of {}", stats.successes, stats.attempts);
    assert_eq!(stats.per_subtask_source.len(), 2);
    for (subtask, row) in stats.per_subtask_source.iter().enumerate() {
        assert_eq!(row.len(), 6, "a column per source demo");
        for (demo, cell) in row.iter().enumerate() {
            let used: Vec<&Attempt> = attempts.iter().filter(|a| a.src_demo_per_subtask.get(subtask) == Some(&demo)).collect();
            assert_eq!(cell.attempts, used.len(), "subtask {subtask} demo {demo}");
            assert_eq!(cell.successes, used.iter().filter(|a| a.success).count(), "subtask {subtask} demo {demo}");
        }
    }
    assert_eq!(stats.per_subtask_source[1].iter().map(|c| c.successes).sum::<usize>(), stats.successes);
}

#[test]
fn transformed_segments_follow_the_new_object() {
    let (attempts, _) = collect(&generator(kinematic::pick_place_spec(5, 9)), 1, 0.2);
    for a in &attempts {
        for plan in &a.plans {
            let (new, src) = (plan.world_from_obj_new.unwrap(), plan.world_from_obj_src.unwrap());
            for (s, t) in plan.source_poses.iter().zip(&plan.transformed_poses) {
                let before = src.inverse() * s;
                let after = new.inverse() * t;
                assert!((before.translation.vector - after.translation.vector).norm() < 1e-9);
            }
        }
    }
}

#[test]
fn same_seed_same_attempts_for_any_worker_count() {
    let g = generator(kinematic::pick_place_spec(24, 5));
    let (one, s1) = collect(&g, 1, 0.15);
    let (two, s2) = collect(&g, 2, 0.15);
    let (three, s3) = collect(&g, 3, 0.15);
    assert_eq!(one, two);
    assert_eq!(one, three);
    assert_eq!(s1, s2);
    assert_eq!(s1, s3);
    // A different seed gives different scenes.
    let other = generator(kinematic::pick_place_spec(24, 6));
    let (four, _) = collect(&other, 2, 0.15);
    assert_ne!(one[0].initial_object_poses, four[0].initial_object_poses);
    // An attempt re-run alone is bit-identical to the one inside the run.
    let mut env = PickPlace::new(0.15);
    assert_eq!(g.attempt(&mut env, 17).unwrap(), one[17]);
}

#[test]
fn guarantee_stops_at_the_same_success_whatever_the_workers() {
    let mut spec = kinematic::pick_place_spec(10, 2);
    spec.generation.guarantee = true;
    spec.subtasks[0].action_noise = 0.4; // make failures common
    let g = generator(spec);
    let (one, s1) = collect(&g, 1, 0.15);
    let (two, s2) = collect(&g, 2, 0.15);
    assert_eq!(s1.successes, 10);
    assert!(one.last().unwrap().success);
    assert_eq!(one.len(), two.len());
    assert_eq!(s1, s2);
    assert!(s1.attempts > 10, "noise this high should cause failures");
}

#[test]
fn failed_grasps_are_attributed_to_the_grasp_subtask() {
    let mut spec = kinematic::pick_place_spec(30, 4);
    spec.subtasks[0].action_noise = 0.6;
    let (attempts, stats) = collect(&generator(spec), 2, 0.15);
    let missed: Vec<&Attempt> = attempts.iter().filter(|a| !a.success).collect();
    assert!(!missed.is_empty());
    for a in &missed {
        let failure = a.failure.as_ref().unwrap();
        // A grasp that never closed on the cube fails subtask 0; a grasp that held but a place that
        // missed fails subtask 1.
        let grasped = a.trajectory.subtask_term_signals["grasp"].iter().any(|&v| v != 0);
        if grasped {
            assert_eq!(failure.subtask, 1, "{failure:?}");
        } else {
            assert_eq!(failure.subtask, 0);
            assert_eq!(failure.reason, FailureReason::SignalNeverOn { signal: "grasp".into() });
        }
    }
    let counted: usize = stats.failures.iter().map(|f| f.count).sum();
    assert_eq!(counted, missed.len());
    assert_eq!(stats.successes + counted, stats.attempts);
}

#[test]
fn per_episode_selection_uses_one_demo() {
    let mut spec = kinematic::pick_place_spec(20, 8);
    spec.generation.select_src_per_subtask = false;
    let (attempts, _) = collect(&generator(spec), 1, 0.15);
    assert!(attempts.iter().all(|a| a.src_demo_per_subtask[0] == a.src_demo_per_subtask[1]));
    let mut spec = kinematic::pick_place_spec(40, 8);
    for s in &mut spec.subtasks {
        s.selection = SelectionStrategy::Random;
    }
    let (attempts, _) = collect(&generator(spec), 1, 0.15);
    assert!(attempts.iter().any(|a| a.src_demo_per_subtask[0] != a.src_demo_per_subtask[1]));
}

#[test]
fn unstable_physics_fails_the_attempt_and_the_run_goes_on() {
    /// Wraps the kinematic environment and blows up on every third attempt's 10th step.
    struct Flaky {
        inner: PickPlace,
        resets: usize,
        steps: usize,
    }
    impl Environment for Flaky {
        fn reset(&mut self, rng: &mut dyn rand::RngCore) -> Result<(), mimicgen_engine::EnvError> {
            self.resets += 1;
            self.steps = 0;
            self.inner.reset(rng)
        }
        fn eef_pose(&self) -> mimicgen_engine::Pose {
            self.inner.eef_pose()
        }
        fn object_poses(&self) -> std::collections::BTreeMap<String, mimicgen_engine::Pose> {
            self.inner.object_poses()
        }
        fn subtask_term_signals(&self) -> std::collections::BTreeMap<String, i64> {
            self.inner.subtask_term_signals()
        }
        fn is_success(&self) -> bool {
            self.inner.is_success()
        }
        fn target_pose_to_action(&self, t: &mimicgen_engine::Pose) -> [f64; 6] {
            self.inner.target_pose_to_action(t)
        }
        fn action_to_target_pose(&self, a: &[f64]) -> mimicgen_engine::Pose {
            self.inner.action_to_target_pose(a)
        }
        fn action_dim(&self) -> usize {
            7
        }
        fn step(&mut self, a: &[f64]) -> Result<(), mimicgen_engine::EnvError> {
            self.steps += 1;
            if self.resets.is_multiple_of(3) && self.steps == 10 {
                return Err(mimicgen_engine::EnvError::Unstable { reason: "qacc is NaN".into() });
            }
            self.inner.step(a)
        }
        fn state(&self) -> Vec<f64> {
            self.inner.state()
        }
        fn set_state(&mut self, s: &[f64]) -> Result<(), mimicgen_engine::EnvError> {
            self.inner.set_state(s)
        }
    }
    let g = generator(kinematic::pick_place_spec(9, 1));
    let mut envs = vec![Flaky { inner: PickPlace::new(0.1), resets: 0, steps: 0 }];
    let mut failures = Vec::new();
    let stats = run(&g, &mut envs, |a, _| {
        failures.extend(a.failure);
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(stats.attempts, 9);
    let unstable = failures.iter().filter(|f| matches!(&f.reason, FailureReason::Unstable { reason } if reason.contains("NaN"))).count();
    assert_eq!(unstable, 3);
}

#[test]
fn the_caller_can_stop_a_run_early() {
    let g = generator(kinematic::pick_place_spec(50, 1));
    let mut envs = vec![PickPlace::new(0.1), PickPlace::new(0.1)];
    let mut seen = 0;
    let stats = run(&g, &mut envs, |_, stats| {
        seen += 1;
        if stats.attempts == 7 { ControlFlow::Break(Ok(())) } else { ControlFlow::Continue(()) }
    })
    .unwrap();
    assert_eq!((seen, stats.attempts), (7, 7));
}

#[test]
fn a_spec_naming_a_missing_object_is_rejected_up_front() {
    let mut spec = kinematic::pick_place_spec(5, 1);
    spec.subtasks[1].object_ref = Some("cubeZ".into());
    let err = Generator::new(spec, kinematic::scripted_dataset(2, 1).unwrap()).unwrap_err().to_string();
    assert!(err.contains("subtask[1].object_ref") && err.contains("cubeZ"), "{err}");
}

/// Where we differ from the reference on purpose: MimicGen prepends the segment's first gripper
/// action for every subtask but the first robot pose only for the first, so from the second
/// subtask on its gripper commands run one step behind the poses they came with (and the last one
/// is dropped). We keep every transformed pose with the gripper action recorded beside it in the
/// source demo, as Isaac Lab Mimic does.
#[test]
fn later_subtasks_keep_each_pose_with_its_own_gripper_action() {
    let mut spec = kinematic::pick_place_spec(4, 3);
    for subtask in &mut spec.subtasks {
        subtask.action_noise = 0.0;
    }
    let generator = generator(spec);
    let (attempts, _) = collect(&generator, 1, 0.1);
    for attempt in &attempts {
        for (subtask, plan) in attempt.plans.iter().enumerate().skip(1) {
            let demo = &generator.dataset().demos[plan.src_demo];
            let executed: Vec<&[f64]> = (0..attempt.trajectory.len())
                .filter(|&t| attempt.trajectory.subtask_labels[t] == subtask && attempt.trajectory.kinds[t] == WaypointKind::Transformed)
                .map(|t| attempt.trajectory.gripper_actions.row(t))
                .collect();
            let source: Vec<&[f64]> = (plan.src_span.0..plan.src_span.1).map(|t| demo.gripper_actions.row(t)).collect();
            // The first transformed pose is reached by the interpolation; the rest execute with the
            // gripper actions of their own source steps, up to the segment's last (the reference
            // would give the action one step earlier, and drop the last).
            assert!(!executed.is_empty() && executed.len() < source.len());
            assert_eq!(executed, source[source.len() - executed.len()..], "attempt {} subtask {subtask}", attempt.index);
            assert_eq!(executed.last(), source.last());
        }
    }
}

#[test]
fn a_plan_is_the_attempt_before_execution_and_forced_sources_keep_the_scene() {
    let g = generator(kinematic::pick_place_spec(10, 4));
    let mut env = PickPlace::new(0.15);
    for index in 0..6 {
        let attempt = g.attempt(&mut env, index).unwrap();
        let plan = g.plan(&mut env, index, &Overrides::default()).unwrap();
        // Same scene, same source, same first subtask (nothing has executed before it).
        assert_eq!(plan.initial_object_poses, attempt.initial_object_poses);
        assert_eq!(plan.subtasks[0].src_demo, attempt.plans[0].src_demo);
        assert_eq!(plan.subtasks[0].transformed_poses, attempt.plans[0].transformed_poses);
        assert_eq!(plan.subtasks[0].waypoints, attempt.plans[0].waypoints);
        // The nearest-neighbour ranking is reported and the pick is among the nn_k nearest.
        let distances = plan.subtasks[0].source_distances.as_ref().unwrap();
        assert_eq!(distances.len(), g.dataset().demos.len());
        let nearer = distances.iter().filter(|&&d| d < distances[plan.subtasks[0].src_demo]).count();
        assert!(nearer < 3, "picked the {}th nearest", nearer + 1);
        // Forcing another source keeps the scene and uses that demo where it is forced.
        let other = (attempt.plans[0].src_demo + 1) % g.dataset().demos.len();
        let forced = g.attempt_with(&mut env, index, &Overrides { sources: vec![Some(other), None], ..Overrides::default() }).unwrap();
        assert_eq!(forced.initial_object_poses, attempt.initial_object_poses);
        assert_eq!(forced.src_demo_per_subtask[0], other);
        assert_ne!(forced.plans[0].transformed_poses, attempt.plans[0].transformed_poses);
    }
    let err = g.plan(&mut env, 0, &Overrides { sources: vec![Some(99)], ..Overrides::default() }).unwrap_err().to_string();
    assert!(err.contains("sources[0]") && err.contains("99"), "{err}");
}

#[test]
fn moved_objects_move_the_plan_and_the_attempt_and_nothing_else() {
    let g = generator(kinematic::pick_place_spec(10, 4));
    let mut env = PickPlace::new(0.15);
    let sampled = g.plan(&mut env, 2, &Overrides::default()).unwrap();
    let mut moved_a = sampled.initial_object_poses["cubeA"];
    moved_a.translation.vector.x += 0.05;
    let overrides = Overrides { sources: vec![Some(1), Some(1)], object_poses: [("cubeA".to_owned(), moved_a)].into() };
    let plan = g.plan(&mut env, 2, &overrides).unwrap();
    assert_eq!(plan.initial_object_poses["cubeA"], moved_a);
    assert_eq!(plan.initial_object_poses["cubeB"], sampled.initial_object_poses["cubeB"]);
    // The subtask relative to cubeA moved with it; the one relative to cubeB did not.
    let unmoved = g.plan(&mut env, 2, &Overrides { object_poses: Default::default(), ..overrides.clone() }).unwrap();
    let shift = plan.subtasks[0].transformed_poses[3].translation.vector - unmoved.subtasks[0].transformed_poses[3].translation.vector;
    assert!((shift - nalgebra::Vector3::new(0.05, 0.0, 0.0)).norm() < 1e-9, "{shift:?}");
    assert_eq!(plan.subtasks[1].transformed_poses, unmoved.subtasks[1].transformed_poses);
    let attempt = g.attempt_with(&mut env, 2, &overrides).unwrap();
    assert_eq!(attempt.initial_object_poses["cubeA"], moved_a);
    let err = g.plan(&mut env, 2, &Overrides { object_poses: [("cubeZ".to_owned(), moved_a)].into(), ..Overrides::default() }).unwrap_err();
    assert!(err.to_string().contains("cubeZ"), "{err}");
}

/// Shards of a run, joined in index order, are the run: with a fixed number of attempts, and with
/// `guarantee`, where each shard stops at its own successes and the join is cut at the run's.
#[test]
fn shards_joined_in_index_order_are_the_whole_run() {
    use mimicgen_engine::{RunControl, RunStats, Shard, run_with};
    let sharded = |g: &Generator, shard: Shard, workers: usize| -> (Vec<Attempt>, RunStats) {
        let mut envs: Vec<PickPlace> = (0..workers).map(|_| PickPlace::new(0.15)).collect();
        let mut attempts = Vec::new();
        let control = RunControl { shard, ..RunControl::default() };
        let stats = run_with(
            g,
            &mut envs,
            control,
            |_, _| Ok(()),
            |a, (), _| {
                attempts.push(a);
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        (attempts, stats)
    };
    for guarantee in [false, true] {
        let mut spec = kinematic::pick_place_spec(12, 5);
        spec.generation.guarantee = guarantee;
        spec.subtasks[0].action_noise = 0.4;
        let g = generator(spec);
        let (whole, whole_stats) = collect(&g, 1, 0.15);
        for count in [2, 3] {
            let mut joined: Vec<Attempt> = Vec::new();
            for part in 0..count {
                let shard = Shard::new(part, count).unwrap();
                let (attempts, stats) = sharded(&g, shard, 2);
                assert!(attempts.iter().all(|a| shard.contains(usize::try_from(a.index).unwrap())));
                assert_eq!(stats.attempts, attempts.len());
                if guarantee {
                    assert_eq!(stats.successes, 12, "shard {shard} stops at its own successes");
                }
                joined.extend(attempts);
            }
            joined.sort_by_key(|a| a.index);
            // Cut where the whole run stopped: its last attempt (with guarantee, its 12th success).
            let last = whole.last().unwrap().index;
            joined.retain(|a| a.index <= last);
            assert_eq!(joined, whole, "guarantee {guarantee}, {count} shards");
            let mut replayed = RunStats::new(g.dataset().demos.len());
            for a in &joined {
                replayed.record_outcome(a.success, &a.src_demo_per_subtask, a.failure.as_ref(), a.cause.as_ref());
            }
            assert_eq!(replayed, whole_stats);
        }
    }
    assert!("2/2".parse::<Shard>().is_err() && "1/0".parse::<Shard>().is_err() && "a/2".parse::<Shard>().is_err());
    assert_eq!("1/3".parse::<Shard>().unwrap().first_at_or_after(5), 7);
}

#[test]
fn a_slow_attempt_holds_back_the_others_only_a_bounded_window() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    /// Counts attempts started; the first one started waits until the other worker has run as
    /// far ahead as the pool lets it (a slow attempt), then goes on.
    struct Tally {
        started: AtomicUsize,
        handed_on: AtomicUsize,
        most_ahead: AtomicUsize,
    }
    struct Slow {
        inner: PickPlace,
        tally: Arc<Tally>,
    }
    let window = mimicgen_engine::generate::REORDER_WINDOW_PER_WORKER * 2;
    impl Environment for Slow {
        fn reset(&mut self, rng: &mut dyn rand::RngCore) -> Result<(), mimicgen_engine::EnvError> {
            let t = &self.tally;
            let started = t.started.fetch_add(1, Ordering::SeqCst) + 1;
            let ahead = started - t.handed_on.load(Ordering::SeqCst);
            t.most_ahead.fetch_max(ahead, Ordering::SeqCst);
            if started == 1 {
                let window = mimicgen_engine::generate::REORDER_WINDOW_PER_WORKER * 2;
                while t.started.load(Ordering::SeqCst) - t.handed_on.load(Ordering::SeqCst) < window {
                    std::thread::yield_now();
                }
            }
            self.inner.reset(rng)
        }
        fn eef_pose(&self) -> mimicgen_engine::Pose {
            self.inner.eef_pose()
        }
        fn object_poses(&self) -> std::collections::BTreeMap<String, mimicgen_engine::Pose> {
            self.inner.object_poses()
        }
        fn subtask_term_signals(&self) -> std::collections::BTreeMap<String, i64> {
            self.inner.subtask_term_signals()
        }
        fn is_success(&self) -> bool {
            self.inner.is_success()
        }
        fn target_pose_to_action(&self, t: &mimicgen_engine::Pose) -> [f64; 6] {
            self.inner.target_pose_to_action(t)
        }
        fn action_to_target_pose(&self, a: &[f64]) -> mimicgen_engine::Pose {
            self.inner.action_to_target_pose(a)
        }
        fn action_dim(&self) -> usize {
            7
        }
        fn step(&mut self, a: &[f64]) -> Result<(), mimicgen_engine::EnvError> {
            self.inner.step(a)
        }
        fn state(&self) -> Vec<f64> {
            self.inner.state()
        }
        fn set_state(&mut self, s: &[f64]) -> Result<(), mimicgen_engine::EnvError> {
            self.inner.set_state(s)
        }
    }
    let tally = Arc::new(Tally { started: AtomicUsize::new(0), handed_on: AtomicUsize::new(0), most_ahead: AtomicUsize::new(0) });
    let g = generator(kinematic::pick_place_spec(40, 1));
    let mut envs: Vec<Slow> = (0..2).map(|_| Slow { inner: PickPlace::new(0.1), tally: Arc::clone(&tally) }).collect();
    let mut indices = Vec::new();
    let stats = run(&g, &mut envs, |a, _| {
        indices.push(a.index);
        tally.handed_on.fetch_add(1, Ordering::SeqCst);
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!(stats.attempts, 40);
    assert_eq!(indices, (0..40).collect::<Vec<u64>>());
    // While the slow attempt held everything back, the other worker got exactly as far as the
    // window, and no further.
    assert_eq!(tally.most_ahead.load(Ordering::SeqCst), window);
}

/// A shard read from a file is checked as one given on the command line: `count = 0` would divide
/// by zero wherever the shard decides which attempts are its own.
#[test]
fn a_stored_shard_of_zero_shares_is_refused() {
    use mimicgen_engine::Shard;
    let read = |json: &str| serde_json::from_str::<Shard>(json);
    assert_eq!(read(r#"{"part": 1, "count": 3}"#).unwrap(), Shard::new(1, 3).unwrap());
    for bad in [r#"{"part": 0, "count": 0}"#, r#"{"part": 3, "count": 3}"#] {
        let err = read(bad).unwrap_err().to_string();
        assert!(err.contains("does not exist"), "{bad}: {err}");
    }
}

/// Records `n` tries in the physics-free environment in `style`; the successful demos'
/// actions and the number of successes.
fn record_in_style(style: Style, seed: u64, n: usize) -> (Vec<Vec<Vec<f64>>>, usize) {
    let script = PickPlaceScript { style, ..kinematic::pick_place_script() };
    let mut env = PickPlace::new(0.08);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut actions = Vec::new();
    let mut successes = 0;
    for _ in 0..n {
        env.reset(&mut rng).unwrap();
        let demo = script.record(&mut env, "demo", &mut rng).unwrap();
        successes += usize::from(env.is_success());
        actions.push((0..demo.sim.actions.len()).map(|t| demo.sim.actions.row(t).to_vec()).collect());
    }
    (actions, successes)
}

#[test]
fn human_style_demos_are_seeded_longer_than_careful_ones_and_still_succeed() {
    let (human, human_ok) = record_in_style(Style::Human, 5, 20);
    let (again, _) = record_in_style(Style::Human, 5, 20);
    assert_eq!(human, again, "the same seed records the same demos");
    let (careful, careful_ok) = record_in_style(Style::Careful, 5, 20);
    assert!(human_ok >= 16 && careful_ok >= 16, "successes: human {human_ok}, careful {careful_ok} of 20");
    let steps = |demos: &[Vec<Vec<f64>>]| demos.iter().map(Vec::len).sum::<usize>();
    // Reaction, hesitation, corrections and slower starts and stops take time.
    assert!(steps(&human) > steps(&careful) * 11 / 10, "steps: human {}, careful {}", steps(&human), steps(&careful));
}

#[test]
fn the_quality_figures_show_a_stitch_made_to_jump() {
    // Without a bridge into the place, the commanded pose jumps from the grasp's last target to
    // the place segment's first; with the spec's 5 interpolation steps it moves there in 6 steps.
    let quality = |steps: usize| {
        let mut spec = kinematic::pick_place_spec(20, 5);
        spec.subtasks[1].num_interpolation_steps = steps;
        let (attempts, _) = collect(&generator(spec), 1, 0.1);
        let mut q = mimicgen_engine::quality::QualityStats::default();
        for a in attempts.iter().filter(|a| a.success) {
            q.add(a, 0.05);
        }
        q.summary()
    };
    let (smooth, jumpy) = (quality(5), quality(0));
    let place_start = |q: &mimicgen_engine::quality::Quality| {
        q.stitches.iter().find(|s| s.subtask == 1 && s.at == mimicgen_engine::quality::StitchAt::InterpolationStart).cloned().unwrap()
    };
    let (s, j) = (place_start(&smooth), place_start(&jumpy));
    assert!(s.count > 10 && j.count > 10, "{s:?} {j:?}");
    assert!(j.jump_m_max > 3.0 * s.jump_m_max && j.jump_m_p95 > 3.0 * s.jump_m_p95, "jumpy {j:?}, smooth {s:?}");
    assert!(j.jump_m_p95 > 3.0 * j.step_m_p95, "a jump stands out from the subtask's steps: {j:?}");
    // The smooth one bridges: its segment starts after interpolation, the jumpy one's does not.
    assert!(smooth.stitches.iter().any(|s| s.subtask == 1 && s.at == mimicgen_engine::quality::StitchAt::InterpolationEnd));
    assert!(!jumpy.stitches.iter().any(|s| s.subtask == 1 && s.at == mimicgen_engine::quality::StitchAt::InterpolationEnd));
    // Actions: every step counted, none beyond the controller's limits.
    let a = &smooth.actions;
    assert!(a.steps > 0 && a.max_abs.len() == 6 && a.max_abs.iter().all(|&m| m <= 1.0));
    assert!(a.p95_abs.iter().zip(&a.max_abs).all(|(p, m)| *p <= m + 0.01), "{a:?}");
}
