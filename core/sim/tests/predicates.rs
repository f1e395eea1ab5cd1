//! The task-file predicates a bundled task does not use yet, checked in a real scene: Stack's file
//! with extra signals, evaluated as the cubes are put in known places.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::sync::Arc;

use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};
use mimicgen_sim::{DataTask, Scene, SimEnv, Task, TaskFile};
use rand::SeedableRng as _;

const SIGNALS: &str = r#"[signals]
grasp = { grasped = "cubeA" }
aligned = { aligned = { object = "cubeA", with = "cubeB", tolerance_deg = 5.0, symmetry_deg = 90.0 } }
at_rest = { at_rest = { object = "cubeA", max_speed_m_s = 0.01 } }
apart = { apart = { object = "cubeA", from = "cubeB", min_m = 0.1 } }
near = { near = { object = "cubeA", point_m = [0.0, 0.0, -0.02], of = "cubeB", of_point_m = [0.0, 0.0, 0.025], within_m = 0.005 } }
on_top = { inside = { object = "cubeA", of = "cubeB", xy_m = 0.01, dz_m = [0.04, 0.05] } }
either = { any = [{ lifted = { object = "cubeA", above_m = 0.5 } }, { contact = ["cubeA", "cubeB"] }] }
in_row = { inside = { object = "cubeA", of = "cubeB", xy_m = [0.2, 0.01] } }
was_stacked = { ever = { contact = ["cubeA", "cubeB"] } }
"#;

fn task() -> Arc<dyn Task> {
    let stack = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks/stack.task.toml")).unwrap();
    let text = stack.replace("[signals]\ngrasp = { grasped = \"cubeA\" }\n", SIGNALS);
    assert_ne!(text, stack);
    Arc::new(DataTask::new(TaskFile::from_toml_str(&text, "predicates").unwrap(), "D0").unwrap())
}

#[test]
fn predicates_read_the_scene() {
    let task = task();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(scene, Arc::clone(&task));
    mimicgen_engine::Environment::reset(&mut env, &mut rand_chacha::ChaCha8Rng::seed_from_u64(1)).unwrap();
    let settle = |env: &mut SimEnv, steps: usize| {
        for _ in 0..steps {
            mimicgen_engine::Environment::step(env, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]).unwrap();
        }
    };
    let yaw = |deg: f64| Rot::from_axis_angle(&Vec3::z_axis(), deg.to_radians());
    // Apart on the table, turned 93 deg to each other (aligned modulo 90 within 5 deg).
    env.place_object(1, &pose_from_parts(Vec3::new(0.05, 0.0, 0.825), yaw(10.0)));
    env.place_object(0, &pose_from_parts(Vec3::new(-0.1, 0.0, 0.82), yaw(103.0)));
    settle(&mut env, 10);
    let s = task.signals(env.physics());
    assert_eq!((s["aligned"], s["at_rest"], s["apart"], s["near"], s["on_top"], s["either"]), (1, 1, 1, 0, 0, 0), "{s:?}");
    // 15 cm apart along x, level in y: inside a bound of [0.2, 0.01]; never touched yet.
    assert_eq!((s["in_row"], s["was_stacked"]), (1, 0), "{s:?}");
    // Stacked, turned 20 deg: near and on top, touching, not aligned.
    env.place_object(0, &pose_from_parts(Vec3::new(0.05, 0.0, 0.8705), yaw(30.0)));
    settle(&mut env, 10);
    let s = task.signals(env.physics());
    assert_eq!((s["aligned"], s["apart"], s["near"], s["on_top"], s["either"], s["was_stacked"]), (0, 0, 1, 1, 1, 1), "{s:?}");
    // Dropped from 10 cm: moving, not at rest; 10 cm off in y, out of the row; they touched once.
    env.place_object(0, &pose_from_parts(Vec3::new(-0.1, 0.1, 0.92), yaw(0.0)));
    settle(&mut env, 2);
    let s = task.signals(env.physics());
    assert_eq!((s["at_rest"], s["either"], s["in_row"], s["was_stacked"]), (0, 0, 0, 1), "{s:?}");
    // A reset forgets the episode's history.
    mimicgen_engine::Environment::reset(&mut env, &mut rand_chacha::ChaCha8Rng::seed_from_u64(2)).unwrap();
    assert_eq!(task.signals(env.physics())["was_stacked"], 0);
}

#[test]
fn a_joint_the_scene_lacks_is_refused_naming_the_field() {
    // Stack's scene has no lid: a signal reading `lid_hinge` is an error when the scene is built,
    // not a signal that silently never turns on.
    let stack = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks/stack.task.toml")).unwrap();
    let text = stack.replace("[signals]\n", "[signals]\nlid_open = { joint = { joint = \"lid_hinge\", min = 30.0 } }\n");
    let task = DataTask::new(TaskFile::from_toml_str(&text, "stack").unwrap(), "D0").unwrap();
    let err = Scene::for_task(&task).unwrap_err().to_string();
    assert!(err.contains("signals.lid_open") && err.contains("\"lid_hinge\"") && err.contains("stack.task.toml"), "{err}");
}
