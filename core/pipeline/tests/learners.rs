//! What learners take from us: absolute actions beside the delta ones, and our simulator as an
//! environment their policies act in.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::sync::atomic::AtomicBool;

use mimicgen_io::RobomimicDataset;
use mimicgen_pipeline::replay::{ReplayMode, replay};
use mimicgen_pipeline::{ActionForm, Pipeline, PolicyEnv, RunConfig};

fn values(demo: &mimicgen_io::tree::Group, key: &str) -> (Vec<usize>, Vec<f64>) {
    let d = demo.dataset_at(key).unwrap_or_else(|| panic!("no {key}"));
    (d.array.shape.clone(), d.array.values.to_f64().unwrap())
}

#[test]
fn absolute_and_joint_actions_replay_to_the_same_outcome() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("stack_d1.hdf5");
    let config = RunConfig {
        task: Some("stack".into()),
        variant: Some("D1".into()),
        num_demos: Some(3),
        guarantee: true,
        seed: Some(2),
        out: out.clone(),
        actions: vec![ActionForm::Abs, ActionForm::Joint],
        ..RunConfig::default()
    };
    let report = Pipeline::prepare(&config).unwrap().run(&AtomicBool::new(false), |_| {}).unwrap();
    assert_eq!(report.successes, 3);
    let dataset = RobomimicDataset::open(&out).unwrap();
    for name in dataset.demo_names() {
        let demo = dataset.demo(name).unwrap();
        let (shape, actions) = values(demo, "actions");
        let (abs_shape, abs) = values(demo, "actions_abs");
        assert_eq!(abs_shape, shape, "{name}: one absolute action per action, as wide");
        let (_, eef) = values(demo, "datagen_info/eef_pose");
        for (t, (row, a)) in abs.chunks(7).zip(actions.chunks(7)).enumerate() {
            // The gripper is copied; the position is the end effector's plus the clipped delta
            // scaled by the controller's 5 cm (robosuite's OSC_POSE output_max).
            assert_eq!(row[6].to_bits(), a[6].to_bits(), "{name} step {t}: the gripper, copied");
            for k in 0..3 {
                let want = eef[t * 16 + k * 4 + 3] + 0.05 * a[k].clamp(-1.0, 1.0);
                assert!((row[k] - want).abs() < 1e-9, "{name} step {t} axis {k}: {} vs {want}", row[k]);
            }
        }
    }
    for name in dataset.demo_names() {
        // The Panda's seven joints at the next step, then the gripper, copied.
        let demo = dataset.demo(name).unwrap();
        let (shape, joint) = values(demo, "actions_joint");
        let (_, actions) = values(demo, "actions");
        let (_, qpos) = values(demo, "obs/robot0_joint_pos");
        assert_eq!(shape[1], 8, "{name}: seven joint targets and the gripper");
        for (t, row) in joint.chunks(8).enumerate().take(shape[0] - 1) {
            assert_eq!(row[7].to_bits(), actions[t * 7 + 6].to_bits(), "{name} step {t}: the gripper, copied");
            assert!((0..7).all(|j| (row[j] - qpos[(t + 1) * 7 + j]).abs() < 1e-12), "{name} step {t}: the next step's joints");
        }
    }
    let delta = replay(&out, &[], ReplayMode::Actions, None, |_, _, _| {}).unwrap();
    let absolute = replay(&out, &[], ReplayMode::ActionsAbs, None, |_, _, _| {}).unwrap();
    let joint = replay(&out, &[], ReplayMode::ActionsJoint, None, |_, _, _| {}).unwrap();
    let apart = |a: [f64; 7], b: [f64; 7]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    for ((d, a), j) in delta.iter().zip(&absolute).zip(&joint) {
        assert!(d.success && a.success && j.success, "{}: every form replays to success", d.demo);
        let end = |t: &mimicgen_pipeline::replay::DemoTrace| t.steps.last().unwrap().eef;
        assert!(apart(end(d), end(a)) < 1e-4, "{}: the delta and absolute replays end {} m apart", d.demo, apart(end(d), end(a)));
        // Joint targets retrace the recorded motion under another controller: close, not exact.
        let worst = d.steps.iter().zip(&j.steps).map(|(x, y)| apart(x.eef, y.eef)).fold(0.0, f64::max);
        assert!(worst < 0.01, "{}: the joint replay's hand strays {worst} m from the delta replay's", d.demo);
    }
    // Without the form, a replay from it names the field.
    let plain = dir.path().join("plain.hdf5");
    let config = RunConfig { out: plain.clone(), actions: Vec::new(), num_demos: Some(1), guarantee: false, ..config };
    Pipeline::prepare(&config).unwrap().run(&AtomicBool::new(false), |_| {}).unwrap();
    if RobomimicDataset::open(&plain).unwrap().demo_names().is_empty() {
        return; // the one attempt failed: nothing to replay
    }
    let err = replay(&plain, &[], ReplayMode::ActionsAbs, None, |_, _, _| {}).unwrap_err().to_string();
    assert!(err.contains("actions_abs"), "{err}");
}

#[test]
fn a_policy_env_draws_seeded_scenes_and_refuses_bad_actions() {
    let config = RunConfig { task: Some("square".into()), variant: Some("D1".into()), ..RunConfig::default() };
    let scenes = |seed| {
        let mut env = PolicyEnv::new(&config, seed).unwrap();
        (0..3)
            .map(|_| {
                env.reset().unwrap();
                env.observation()["object"].clone()
            })
            .collect::<Vec<_>>()
    };
    let (a, b, c) = (scenes(4), scenes(4), scenes(5));
    assert_eq!(a, b, "the same seed, the same scenes");
    assert_ne!(a[0], c[0]);
    assert_ne!(a[0], a[1], "every reset draws a new scene");

    let mut env = PolicyEnv::new(&config, 4).unwrap();
    env.reset().unwrap();
    assert_eq!(env.action_dim(), 7);
    let err = env.step(&[0.0; 6]).unwrap_err().to_string();
    assert!(err.contains("action: has 6 values; square D1 takes 7"), "{err}");
    let err = env.step(&[0.0, 0.0, f64::INFINITY, 0.0, 0.0, 0.0, 0.0]).unwrap_err().to_string();
    assert!(err.contains("action[2]: is inf"), "{err}");
    let err = env.reset_to(&[0.0; 3]).unwrap_err().to_string();
    assert!(err.starts_with("state: "), "{err}");
    // A state restored is the state read back.
    let state = env.state();
    env.step(&[0.0, 0.0, 0.5, 0.0, 0.0, 0.0, -1.0]).unwrap();
    env.reset_to(&state).unwrap();
    assert_eq!(env.state(), state);
    let err = PolicyEnv::new(&RunConfig { task: Some("two_arm_lift".into()), ..RunConfig::default() }, 0).unwrap_err().to_string();
    assert!(err.contains("two-arm"), "{err}");
}
