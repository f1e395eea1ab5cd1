#![allow(missing_docs)] // criterion_group! generates undocumented items
//! Engine hot paths: segment transform + interpolation, and source selection over many demos.
//!
//! `cargo bench -p mimicgen-engine --bench engine`

use std::collections::BTreeMap;
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use mimicgen_engine::pose::{Pose, Rot, Vec3, pose_from_parts};
use mimicgen_engine::segment::Span;
use mimicgen_engine::select::{SceneContext, select_source};
use mimicgen_engine::transform::{subtask_waypoints, transform_segment};
use mimicgen_engine::{Rows, SelectionStrategy, SourceDemo};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_pose(rng: &mut ChaCha8Rng) -> Pose {
    pose_from_parts(
        Vec3::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3), rng.random_range(0.8..1.2)),
        Rot::from_scaled_axis(Vec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0))),
    )
}

fn demo(rng: &mut ChaCha8Rng, steps: usize) -> SourceDemo {
    let eef: Vec<Pose> = (0..steps).map(|_| random_pose(rng)).collect();
    SourceDemo {
        name: "demo".into(),
        target_poses: eef.clone(),
        eef_poses: eef,
        gripper_actions: Rows::from_vec(1, vec![-1.0; steps], "gripper").unwrap_or_default(),
        object_poses: BTreeMap::from([("cube".to_owned(), (0..steps).map(|_| random_pose(rng)).collect())]),
        ..SourceDemo::default()
    }
}

fn transform_and_interpolate(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let segment: Vec<Pose> = (0..200).map(|_| random_pose(&mut rng)).collect();
    let gripper: Vec<Vec<f64>> = vec![vec![-1.0]; 200];
    let (obj_src, obj_new, start) = (random_pose(&mut rng), random_pose(&mut rng), random_pose(&mut rng));
    c.bench_function("transform+interpolate 200-step segment", |b| {
        b.iter(|| {
            let transformed = transform_segment(black_box(&obj_new), black_box(&obj_src), black_box(&segment));
            subtask_waypoints(&start, &transformed, &gripper, 5, 0, 0.05, 0.0)
        });
    });
}

fn selection(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for n in [10usize, 1000] {
        let demos: Vec<SourceDemo> = (0..n).map(|_| demo(&mut rng, 20)).collect();
        let spans: Vec<Vec<Span>> = demos.iter().map(|_| vec![(3, 20)]).collect();
        let (eef, obj) = (random_pose(&mut rng), random_pose(&mut rng));
        for strategy in [
            SelectionStrategy::NearestNeighborObject { nn_k: 3, pos_weight: 1.0, rot_weight: 1.0 },
            SelectionStrategy::NearestNeighborRobotDistance { nn_k: 3, pos_weight: 1.0, rot_weight: 1.0 },
        ] {
            let mut pick_rng = ChaCha8Rng::seed_from_u64(2);
            c.bench_function(&format!("select {} over {n} demos", strategy.name()), |b| {
                b.iter(|| {
                    let scene = SceneContext { world_from_eef: &eef, world_from_obj: Some(&obj) };
                    select_source(&strategy, black_box(&demos), &spans, 0, Some("cube"), scene, &mut pick_rng)
                });
            });
        }
    }
}

/// A whole attempt on the physics-free environment against stepping that environment the same
/// number of times with no engine around it: the engine's own cost per step.
fn attempt_overhead(c: &mut Criterion) {
    use mimicgen_engine::Environment as _;
    use mimicgen_engine::kinematic::{self, PickPlace};
    let generator =
        mimicgen_engine::Generator::new(kinematic::pick_place_spec(1, 1), kinematic::scripted_dataset(10, 1).unwrap_or_default())
            .unwrap_or_else(|e| panic!("{e}"));
    let mut env = PickPlace::new(0.08);
    let steps = generator.attempt(&mut env, 0).map(|a| a.trajectory.len()).unwrap_or(0);
    c.bench_function(&format!("kinematic attempt ({steps} steps)"), |b| b.iter(|| generator.attempt(&mut env, black_box(0))));
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    c.bench_function(&format!("kinematic bare stepping ({steps} steps)"), |b| {
        b.iter(|| {
            let _ = env.reset(&mut rng);
            for _ in 0..steps {
                let _ = env.step(black_box(&[0.1, 0.0, -0.1, 0.0, 0.0, 0.05, -1.0]));
            }
        });
    });
}

criterion_group!(benches, transform_and_interpolate, selection, attempt_overhead);
criterion_main!(benches);
