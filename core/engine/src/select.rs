//! Choosing the source demo for a subtask (paper appendix "Reference Segment Selection").

use rand::Rng;

use crate::demo::SourceDemo;
use crate::pose::{Pose, pose_distance};
use crate::segment::Span;
use crate::spec::SelectionStrategy;

/// What the selection may look at in the new scene.
#[derive(Debug, Clone, Copy)]
pub struct SceneContext<'a> {
    /// Current `world_from_eef`.
    pub world_from_eef: &'a Pose,
    /// Current `world_from_object` of the subtask's reference object, if it has one.
    pub world_from_obj: Option<&'a Pose>,
}

/// How far each source demo's segment for `subtask` is from the new scene, as the strategy
/// measures it (`None` for [`SelectionStrategy::Random`], which measures nothing). `spans[d][subtask]`
/// is demo `d`'s segment this attempt and `object` the subtask's reference object; a demo without
/// that object is infinitely far.
#[must_use]
pub fn source_distances(
    strategy: &SelectionStrategy,
    demos: &[SourceDemo],
    spans: &[Vec<Span>],
    subtask: usize,
    object: Option<&str>,
    scene: SceneContext<'_>,
) -> Option<Vec<f64>> {
    // Where demo d's segment starts this attempt (None for a demo or subtask `spans` lacks).
    let start = |d: usize| spans.get(d).and_then(|s| s.get(subtask)).map(|&(start, _)| start);
    let src_object_pose = |d: usize| demos.get(d)?.object_poses.get(object?)?.get(start(d)?).copied();
    match strategy {
        SelectionStrategy::Random => None,
        SelectionStrategy::NearestNeighborObject { .. } => {
            let world_from_obj = scene.world_from_obj?;
            Some(
                (0..demos.len())
                    .map(|d| src_object_pose(d).map_or(f64::INFINITY, |src| pose_distance(world_from_obj, &src, strategy.weights())))
                    .collect(),
            )
        }
        SelectionStrategy::NearestNeighborRobotDistance { .. } => Some(
            (0..demos.len())
                .map(|d| {
                    let Some(&world_from_eef_src) = demos.get(d).zip(start(d)).and_then(|(demo, t)| demo.eef_poses.get(t)) else {
                        return f64::INFINITY;
                    };
                    let start = match (scene.world_from_obj, src_object_pose(d)) {
                        (Some(world_from_obj_new), Some(world_from_obj_src)) => {
                            world_from_obj_new * world_from_obj_src.inverse() * world_from_eef_src
                        }
                        _ => world_from_eef_src,
                    };
                    pose_distance(scene.world_from_eef, &start, strategy.weights())
                })
                .collect(),
        ),
    }
}

/// Picks a demo index given the strategy's [`source_distances`] (uniformly among the `nn_k`
/// nearest, ties in dataset order; uniformly among all demos without distances), never one of
/// `excluded`, so the choice depends only on the inputs and `rng`. With nothing excluded it draws
/// as it always has; with every demo excluded it picks the first (the generator refuses such a
/// spec before).
pub fn pick_source<R: Rng + ?Sized>(
    strategy: &SelectionStrategy,
    distances: Option<&[f64]>,
    num_demos: usize,
    excluded: &[usize],
    rng: &mut R,
) -> usize {
    let allowed: Vec<usize> = (0..num_demos).filter(|d| !excluded.contains(d)).collect();
    if allowed.is_empty() {
        return 0;
    }
    match distances {
        Some(distances) => nearest_k_pick(distances, &allowed, strategy_k(strategy), rng),
        None => allowed.get(rng.random_range(0..allowed.len())).copied().unwrap_or(0),
    }
}

/// Picks a demo index for `subtask`: [`source_distances`] then [`pick_source`].
pub fn select_source<R: Rng + ?Sized>(
    strategy: &SelectionStrategy,
    demos: &[SourceDemo],
    spans: &[Vec<Span>],
    subtask: usize,
    object: Option<&str>,
    scene: SceneContext<'_>,
    rng: &mut R,
) -> usize {
    let distances = source_distances(strategy, demos, spans, subtask, object, scene);
    pick_source(strategy, distances.as_deref(), demos.len(), &[], rng)
}

fn strategy_k(strategy: &SelectionStrategy) -> usize {
    match strategy {
        SelectionStrategy::Random => usize::MAX,
        SelectionStrategy::NearestNeighborObject { nn_k, .. } | SelectionStrategy::NearestNeighborRobotDistance { nn_k, .. } => *nn_k,
    }
}

/// Uniform pick among the `k` smallest distances of the `allowed` demos (ties broken by index).
fn nearest_k_pick<R: Rng + ?Sized>(distances: &[f64], allowed: &[usize], k: usize, rng: &mut R) -> usize {
    let mut order: Vec<(usize, f64)> = distances.iter().copied().enumerate().filter(|(d, _)| allowed.contains(d)).collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let k = k.min(order.len()).max(1);
    order.get(rng.random_range(0..k)).map_or(0, |&(d, _)| d)
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::pose::{Vec3, pose_from_parts};
    use crate::testing::demo_with_object_at;

    #[test]
    fn nearest_neighbour_draws_only_from_the_k_closest() {
        let xs = [0.5, 0.0, 0.31, 0.1, 0.9, 0.2];
        let demos: Vec<SourceDemo> = xs.iter().map(|&x| demo_with_object_at("cube", x)).collect();
        let spans: Vec<Vec<Span>> = demos.iter().map(|d| vec![(0, d.len())]).collect();
        let strategy = SelectionStrategy::NearestNeighborObject { nn_k: 3, pos_weight: 1.0, rot_weight: 1.0 };
        let here = pose_from_parts(Vec3::new(0.12, 0.0, 0.0), crate::pose::Rot::identity());
        let eef = Pose::identity();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..300 {
            let scene = SceneContext { world_from_eef: &eef, world_from_obj: Some(&here) };
            seen.insert(select_source(&strategy, &demos, &spans, 0, Some("cube"), scene, &mut rng));
        }
        // Closest to 0.12: 0.1 (d3), 0.2 (d5), 0.0 (d1).
        assert_eq!(seen.into_iter().collect::<Vec<_>>(), vec![1, 3, 5]);
    }

    #[test]
    fn an_excluded_demo_is_never_picked_and_nothing_excluded_draws_as_before() {
        let strategy = SelectionStrategy::NearestNeighborObject { nn_k: 2, pos_weight: 1.0, rot_weight: 1.0 };
        // Demo 1 is the nearest: excluded, the two nearest left are 3 and 0.
        let distances = [0.2, 0.0, 0.9, 0.1];
        let (mut a, mut b) = (ChaCha8Rng::seed_from_u64(5), ChaCha8Rng::seed_from_u64(5));
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..200 {
            seen.insert(pick_source(&strategy, Some(&distances), 4, &[1], &mut a));
        }
        assert_eq!(seen.into_iter().collect::<Vec<_>>(), vec![0, 3]);
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..200 {
            seen.insert(pick_source(&SelectionStrategy::Random, None, 4, &[0, 2], &mut b));
        }
        assert_eq!(seen.into_iter().collect::<Vec<_>>(), vec![1, 3]);
        // Without exclusions the picks are the draws of the unfiltered rule.
        let (mut c, mut d) = (ChaCha8Rng::seed_from_u64(9), ChaCha8Rng::seed_from_u64(9));
        for _ in 0..50 {
            assert_eq!(pick_source(&SelectionStrategy::Random, None, 7, &[], &mut c), d.random_range(0..7));
        }
    }

    #[test]
    fn nn_k_larger_than_the_dataset_is_random() {
        let demos: Vec<SourceDemo> = [0.0, 0.1].iter().map(|&x| demo_with_object_at("cube", x)).collect();
        let spans: Vec<Vec<Span>> = demos.iter().map(|d| vec![(0, d.len())]).collect();
        let strategy = SelectionStrategy::NearestNeighborObject { nn_k: 10, pos_weight: 1.0, rot_weight: 1.0 };
        let eef = Pose::identity();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let picks: Vec<usize> = (0..50)
            .map(|_| {
                select_source(
                    &strategy,
                    &demos,
                    &spans,
                    0,
                    Some("cube"),
                    SceneContext { world_from_eef: &eef, world_from_obj: Some(&eef) },
                    &mut rng,
                )
            })
            .collect();
        assert!(picks.contains(&0) && picks.contains(&1));
    }

    #[test]
    fn robot_distance_prefers_the_shortest_travel() {
        // Each demo starts 0.1 m above its cube; in the new scene the cube is at the origin, so every
        // transformed start is the same except for the demo whose eef started further away.
        let mut demos: Vec<SourceDemo> = [0.0, 0.3, 0.6].iter().map(|&x| demo_with_object_at("cube", x)).collect();
        for d in &mut demos {
            let cube = d.object_poses["cube"][0];
            d.eef_poses[0] = cube * pose_from_parts(Vec3::new(0.0, 0.0, 0.1), crate::pose::Rot::identity());
        }
        demos[1].eef_poses[0] = demos[1].object_poses["cube"][0] * pose_from_parts(Vec3::new(0.0, 0.0, 0.02), crate::pose::Rot::identity());
        let spans: Vec<Vec<Span>> = demos.iter().map(|d| vec![(0, d.len())]).collect();
        let strategy = SelectionStrategy::NearestNeighborRobotDistance { nn_k: 1, pos_weight: 1.0, rot_weight: 1.0 };
        let eef = pose_from_parts(Vec3::new(0.0, 0.0, 0.0), crate::pose::Rot::identity());
        let obj = Pose::identity();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let pick = select_source(
            &strategy,
            &demos,
            &spans,
            0,
            Some("cube"),
            SceneContext { world_from_eef: &eef, world_from_obj: Some(&obj) },
            &mut rng,
        );
        assert_eq!(pick, 1);
    }
}
