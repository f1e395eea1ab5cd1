//! Nut Assembly (robosuite's square and round nuts and pegs): the scene composes with both nuts
//! resting where robosuite drops them and the pegs stay put (its bundled demos are checked with the
//! other scripted tasks' in `paper_tasks.rs`).
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::sync::Arc;

use mimicgen_engine::Environment as _;
use mimicgen_sim::{Scene, SimEnv, Task, registry};
use rand::SeedableRng as _;

#[test]
fn the_nuts_rest_in_their_strips_and_the_pegs_stay_put() {
    let task: Arc<dyn Task> = registry::task("nut_assembly", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    assert_eq!(scene.objects.len(), 4);
    assert!(scene.objects[2].mocap.is_some() && scene.objects[3].mocap.is_some(), "pegs are fixed bodies");
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    env.reset(&mut rng).unwrap();
    for _ in 0..10 {
        env.step(&[0.0; 7]).unwrap();
    }
    let poses = env.object_poses();
    let (square, round) = (poses["square_nut"].translation.vector, poses["round_nut"].translation.vector);
    // Both nuts dropped onto the table (top at 0.82 m), square on the +y side, round on the -y side.
    assert!((square.z - 0.83).abs() < 0.003 && (round.z - 0.83).abs() < 0.003, "{square:?} {round:?}");
    assert!(square.y > 0.1 && round.y < -0.1);
    assert!((poses["round_peg"].translation.vector - nalgebra::Vector3::new(0.23, -0.1, 0.85)).norm() < 1e-12);
    assert!(!task.is_success(env.physics()));
    assert!(registry::task("nut_assembly", "D2").is_err());
    // D1: both nuts anywhere in front of the pegs, kept apart as robosuite's sampler keeps them:
    // by the sum of their horizontal radii (0.11 m each, the x of the horizontal_radius_site).
    let wide: Arc<dyn Task> = registry::task("nut_assembly", "D1").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for _ in 0..200 {
        let poses = wide.sample_scene(&mut rng, None).unwrap();
        assert!((poses[0].translation.vector - poses[1].translation.vector).xy().norm() > 0.22);
    }
}
