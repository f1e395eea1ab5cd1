//! robosuite's two-arm tasks in MuJoCo: both arms under their own controllers, the scripted
//! demonstrators, and generation with coordinated and sequential subtasks (Lift, Handover,
//! Transport).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)] // tests fail loudly by design

use std::sync::Arc;

use mimicgen_engine::demonstrator::Style;
use mimicgen_engine::two_arm::{TwoArmEnvironment, TwoArmLiftScript};
use mimicgen_sim::two_arm::{TwoArmSimEnv, TwoArmTask};
use rand::SeedableRng;

fn env(variant: &str) -> TwoArmSimEnv {
    let scene = Arc::new(TwoArmTask::Lift.scene().unwrap());
    TwoArmSimEnv::new(scene, TwoArmTask::Lift, variant).unwrap()
}

/// The scripted lift grasps both handles on about the same step and lifts the pot 10 cm; each
/// arm's action half moves its own arm.
#[test]
fn the_scripted_two_arm_lift_lifts_the_pot_by_both_handles() {
    let mut env = env("D0");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    env.reset(&mut rng).unwrap();
    let demo = TwoArmLiftScript::pot().record(&mut env, Style::Careful, &mut rng).unwrap();
    assert!(demo.success, "{:?}", env.unmet_success());
    assert_eq!(demo.actions.width(), 14);
    let first_on = |signal: &str| demo.subtask_term_signals[signal].iter().position(|&v| v != 0).unwrap();
    let (g0, g1) = (first_on("grasp_handle0"), first_on("grasp_handle1"));
    assert!(g0.abs_diff(g1) <= 3, "handle grasps at steps {g0} and {g1}");
    for arm in 0..2 {
        let track = &demo.arms[arm];
        assert_eq!(track.eef_poses.len(), demo.actions.len());
        // Each arm's end effector went up with the pot.
        let rise = track.eef_poses.last().unwrap().translation.z - track.eef_poses[0].translation.z;
        assert!(rise > 0.05, "arm {arm} rose {rise:.3} m");
    }
    // Arm 1 is across the table from arm 0 (robosuite's "single-arm-opposed").
    assert!(demo.arms[0].eef_poses[0].translation.y < -0.05 && demo.arms[1].eef_poses[0].translation.y > 0.05);
    let obs = env.observation();
    assert_eq!(obs["object"].len(), 19);
    assert_eq!(obs["robot1_eef_pos"].len(), 3);
}

/// The human style: the same scene and script, recorded slower and with a hand that is never
/// quite still, yet both arms still close on the same step and lift on the same step (a
/// reaction is drawn only where an arm waited for the other, never between legs the two start
/// together).
#[test]
fn a_human_style_two_arm_lift_reacts_and_drifts_but_closes_and_lifts_together() {
    let record = |style: Style| {
        let mut env = env("D0");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        env.reset(&mut rng).unwrap();
        let demo = TwoArmLiftScript::pot().record(&mut env, style, &mut rng).unwrap();
        assert!(demo.success, "{style:?}: {:?}", env.unmet_success());
        demo
    };
    let (careful, human) = (record(Style::Careful), record(Style::Human));
    assert!(human.actions.len() > careful.actions.len(), "{} steps, careful {}", human.actions.len(), careful.actions.len());
    // Each arm's first step: the careful hand starts at once; the human one reacts first.
    let first_move = |demo: &mimicgen_engine::two_arm::TwoArmAttempt, arm: usize| {
        let start = demo.arms[arm].target_poses[0].translation.vector;
        demo.arms[arm].target_poses.iter().position(|p| (p.translation.vector - start).norm() > 0.004).unwrap()
    };
    for arm in 0..2 {
        assert!(first_move(&human, arm) > first_move(&careful, arm), "arm {arm}");
    }
    // Both grippers close on one step.
    let closes = |demo: &mimicgen_engine::two_arm::TwoArmAttempt, arm: usize| {
        (0..demo.actions.len()).position(|t| demo.arms[arm].gripper_actions.row(t)[0] > 0.0).unwrap()
    };
    assert_eq!(closes(&human, 0), closes(&human, 1));
    // While closing, the commanded hands drift by about a millimetre rather than hold exactly.
    let t = closes(&human, 0);
    let drift = (human.arms[0].target_poses[t + 5].translation.vector - human.arms[0].target_poses[t].translation.vector).norm();
    assert!(drift > 1e-5 && drift < 0.005, "{drift}");
}

/// Generation from scripted demos: each arm grasps on its own, then both lift in lockstep from
/// one source demo; most attempts lift the pot.
#[test]
fn two_arm_lift_generates_with_a_coordinated_lift() {
    use mimicgen_engine::demo::SourceDataset;
    use mimicgen_engine::two_arm::TwoArmGenerator;

    let mut env = env("D0");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut views: Vec<Vec<_>> = vec![Vec::new(), Vec::new()];
    for k in 0..4 {
        env.reset(&mut rng).unwrap();
        let demo = TwoArmLiftScript::pot().record(&mut env, Style::Careful, &mut rng).unwrap();
        assert!(demo.success);
        for (arm, view) in demo.arm_views(&format!("demo_{k}")).into_iter().enumerate() {
            views[arm].push(view);
        }
    }
    let sources = views.into_iter().map(|demos| SourceDataset { demos, env_args: None }).collect();
    let generator = TwoArmGenerator::new(TwoArmTask::Lift.spec().unwrap(), sources).unwrap();
    let mut successes = 0;
    for index in 0..6 {
        let attempt = generator.attempt(&mut env, index).unwrap();
        successes += usize::from(attempt.success);
        assert_eq!(attempt.actions.width(), 14);
        // The lift (each arm's subtask 1): one source demo, the same first step and length.
        let lift = |arm: usize| attempt.arms[arm].plans.get(1);
        if let (Some(a), Some(b)) = (lift(0), lift(1)) {
            assert_eq!(a.src_demo, b.src_demo, "attempt {index}");
            assert_eq!(a.first_step, b.first_step, "attempt {index}");
            assert_eq!(a.waypoints.len(), b.waypoints.len(), "attempt {index}");
        }
    }
    assert!(successes >= 3, "{successes} of 6 attempts lifted the pot");
}

/// The scripted handover: arm 1 starts for the handle only once arm 0 holds the hammer at the
/// handover point, arm 0 lets go only once arm 1 has closed, and robosuite's success holds.
#[test]
fn the_scripted_handover_gives_the_hammer_from_arm_0_to_arm_1() {
    use mimicgen_engine::two_arm::TwoArmHandoverScript;
    let scene = Arc::new(TwoArmTask::Handover.scene().unwrap());
    let mut env = TwoArmSimEnv::new(scene, TwoArmTask::Handover, "D0").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut successes = 0;
    for _ in 0..4 {
        env.reset(&mut rng).unwrap();
        let demo = TwoArmHandoverScript::hammer().record(&mut env, Style::Careful, &mut rng).unwrap();
        let first_on = |signal: &str| demo.subtask_term_signals[signal].iter().position(|&v| v != 0);
        let (Some(lift), Some(at), Some(grasp)) = (first_on("lift"), first_on("at_handover"), first_on("handle_grasp")) else {
            eprintln!("a signal never turned on: {:?}", demo.subtask_term_signals.keys());
            continue;
        };
        if !demo.success {
            eprintln!("failed: {:?}", env.unmet_success());
            continue;
        }
        successes += 1;
        assert!(lift < at && at < grasp, "lift {lift}, at handover {at}, handle grasp {grasp}");
        // Arm 1 stood still until the hammer was at the handover.
        let arm1 = &demo.arms[1].eef_poses;
        assert!((arm1[at].translation.vector - arm1[0].translation.vector).norm() < 0.02);
        assert_eq!(obs_len(&env), 16);
    }
    assert!(successes >= 3, "{successes} of 4 scripted handovers succeeded with every signal");
}

fn obs_len(env: &TwoArmSimEnv) -> usize {
    env.observation()["object"].len()
}

/// Handover generation on the simulator: arm 0's release never starts before arm 1's grasp of the
/// handle has ended, the coordinated pairs start on one step, and handovers succeed.
#[test]
fn handover_generation_keeps_its_order_and_hands_over() {
    use mimicgen_engine::demo::SourceDataset;
    use mimicgen_engine::two_arm::{TwoArmGenerator, TwoArmHandoverScript};

    let scene = Arc::new(TwoArmTask::Handover.scene().unwrap());
    let mut env = TwoArmSimEnv::new(scene, TwoArmTask::Handover, "D0").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let spec = TwoArmTask::Handover.spec().unwrap();
    let mut views: Vec<Vec<_>> = vec![Vec::new(), Vec::new()];
    while views[0].len() < 3 {
        env.reset(&mut rng).unwrap();
        let demo = TwoArmHandoverScript::hammer().record(&mut env, Style::Careful, &mut rng).unwrap();
        let arm_views = demo.arm_views(&format!("demo_{}", views[0].len()));
        let one = arm_views.iter().map(|d| SourceDataset { demos: vec![d.clone()], env_args: None }).collect();
        if demo.success && TwoArmGenerator::new(spec.clone(), one).is_ok() {
            for (arm, view) in arm_views.into_iter().enumerate() {
                views[arm].push(view);
            }
        }
    }
    let sources = views.into_iter().map(|demos| SourceDataset { demos, env_args: None }).collect();
    let generator = TwoArmGenerator::new(spec, sources).unwrap();
    let mut successes = 0;
    for index in 0..4 {
        let attempt = generator.attempt(&mut env, index).unwrap();
        successes += usize::from(attempt.success);
        let plan = |arm: usize, k: usize| attempt.arms[arm].plans.get(k);
        if let (Some(grasp), Some(release)) = (plan(1, 1), plan(0, 3)) {
            assert!(release.first_step >= grasp.first_step + grasp.waypoints.len(), "attempt {index}: released before the grasp ended");
        }
        for (a, b) in [((0, 1), (1, 0)), ((0, 2), (1, 1)), ((0, 3), (1, 2))] {
            if let (Some(x), Some(y)) = (plan(a.0, a.1), plan(b.0, b.1)) {
                assert_eq!(x.first_step, y.first_step, "attempt {index}: {a:?} and {b:?}");
                assert_eq!(x.src_demo, y.src_demo, "attempt {index}: {a:?} and {b:?}");
            }
        }
    }
    assert!(successes >= 2, "{successes} of 4 handovers succeeded");
}

/// Two Arm Transport at robosuite's reset: the hammer and the lid in the start bin, the trash in
/// the target bin, nothing delivered; after a second of holding still everything rests where it
/// was put, in both variants.
#[test]
fn the_transport_scene_rests_unsolved_in_both_variants() {
    let scene = Arc::new(TwoArmTask::Transport.scene().unwrap());
    for variant in ["D0", "D1"] {
        let mut env = TwoArmSimEnv::new(Arc::clone(&scene), TwoArmTask::Transport, variant).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for _ in 0..3 {
            env.reset(&mut rng).unwrap();
            let before = env.object_poses();
            let hold: Vec<f64> =
                (0..2).flat_map(|arm| env.target_pose_to_action(arm, &env.eef_pose(arm)).into_iter().chain([-1.0])).collect();
            for _ in 0..20 {
                env.step(&hold).unwrap();
                assert!(!env.is_success(), "{variant}: solved by holding still");
            }
            for (name, pose) in env.object_poses() {
                let moved = (pose.translation.vector - before[&name].translation.vector).norm();
                assert!(moved < 0.01, "{variant}: {name} moved {moved:.3} m at rest");
            }
            let at = |name: &str| env.object_poses()[name].translation.vector;
            let flat = |a: &str, b: &str| (at(a).xy() - at(b).xy()).norm();
            assert!(flat("payload", "start_bin") < 0.02 && flat("lid", "start_bin") < 0.01 && flat("trash", "target_bin") < 0.01);
            assert!(env.subtask_term_signals().values().all(|&v| v == 0), "{variant}: {:?}", env.subtask_term_signals());
            assert_eq!(obs_len(&env), 41);
        }
    }
}

/// The scripted transport: arm 0's lid, hammer and handover signals and arm 1's trash signals in
/// their order, arm 1's grasp of the handle only after the hammer is at the handover, and
/// robosuite's success; then generation runs arm 1's wait in lockstep with arm 0's carry and keeps
/// the three sequential ties (arm 1 comes for the handle only after arm 0's carry ended, arm 0
/// lets go only after arm 1's grasp ended, arm 1 carries the hammer away only after arm 0's release
/// ended). Deliveries from the bundled sources:
/// `app/cli/tests/two_arm.rs`.
#[test]
fn the_transport_hands_the_hammer_over_into_the_target_bin_in_order() {
    use mimicgen_engine::demo::SourceDataset;
    use mimicgen_engine::two_arm::{TwoArmGenerator, TwoArmTransportScript};

    let scene = Arc::new(TwoArmTask::Transport.scene().unwrap());
    let mut env = TwoArmSimEnv::new(scene, TwoArmTask::Transport, "D0").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let spec = TwoArmTask::Transport.spec().unwrap();
    let mut views: Vec<Vec<_>> = vec![Vec::new(), Vec::new()];
    let mut tries = 0;
    while views[0].len() < 2 {
        tries += 1;
        assert!(tries <= 6, "the script succeeded {} times in {} tries", views[0].len(), tries - 1);
        env.reset(&mut rng).unwrap();
        let demo = TwoArmTransportScript::transport().record(&mut env, Style::Careful, &mut rng).unwrap();
        if !demo.success {
            continue;
        }
        let first_on = |signal: &str| demo.subtask_term_signals[signal].iter().position(|&v| v != 0).unwrap();
        let order = ["lid_grasp", "lid_off", "payload_lift", "at_handover", "handle_grasp"].map(first_on);
        assert!(order.is_sorted(), "arm 0's signals out of order: {order:?}");
        let trash = ["trash_grasp", "trash_in_bin", "handle_grasp"].map(first_on);
        assert!(trash.is_sorted(), "arm 1's signals out of order: {trash:?}");
        for (arm, view) in demo.arm_views(&format!("demo_{}", views[0].len())).into_iter().enumerate() {
            views[arm].push(view);
        }
    }
    let sources = views.into_iter().map(|demos| SourceDataset { demos, env_args: None }).collect();
    let generator = TwoArmGenerator::new(spec, sources).unwrap();
    let mut checked = 0;
    for index in 0..3 {
        let attempt = generator.attempt(&mut env, index).unwrap();
        let plan = |arm: usize, k: usize| attempt.arms[arm].plans.get(k);
        // Arm 1's wait runs in lockstep with arm 0's carry.
        if let (Some(carry), Some(wait)) = (plan(0, 3), plan(1, 2)) {
            assert_eq!((carry.first_step, carry.src_demo), (wait.first_step, wait.src_demo), "attempt {index}: carry and wait apart");
        }
        for (first, later) in [((0, 3), (1, 3)), ((1, 3), (0, 4)), ((0, 4), (1, 4))] {
            if let (Some(a), Some(b)) = (plan(first.0, first.1), plan(later.0, later.1)) {
                assert!(b.first_step >= a.first_step + a.waypoints.len(), "attempt {index}: {later:?} started before {first:?} ended");
                checked += 1;
            }
        }
    }
    assert!(checked >= 1, "no attempt got as far as a sequential tie");
}
