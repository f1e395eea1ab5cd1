//! A physics-free pick-and-place environment with a scripted demonstrator.
//!
//! The end-effector reaches every commanded target exactly (delta-pose actions as in
//! robosuite's OSC_POSE); closing the gripper near `cubeA` grasps it, after which it follows the
//! gripper rigidly; opening releases it onto `cubeB` if it is above it, else onto the table. The
//! task succeeds when `cubeA` rests on `cubeB`. Success is therefore exact, which lets tests check
//! the generation loop (rates, attribution, determinism) without a simulator. It is a reference
//! for tests, benchmarks and docs: real generation runs on the MuJoCo backend.
#![allow(
    clippy::indexing_slicing,
    reason = "states and actions are checked for length where they come in (set_state, step); configurations are \
              the 4 numbers of its own configuration space"
)]

use std::collections::BTreeMap;

use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::EngineError;
use crate::action::DeltaPoseScale;
use crate::demo::SourceDataset;
use crate::demonstrator::PickPlaceScript;
use crate::env::{EnvError, Environment};
use crate::pose::{Pose, Rot, Vec3, pose_from_parts, quat_from_wxyz, quat_to_wxyz};
use crate::spec::{GenerationSettings, SelectionStrategy, SubtaskSpec, TaskSpec};
use crate::transit::TransitSpace;

/// Half the edge of both cubes (m).
pub const CUBE_HALF_M: f64 = 0.02;
/// Height of the table top (m).
pub const TABLE_Z_M: f64 = 0.8;
/// How close (m) the grip point must be to `cubeA`'s centre for a grasp.
pub const GRASP_TOLERANCE_M: f64 = 0.012;
/// How far off-centre (m, horizontally) `cubeA` may be released and still land on `cubeB`.
pub const PLACE_TOLERANCE_M: f64 = 0.02;

const STATE_DIM: usize = 30;

/// The kinematic pick-and-place environment.
#[derive(Debug, Clone)]
pub struct PickPlace {
    scale: DeltaPoseScale,
    half_range_m: f64,
    world_from_eef: Pose,
    gripper_closed: bool,
    cube_a: Pose,
    cube_b: Pose,
    eef_from_held: Option<Pose>,
    /// A vertical post between the cubes, drawn per episode ([`PickPlace::with_post`]).
    post: Option<Post>,
}

/// A vertical post of radius `radius_m` rising from the table to `top_z`, at `(x, y)`; touching it
/// spoils the attempt (the task then fails).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Post {
    radius_m: f64,
    top_z: f64,
    x: f64,
    y: f64,
    touched: bool,
}

/// Radius (m) of the sphere round the grip point, and round a held cube, that must miss the post.
const GRIPPER_RADIUS_M: f64 = 0.01;
const HELD_RADIUS_M: f64 = CUBE_HALF_M * 1.732_050_807_568_877_2;

impl PickPlace {
    /// An environment that samples both cubes in a square of half-width `half_range_m` around the
    /// origin (e.g. 0.08 for a 0.16 m square).
    #[must_use]
    pub fn new(half_range_m: f64) -> Self {
        Self {
            scale: DeltaPoseScale::default(),
            half_range_m,
            world_from_eef: home_pose(),
            gripper_closed: false,
            cube_a: Pose::identity(),
            cube_b: Pose::identity(),
            eef_from_held: None,
            post: None,
        }
    }

    /// The same environment with a post of radius `radius_m` standing on the table up to
    /// `height_m` above it, half-way between the cubes at every reset (cubes are then drawn at
    /// least 0.2 m apart). Carrying the red cube straight over a tall post hits it; a planned
    /// transit goes round.
    #[must_use]
    pub fn with_post(mut self, radius_m: f64, height_m: f64) -> Self {
        self.post = Some(Post { radius_m, top_z: TABLE_Z_M + height_m, x: 0.0, y: 0.0, touched: false });
        self
    }

    /// Whether a sphere of `radius` at `point` overlaps the post.
    fn hits_post(&self, point: &Vec3, radius: f64) -> bool {
        self.post
            .is_some_and(|p| point.z - radius < p.top_z && (point.xy() - nalgebra::Vector2::new(p.x, p.y)).norm() < p.radius_m + radius)
    }

    /// Whether the gripper at `world_from_eef`, and the cube it holds, overlap the post.
    fn collides_at(&self, world_from_eef: &Pose) -> bool {
        self.hits_post(&world_from_eef.translation.vector, GRIPPER_RADIUS_M)
            || self.eef_from_held.is_some_and(|held| self.hits_post(&(world_from_eef * held).translation.vector, HELD_RADIUS_M))
    }

    fn release(&mut self) {
        self.eef_from_held = None;
        let offset = self.cube_a.translation.vector - self.cube_b.translation.vector;
        let above_b = offset.xy().norm() < PLACE_TOLERANCE_M && offset.z > 2.0 * CUBE_HALF_M - 0.015 && offset.z < 2.0 * CUBE_HALF_M + 0.05;
        let z = if above_b { self.cube_b.translation.z + 2.0 * CUBE_HALF_M } else { TABLE_Z_M + CUBE_HALF_M };
        self.cube_a.translation.z = z;
    }
}

fn home_pose() -> Pose {
    // Gripper pointing down, as a Panda at its home posture.
    pose_from_parts(Vec3::new(-0.1, 0.0, 1.0), Rot::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI))
}

fn cube_at(x: f64, y: f64, yaw: f64) -> Pose {
    pose_from_parts(Vec3::new(x, y, TABLE_Z_M + CUBE_HALF_M), Rot::from_axis_angle(&Vec3::z_axis(), yaw))
}

fn push_pose(state: &mut Vec<f64>, pose: &Pose) {
    state.extend(pose.translation.vector.iter());
    state.extend(quat_to_wxyz(&pose.rotation));
}

fn read_pose(v: &[f64]) -> Pose {
    pose_from_parts(Vec3::new(v[0], v[1], v[2]), quat_from_wxyz([v[3], v[4], v[5], v[6]]))
}

impl Environment for PickPlace {
    fn reset(&mut self, rng: &mut dyn RngCore) -> Result<(), EnvError> {
        let r = self.half_range_m;
        let sample = |rng: &mut dyn RngCore| {
            cube_at(rng.random_range(-r..=r), rng.random_range(-r..=r), rng.random_range(-std::f64::consts::PI..std::f64::consts::PI))
        };
        self.cube_a = sample(rng);
        // Rejection-sample cubeB so the cubes never interpenetrate (a generous 3 half-edges apart).
        for _ in 0..1000 {
            self.cube_b = sample(rng);
            let apart = (self.cube_b.translation.vector - self.cube_a.translation.vector).xy().norm();
            let needed = if self.post.is_some() { 0.2 } else { 3.0 * CUBE_HALF_M * std::f64::consts::SQRT_2 };
            if apart > needed {
                if let Some(post) = &mut self.post {
                    let mid = (self.cube_a.translation.vector + self.cube_b.translation.vector) / 2.0;
                    (post.x, post.y, post.touched) = (mid.x, mid.y, false);
                }
                self.world_from_eef = home_pose();
                self.gripper_closed = false;
                self.eef_from_held = None;
                return Ok(());
            }
        }
        Err(EnvError::Fatal { reason: format!("cannot place two cubes apart in a square of half-width {r} m") })
    }

    fn eef_pose(&self) -> Pose {
        self.world_from_eef
    }

    fn object_poses(&self) -> BTreeMap<String, Pose> {
        BTreeMap::from([("cubeA".to_owned(), self.cube_a), ("cubeB".to_owned(), self.cube_b)])
    }

    fn subtask_term_signals(&self) -> BTreeMap<String, i64> {
        BTreeMap::from([("grasp".to_owned(), i64::from(self.eef_from_held.is_some()))])
    }

    fn place_objects(&mut self, world_from_objects: &BTreeMap<String, Pose>) -> Result<(), EnvError> {
        for (name, pose) in world_from_objects {
            match name.as_str() {
                "cubeA" => self.cube_a = *pose,
                "cubeB" => self.cube_b = *pose,
                _ => return Err(EnvError::Fatal { reason: format!("no object {name:?} (the scene has cubeA, cubeB)") }),
            }
        }
        Ok(())
    }

    fn is_success(&self) -> bool {
        let offset = self.cube_a.translation.vector - self.cube_b.translation.vector;
        self.eef_from_held.is_none()
            && offset.xy().norm() < PLACE_TOLERANCE_M
            && (offset.z - 2.0 * CUBE_HALF_M).abs() < 1e-6
            && !self.post.is_some_and(|p| p.touched)
    }

    fn obstacle_contacts(&self) -> usize {
        usize::from(self.collides_at(&self.world_from_eef))
    }

    fn transit_space(&mut self) -> Result<Box<dyn TransitSpace + '_>, EnvError> {
        Ok(Box::new(FreeGripper { env: self }))
    }

    fn target_pose_to_action(&self, world_from_target: &Pose) -> [f64; 6] {
        self.scale.action_from_target(&self.world_from_eef, world_from_target)
    }

    fn action_to_target_pose(&self, action: &[f64]) -> Pose {
        let mut pose_action = [0.0; 6];
        for (a, v) in pose_action.iter_mut().zip(action) {
            *a = *v;
        }
        self.scale.target_from_action(&self.world_from_eef, &pose_action)
    }

    fn action_dim(&self) -> usize {
        7
    }

    fn step(&mut self, action: &[f64]) -> Result<(), EnvError> {
        if action.len() != 7 || action.iter().any(|a| !a.is_finite()) {
            return Err(EnvError::Unstable { reason: format!("action {action:?} is not 7 finite numbers") });
        }
        let from = self.world_from_eef;
        self.world_from_eef = self.action_to_target_pose(action);
        // The motion is checked at 1 cm spacing, so a fast step cannot jump the post.
        let travel = (self.world_from_eef.translation.vector - from.translation.vector).norm();
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // a small positive count
        let checks = (travel / 0.01).ceil().max(1.0) as usize;
        for k in 1..=checks {
            #[allow(clippy::cast_precision_loss)] // a small count
            let p = from.translation.vector.lerp(&self.world_from_eef.translation.vector, k as f64 / checks as f64);
            if self.collides_at(&pose_from_parts(p, self.world_from_eef.rotation))
                && let Some(post) = &mut self.post
            {
                post.touched = true;
            }
        }
        let close = action[6] > 0.0;
        if close
            && !self.gripper_closed
            && (self.world_from_eef.translation.vector - self.cube_a.translation.vector).norm() < GRASP_TOLERANCE_M
        {
            self.eef_from_held = Some(self.world_from_eef.inverse() * self.cube_a);
        }
        if !close && self.eef_from_held.is_some() {
            self.release();
        }
        self.gripper_closed = close;
        if let Some(eef_from_held) = self.eef_from_held {
            self.cube_a = self.world_from_eef * eef_from_held;
        }
        Ok(())
    }

    fn state(&self) -> Vec<f64> {
        let mut s = Vec::with_capacity(STATE_DIM);
        push_pose(&mut s, &self.world_from_eef);
        s.push(f64::from(u8::from(self.gripper_closed)));
        push_pose(&mut s, &self.cube_a);
        push_pose(&mut s, &self.cube_b);
        s.push(f64::from(u8::from(self.eef_from_held.is_some())));
        push_pose(&mut s, &self.eef_from_held.unwrap_or_else(Pose::identity));
        s
    }

    fn set_state(&mut self, state: &[f64]) -> Result<(), EnvError> {
        if state.len() != STATE_DIM {
            return Err(EnvError::Fatal { reason: format!("state has {} values, expected {STATE_DIM}", state.len()) });
        }
        self.world_from_eef = read_pose(&state[0..7]);
        self.gripper_closed = state[7] > 0.5;
        self.cube_a = read_pose(&state[8..15]);
        self.cube_b = read_pose(&state[15..22]);
        self.eef_from_held = (state[22] > 0.5).then(|| read_pose(&state[23..30]));
        Ok(())
    }
}

/// The kinematic environment's configuration space: the grip point's position and the gripper's
/// yaw (it always points down), limited to the space above the table.
struct FreeGripper<'a> {
    env: &'a PickPlace,
}

impl FreeGripper<'_> {
    fn pose(q: &[f64]) -> Pose {
        let down = Rot::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI);
        pose_from_parts(Vec3::new(q[0], q[1], q[2]), Rot::from_axis_angle(&Vec3::z_axis(), q[3]) * down)
    }

    fn yaw(pose: &Pose) -> f64 {
        let x = pose.rotation * Vec3::x();
        x.y.atan2(x.x)
    }
}

impl TransitSpace for FreeGripper<'_> {
    fn joint_limits(&self) -> Vec<[f64; 2]> {
        vec![[-0.4, 0.4], [-0.4, 0.4], [TABLE_Z_M + 0.01, TABLE_Z_M + 0.5], [-2.0 * std::f64::consts::PI, 2.0 * std::f64::consts::PI]]
    }

    fn joints(&self) -> Vec<f64> {
        let t = self.env.world_from_eef.translation.vector;
        vec![t.x, t.y, t.z, Self::yaw(&self.env.world_from_eef)]
    }

    fn is_free(&mut self, q: &[f64]) -> bool {
        !self.env.collides_at(&Self::pose(q))
    }

    fn eef_pose_at(&mut self, q: &[f64]) -> Pose {
        Self::pose(q)
    }

    fn inverse_kinematics(&mut self, world_from_eef: &Pose, seed: &[f64]) -> Option<Vec<f64>> {
        let t = world_from_eef.translation.vector;
        // The yaw nearest the seed's, of the two turns the limits allow.
        let yaw = Self::yaw(world_from_eef);
        let turn = 2.0 * std::f64::consts::PI;
        let yaw = yaw + turn * ((seed.get(3).copied().unwrap_or(0.0) - yaw) / turn).round();
        Some(vec![t.x, t.y, t.z, yaw])
    }
}

/// The scripted demonstrator's settings for this environment.
#[must_use]
pub fn pick_place_script() -> PickPlaceScript {
    PickPlaceScript {
        pick: "cubeA".to_owned(),
        place_on: "cubeB".to_owned(),
        grasp_height_m: 0.0,
        release_height_m: 2.0 * CUBE_HALF_M + 0.002,
        close_steps: (2, 4),
        open_steps: (2, 3),
        lift_height_m: (0.08, 0.14),
        ..PickPlaceScript::default()
    }
}

/// `n` scripted demos in scenes drawn from a 0.16 m square (D0-like), keeping only successful ones.
///
/// # Errors
/// [`EngineError::Env`] if the environment fails, or if 10 n tries give fewer than n successes.
pub fn scripted_dataset(n: usize, seed: u64) -> Result<SourceDataset, EngineError> {
    let mut env = PickPlace::new(0.08);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut demos = Vec::with_capacity(n);
    let script = pick_place_script();
    for attempt in 0..10 * n.max(1) {
        if demos.len() == n {
            break;
        }
        let fail = |source| EngineError::Env { attempt: attempt as u64, source };
        env.reset(&mut rng).map_err(fail)?;
        let demo = script.record(&mut env, &format!("demo_{}", demos.len()), &mut rng).map_err(fail)?;
        if env.is_success() {
            demos.push(demo);
        }
    }
    if demos.len() < n {
        return Err(EngineError::Env {
            attempt: 0,
            source: EnvError::Fatal { reason: format!("scripted demonstrator succeeded {} times in {} tries", demos.len(), 10 * n) },
        });
    }
    Ok(SourceDataset { demos, env_args: None })
}

/// The paper's Stack settings for this environment: grasp `cubeA` (ends on `grasp`, offsets
/// 10-20), place on `cubeB`; nearest-neighbour selection with nn_k 3 per subtask, noise 0.05,
/// 5 interpolation steps.
#[must_use]
pub fn pick_place_spec(num_trials: usize, seed: u64) -> TaskSpec {
    let subtask = |object: &str, signal: Option<&str>, offsets| SubtaskSpec {
        object_ref: Some(object.to_owned()),
        term_signal: signal.map(str::to_owned),
        term_offset_range: offsets,
        selection: SelectionStrategy::NearestNeighborObject { nn_k: 3, pos_weight: 1.0, rot_weight: 1.0 },
        action_noise: 0.05,
        num_interpolation_steps: 5,
        num_fixed_steps: 0,
        apply_noise_during_interpolation: false,
        transit: crate::spec::Transit::Interpolate,
        approach_m: 0.1,
        selection_object: None,
    };
    TaskSpec {
        name: "kinematic_pick_place".to_owned(),
        env_name: None,
        generation: GenerationSettings { num_trials, select_src_per_subtask: true, seed, ..GenerationSettings::default() },
        source: crate::spec::SourceSelection::default(),
        subtasks: vec![subtask("cubeA", Some("grasp"), Some((10, 20))), subtask("cubeB", None, None)],
    }
}
