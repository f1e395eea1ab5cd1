//! The two-arm schedule (DexMimicGen's subtask kinds): coordination subtasks start and end on the
//! same step, a sequential subtask never starts before the one it waits for has ended, and
//! constraints that can never be met are refused.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)] // tests fail loudly by design

use std::collections::BTreeMap;

use mimicgen_engine::two_arm::{ArmStep, ArmSubtask, Constraint, Schedule};
use proptest::prelude::*;

/// When each subtask started and ended (the step of its first action, the step after its last).
#[derive(Debug, Default)]
struct Timeline {
    start: BTreeMap<ArmSubtask, usize>,
    end: BTreeMap<ArmSubtask, usize>,
}

/// Runs `schedule` to its end, each subtask taking `lengths[s]` steps, as a generator would:
/// start what is ready, act, advance. Checks on the way that each arm runs its subtasks' steps in
/// order.
fn run(mut schedule: Schedule, lengths: &BTreeMap<ArmSubtask, usize>) -> Timeline {
    let mut t = Timeline::default();
    for step in 0..10_000 {
        loop {
            let groups = schedule.ready();
            if groups.is_empty() {
                break;
            }
            for group in groups {
                let with_lengths: Vec<(ArmSubtask, usize)> = group.iter().map(|s| (*s, lengths[s])).collect();
                schedule.start(&with_lengths).unwrap();
                for (s, n) in with_lengths {
                    t.start.insert(s, step);
                    if n == 0 {
                        t.end.insert(s, step);
                    }
                }
            }
        }
        if schedule.is_done() {
            return t;
        }
        for (arm, s) in schedule.steps().into_iter().enumerate() {
            if let ArmStep::Run { subtask, step: k } = s {
                assert_eq!(t.start[&(arm, subtask)] + k, step, "arm {arm} subtask {subtask} skipped or repeated a step");
            }
        }
        for s in schedule.advance() {
            t.end.insert(s, step + 1);
        }
    }
    panic!("the schedule never ended");
}

fn arb_case() -> impl Strategy<Value = (Vec<usize>, Vec<Constraint>, Vec<usize>)> {
    (1usize..5, 1usize..5).prop_flat_map(|(n0, n1)| {
        let subtask = |arm: usize, n: usize| (Just(arm), 0..n);
        let pair = (subtask(0, n0), subtask(1, n1));
        let constraint = (any::<bool>(), any::<bool>(), pair).prop_map(|(coordinate, zero_first, (a, b))| {
            if coordinate {
                Constraint::Coordination(a, b)
            } else if zero_first {
                Constraint::Sequential { first: a, later: b }
            } else {
                Constraint::Sequential { first: b, later: a }
            }
        });
        (Just(vec![n0, n1]), prop::collection::vec(constraint, 0..4), prop::collection::vec(0usize..6, n0 + n1))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn coordinated_subtasks_start_and_end_together_and_sequential_ones_wait((counts, constraints, raw) in arb_case()) {
        let Ok(schedule) = Schedule::new(&counts, &constraints) else {
            // Refused: no order of lengths may then run it to the end (checked below for the
            // accepted ones); a refusal is tested on its own.
            return Ok(());
        };
        let mut lengths: BTreeMap<ArmSubtask, usize> = BTreeMap::new();
        let mut raw = raw.into_iter();
        for (arm, &n) in counts.iter().enumerate() {
            for k in 0..n {
                lengths.insert((arm, k), raw.next().unwrap());
            }
        }
        // Coordinated subtasks are planned to the same length (the generator pads the shorter).
        for c in &constraints {
            if let Constraint::Coordination(a, b) = *c {
                let n = lengths[&a].max(lengths[&b]);
                lengths.insert(a, n);
                lengths.insert(b, n);
            }
        }
        let t = run(schedule, &lengths);
        for (arm, &n) in counts.iter().enumerate() {
            for k in 0..n {
                prop_assert!(t.start.contains_key(&(arm, k)) && t.end.contains_key(&(arm, k)), "arm {arm} subtask {k} never ran");
                prop_assert_eq!(t.end[&(arm, k)], t.start[&(arm, k)] + lengths[&(arm, k)]);
                if k > 0 {
                    prop_assert!(t.start[&(arm, k)] >= t.end[&(arm, k - 1)]);
                }
            }
        }
        for c in &constraints {
            match *c {
                Constraint::Coordination(a, b) => {
                    prop_assert_eq!(t.start[&a], t.start[&b], "{:?}", c);
                    prop_assert_eq!(t.end[&a], t.end[&b], "{:?}", c);
                }
                Constraint::Sequential { first, later } => {
                    prop_assert!(t.start[&later] >= t.end[&first], "{:?}: started {} before {} ended", c, t.start[&later], t.end[&first]);
                }
            }
        }
    }

    #[test]
    fn without_constraints_each_arm_runs_back_to_back(lengths in prop::collection::vec(1usize..6, 1..5)) {
        // One arm with subtasks, the other idle: the single-arm schedule, no step held.
        let schedule = Schedule::new(&[lengths.len(), 0], &[]).unwrap();
        let map: BTreeMap<ArmSubtask, usize> = lengths.iter().enumerate().map(|(k, &n)| ((0, k), n)).collect();
        let t = run(schedule, &map);
        let mut at = 0;
        for (k, n) in lengths.iter().enumerate() {
            prop_assert_eq!(t.start[&(0, k)], at);
            at += n;
        }
    }
}

#[test]
fn constraints_that_can_never_be_met_are_refused_naming_the_subtasks() {
    // Each arm's first subtask waits for the other's second.
    let cycle = [Constraint::Sequential { first: (0, 1), later: (1, 0) }, Constraint::Sequential { first: (1, 1), later: (0, 0) }];
    let err = Schedule::new(&[2, 2], &cycle).unwrap_err().to_string();
    assert!(err.contains("arm 0 subtask 0") && err.contains("arm 1 subtask 0") && err.contains("never"), "{err}");
    // Crossed coordinations: arm 0's first with arm 1's second, and the other way round.
    let crossed = [Constraint::Coordination((0, 0), (1, 1)), Constraint::Coordination((0, 1), (1, 0))];
    assert!(Schedule::new(&[2, 2], &crossed).is_err());
    // A subtask that does not exist, an arm tied to itself, a subtask in two coordinations.
    let err = Schedule::new(&[2, 2], &[Constraint::Coordination((0, 2), (1, 0))]).unwrap_err().to_string();
    assert!(err.contains("arm 0 subtask 2") && err.contains("does not exist"), "{err}");
    assert!(Schedule::new(&[2, 2], &[Constraint::Sequential { first: (0, 0), later: (0, 1) }]).is_err());
    let twice = [Constraint::Coordination((0, 0), (1, 0)), Constraint::Coordination((0, 0), (1, 1))];
    assert!(Schedule::new(&[2, 2], &twice).unwrap_err().to_string().contains("two coordination"));
    // A coordination pair started apart, or with different lengths, is refused.
    let mut s = Schedule::new(&[1, 1], &[Constraint::Coordination((0, 0), (1, 0))]).unwrap();
    assert_eq!(s.ready(), vec![vec![(0, 0), (1, 0)]]);
    assert!(s.start(&[((0, 0), 3)]).unwrap_err().contains("without"));
    assert!(s.start(&[((0, 0), 3), ((1, 0), 4)]).unwrap_err().contains("different lengths"));
    s.start(&[((0, 0), 3), ((1, 0), 3)]).unwrap();
}

#[test]
fn a_handover_waits_for_the_give_and_the_giver_holds_while_the_other_arm_catches_up() {
    // Arm 0: grasp, give (2 subtasks); arm 1: receive after the give. Arm 1 holds until then.
    let mut s = Schedule::new(&[2, 1], &[Constraint::Sequential { first: (0, 1), later: (1, 0) }]).unwrap();
    assert_eq!(s.ready(), vec![vec![(0, 0)]]);
    s.start(&[((0, 0), 2)]).unwrap();
    assert_eq!(s.steps(), vec![ArmStep::Run { subtask: 0, step: 0 }, ArmStep::Hold]);
    assert!(s.advance().is_empty());
    assert_eq!(s.advance(), vec![(0, 0)]);
    assert!(s.ended((0, 0)) && !s.ended((0, 1)));
    assert_eq!(s.ready(), vec![vec![(0, 1)]]);
    s.start(&[((0, 1), 1)]).unwrap();
    assert_eq!(s.advance(), vec![(0, 1)]);
    assert_eq!(s.ready(), vec![vec![(1, 0)]]);
    s.start(&[((1, 0), 1)]).unwrap();
    assert_eq!(s.steps(), vec![ArmStep::Hold, ArmStep::Run { subtask: 0, step: 0 }]);
    s.advance();
    assert!(s.is_done());
}

const HANDOVER: &str = r#"
name = "two_arm_handover"
[[arm]]
name = "robot0"
[[arm.subtask]]
object_ref = "hammer"
term_signal = "grasp0"
[[arm.subtask]]
object_ref = "hammer"

[[arm]]
name = "robot1"
[[arm.subtask]]
object_ref = "hammer"

[[sequential]]
first = [0, 1]
later = [1, 0]
"#;

#[test]
fn a_two_arm_spec_reads_its_ties_and_names_the_field_at_fault() {
    use mimicgen_engine::two_arm::TwoArmSpec;
    let spec = TwoArmSpec::from_toml_str(HANDOVER, "handover.toml").unwrap();
    assert_eq!(spec.constraints(), vec![Constraint::Sequential { first: (0, 1), later: (1, 0) }]);
    assert_eq!(spec.arm_spec(1).unwrap().subtasks.len(), 1);
    let config = |text: &str| match TwoArmSpec::from_toml_str(text, "t.toml").unwrap_err() {
        mimicgen_engine::EngineError::Config { file, field, reason } => {
            assert!(file.starts_with("t.toml"), "{file}");
            (field, reason)
        }
        other => panic!("{other:?}"),
    };
    // A subtask field, as a one-arm spec checks it, under its arm.
    let (field, reason) = config(&HANDOVER.replacen("term_signal = \"grasp0\"", "term_signal = \"grasp0\"\naction_noise = -1.0", 1));
    assert_eq!(field, "arm[0].subtask[0].action_noise", "{reason}");
    // A TOML error in the second arm's subtask names it within its arm.
    let (field, _) = config(&HANDOVER.replace("name = \"robot1\"\n[[arm.subtask]]\n", "name = \"robot1\"\n[[arm.subtask]]\nbogus = 1\n"));
    assert_eq!(field, "arm[1].subtask[0].bogus");
    // A tie to a subtask that does not exist.
    let (field, reason) = config(&HANDOVER.replace("later = [1, 0]", "later = [1, 3]"));
    assert!(field == "sequential" && reason.contains("arm 1 subtask 3"), "{field}: {reason}");
    // Coordinated subtasks on different objects.
    let other = HANDOVER.replace("[[sequential]]\nfirst = [0, 1]\nlater = [1, 0]", "[[coordination]]\nsubtasks = [[0, 1], [1, 0]]");
    let other = other.replacen(
        "name = \"robot1\"\n[[arm.subtask]]\nobject_ref = \"hammer\"",
        "name = \"robot1\"\n[[arm.subtask]]\nobject_ref = \"bin\"",
        1,
    );
    let (field, reason) = config(&other);
    assert!(field == "coordination[0].subtasks" && reason.contains("\"bin\""), "{field}: {reason}");
    // One arm is not two.
    let one = &HANDOVER[..HANDOVER.find("[[arm]]\nname = \"robot1\"").unwrap()];
    let (field, _) = config(one);
    assert_eq!(field, "arm");
}

/// The kinematic pick-and-place as arm 0, and a second hand as arm 1 that goes where it is sent
/// and touches nothing.
struct WithSecondHand {
    one: mimicgen_engine::kinematic::PickPlace,
    hand: mimicgen_engine::Pose,
}

impl mimicgen_engine::two_arm::TwoArmEnvironment for WithSecondHand {
    fn reset(&mut self, rng: &mut dyn rand::RngCore) -> Result<(), mimicgen_engine::EnvError> {
        self.hand = mimicgen_engine::Pose::translation(0.0, 0.6, 1.0);
        mimicgen_engine::Environment::reset(&mut self.one, rng)
    }
    fn eef_pose(&self, arm: usize) -> mimicgen_engine::Pose {
        if arm == 0 { mimicgen_engine::Environment::eef_pose(&self.one) } else { self.hand }
    }
    fn object_poses(&self) -> BTreeMap<String, mimicgen_engine::Pose> {
        mimicgen_engine::Environment::object_poses(&self.one)
    }
    fn subtask_term_signals(&self) -> BTreeMap<String, i64> {
        mimicgen_engine::Environment::subtask_term_signals(&self.one)
    }
    fn is_success(&self) -> bool {
        mimicgen_engine::Environment::is_success(&self.one)
    }
    fn target_pose_to_action(&self, arm: usize, target: &mimicgen_engine::Pose) -> [f64; 6] {
        if arm == 0 {
            return mimicgen_engine::Environment::target_pose_to_action(&self.one, target);
        }
        let d = (target.translation.vector - self.hand.translation.vector) / 0.05;
        [d.x.clamp(-1.0, 1.0), d.y.clamp(-1.0, 1.0), d.z.clamp(-1.0, 1.0), 0.0, 0.0, 0.0]
    }
    fn action_to_target_pose(&self, arm: usize, action: &[f64]) -> mimicgen_engine::Pose {
        if arm == 0 {
            return mimicgen_engine::Environment::action_to_target_pose(&self.one, action);
        }
        mimicgen_engine::Pose::translation(action[0] * 0.05, action[1] * 0.05, action[2] * 0.05) * self.hand
    }
    fn gripper_dim(&self, _arm: usize) -> usize {
        mimicgen_engine::Environment::action_dim(&self.one) - 6
    }
    fn step(&mut self, action: &[f64]) -> Result<(), mimicgen_engine::EnvError> {
        let split = mimicgen_engine::Environment::action_dim(&self.one);
        self.hand = self.action_to_target_pose(1, &action[split..]);
        mimicgen_engine::Environment::step(&mut self.one, &action[..split])
    }
    fn state(&self) -> Vec<f64> {
        let mut s = mimicgen_engine::Environment::state(&self.one);
        s.extend(self.hand.translation.vector.iter());
        s
    }
}

#[test]
fn one_arms_subtasks_with_the_other_arm_idle_are_todays_one_arm_generation() {
    use mimicgen_engine::two_arm::{ArmSpec, TwoArmGenerator, TwoArmSpec};
    use mimicgen_engine::{Generator, kinematic};
    let one = kinematic::pick_place_spec(12, 3);
    let sources = kinematic::scripted_dataset(4, 1).unwrap();
    let single = Generator::new(one.clone(), sources.clone()).unwrap();
    let spec = TwoArmSpec {
        name: "pick_place_and_a_hand".to_owned(),
        env_name: None,
        generation: one.generation.clone(),
        arms: vec![
            ArmSpec { name: "robot0".to_owned(), subtasks: one.subtasks.clone() },
            ArmSpec { name: "robot1".to_owned(), subtasks: Vec::new() },
        ],
        coordinations: Vec::new(),
        sequentials: Vec::new(),
    };
    let two = TwoArmGenerator::new(spec, vec![sources.clone(), sources]).unwrap();
    let mut successes = 0;
    let (mut one_stats, mut two_stats) = (mimicgen_engine::RunStats::new(4), mimicgen_engine::RunStats::new(4));
    for index in 0..12 {
        let a = single.attempt(&mut kinematic::PickPlace::new(0.1), index).unwrap();
        let mut env = WithSecondHand { one: kinematic::PickPlace::new(0.1), hand: mimicgen_engine::Pose::identity() };
        let b = two.attempt(&mut env, index).unwrap();
        one_stats.record(&a);
        b.record_into(&mut two_stats, &[one.subtasks.len(), 0]);
        successes += usize::from(a.success);
        assert_eq!(a.success, b.success, "attempt {index}");
        let arm = &b.arms[0];
        assert_eq!(a.src_demo_per_subtask, arm.plans.iter().map(|p| p.src_demo).collect::<Vec<_>>());
        assert_eq!(a.trajectory.eef_poses, arm.eef_poses, "attempt {index}");
        assert_eq!(a.trajectory.target_poses, arm.target_poses);
        assert_eq!(a.trajectory.gripper_actions, arm.gripper_actions);
        assert_eq!(a.trajectory.subtask_labels, arm.subtask_labels);
        assert_eq!(a.trajectory.src_demo_labels, arm.src_demo_labels);
        let width = a.trajectory.actions.width();
        for t in 0..a.trajectory.len() {
            assert_eq!(a.trajectory.actions.row(t), &b.actions.row(t)[..width], "attempt {index} step {t}");
        }
        // The other hand held where it started.
        assert!(b.arms[1].holding.iter().all(|&h| h) && b.arms[1].eef_poses.iter().all(|p| *p == b.arms[1].eef_poses[0]));
        assert_eq!(a.failure.map(|f| (f.subtask, f.reason)), b.failure.map(|f| (f.subtask, f.reason)));
    }
    assert!(successes > 0, "no attempt succeeded: the comparison covered failures only");
    // The run's statistics too (the two-arm run records no causes yet).
    assert_eq!(two_stats, mimicgen_engine::RunStats { causes: Vec::new(), ..one_stats });
}

#[test]
fn a_coordinated_pair_shares_its_source_demo_and_transform_and_runs_in_lockstep() {
    use mimicgen_engine::two_arm::{ArmSpec, CoordinationSpec, SequentialSpec, TwoArmGenerator, TwoArmSpec};
    use mimicgen_engine::{kinematic, transform::WaypointKind};
    let one = kinematic::pick_place_spec(6, 5);
    let sources = kinematic::scripted_dataset(4, 1).unwrap();
    // Arm 1 (the second hand, a view of the same demos) places with arm 0, after waiting for
    // nothing; then a last subtask of its own that starts only after arm 0's place has ended.
    let mut place = one.subtasks[1].clone();
    place.term_signal = Some("grasp".to_owned());
    let mut grasp_last = one.subtasks[0].clone();
    (grasp_last.term_signal, grasp_last.term_offset_range) = (None, None);
    let spec = TwoArmSpec {
        name: "pair".to_owned(),
        env_name: None,
        generation: one.generation.clone(),
        arms: vec![
            ArmSpec { name: "robot0".to_owned(), subtasks: one.subtasks.clone() },
            ArmSpec { name: "robot1".to_owned(), subtasks: vec![place, grasp_last] },
        ],
        coordinations: vec![CoordinationSpec { subtasks: [(0, 1), (1, 0)] }],
        sequentials: vec![SequentialSpec { first: (0, 1), later: (1, 1) }],
    };
    let two = TwoArmGenerator::new(spec, vec![sources.clone(), sources]).unwrap();
    for index in 0..6 {
        let mut env = WithSecondHand { one: kinematic::PickPlace::new(0.1), hand: mimicgen_engine::Pose::identity() };
        let b = two.attempt(&mut env, index).unwrap();
        let (p0, p1) = (&b.arms[0].plans[1], &b.arms[1].plans[0]);
        assert_eq!(p0.src_demo, p1.src_demo, "attempt {index}");
        assert_eq!(p0.world_from_obj_src, p1.world_from_obj_src);
        assert_eq!(p0.first_step, p1.first_step, "attempt {index}: started apart");
        assert_eq!(p0.waypoints.len(), p1.waypoints.len(), "attempt {index}: lengths differ");
        // Arm 1 held until the pair started, ran with arm 0, then waited for arm 0's place to end.
        let run = |arm: usize, t: usize| !b.arms[arm].holding[t];
        assert!((0..p0.first_step).all(|t| !run(1, t)));
        let end = p0.first_step + p0.waypoints.len();
        assert!((p0.first_step..end).all(|t| run(0, t) && run(1, t)));
        let p2 = &b.arms[1].plans[1];
        assert!(p2.first_step >= end, "attempt {index}: arm 1's last started at {} before {end}", p2.first_step);
        assert!(p0.waypoints.iter().chain(&p1.waypoints).any(|(_, k)| *k == WaypointKind::Transformed));
        // A run's statistics number arm 1's subtasks after arm 0's two.
        let mut stats = mimicgen_engine::RunStats::new(4);
        b.record_into(&mut stats, &[2, 2]);
        assert_eq!(stats.per_subtask_source.len(), 4);
        for (k, plan) in b.arms[0].plans.iter().chain(&b.arms[1].plans).enumerate() {
            assert_eq!(stats.per_subtask_source[k][plan.src_demo].attempts, 1, "attempt {index}: subtask {k}");
        }
        if let Some(f) = &b.failure {
            assert_eq!(stats.failures[0].subtask, 2 * f.arm.unwrap_or(0) + f.subtask);
        }
    }
}
