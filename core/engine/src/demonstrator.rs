//! A scripted pick-and-place demonstrator that records demos the way a teleoperator's would be
//! recorded (actions, states, eef and target poses, object poses, signals), with the variation a
//! person brings: grasp offsets and yaw, approach heights, speeds, pauses and small jitter.
//! It drives any [`Environment`], so the same script makes source demos for the kinematic test
//! environment and for MuJoCo.

use rand::Rng;

use crate::SourceDemo;
use crate::env::{EnvError, Environment};
use crate::generate::{StepLabels, Trajectory, execute_step};
use crate::pose::{Pose, Rot, Vec3, pose_from_parts, yaw_of};
use crate::transform::{Waypoint, WaypointKind, interpolate_poses};

/// What to pick, where to put it, and the timing of the gripper.
#[derive(Debug, Clone, PartialEq)]
pub struct PickPlaceScript {
    /// Object to pick.
    pub pick: String,
    /// Object to place it on.
    pub place_on: String,
    /// Height of the grip point above the picked object's centre when grasping (m).
    pub grasp_height_m: f64,
    /// Height of the picked object's centre above the target object's centre at release (m).
    pub release_height_m: f64,
    /// Steps to hold while closing, drawn from this range.
    pub close_steps: (usize, usize),
    /// Steps to hold while opening, drawn from this range.
    pub open_steps: (usize, usize),
    /// Largest random grasp offset from the object's centre, per axis (m).
    pub grasp_offset_m: f64,
    /// Range of the hover height above the grasp before descending (m).
    pub approach_height_m: (f64, f64),
    /// Range of the lift height above the grasp after closing (m).
    pub lift_height_m: (f64, f64),
    /// Height of the retreat above the release pose at the end (m).
    pub retreat_height_m: f64,
}

/// Target poses from `from` to `to` moving at most `speed_m` per step (and a matching share of the
/// rotation), ending exactly at `to`.
fn moves(from: &Pose, to: &Pose, speed_m: f64) -> Vec<Pose> {
    let distance = (to.translation.vector - from.translation.vector).norm().max(from.rotation.angle_to(&to.rotation) * 0.05);
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let steps = (distance / speed_m).ceil().max(1.0) as usize;
    interpolate_poses(from, to, steps - 1).into_iter().skip(1).collect()
}

fn env_err(what: &str) -> EnvError {
    EnvError::Fatal { reason: format!("the scene has no object {what:?}") }
}

impl PickPlaceScript {
    /// Records one demo in the environment's current scene (call `reset` first). Whether it
    /// succeeded is `env.is_success()` afterwards.
    ///
    /// # Errors
    /// The environment's error if a step fails, or [`EnvError::Fatal`] if an object is missing.
    pub fn record<E: Environment + ?Sized, R: Rng + ?Sized>(&self, env: &mut E, name: &str, rng: &mut R) -> Result<SourceDemo, EnvError> {
        record_sequence(std::slice::from_ref(self), env, name, rng)
    }

    /// Appends this pick-and-place to `traj`, starting from the current state.
    ///
    /// # Errors
    /// As [`PickPlaceScript::record`].
    pub fn record_into<E: Environment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        traj: &mut Trajectory,
        rng: &mut R,
    ) -> Result<(), EnvError> {
        let objects = env.object_poses();
        let a = *objects.get(&self.pick).ok_or_else(|| env_err(&self.pick))?;
        let b = *objects.get(&self.place_on).ok_or_else(|| env_err(&self.place_on))?;
        let start = env.eef_pose();
        // Grasp about one of the object's four symmetric yaws, the one closest to the gripper's.
        let quarter = std::f64::consts::FRAC_PI_2;
        let (cube_yaw, eef_yaw) = (yaw_of(&a), yaw_of(&start));
        let grasp_yaw = cube_yaw + ((eef_yaw - cube_yaw) / quarter).round() * quarter + rng.random_range(-0.15..0.15);
        let grasp_rot = Rot::from_axis_angle(&Vec3::z_axis(), grasp_yaw - eef_yaw) * start.rotation;
        let g = self.grasp_offset_m;
        let offset = Vec3::new(rng.random_range(-g..=g), rng.random_range(-g..=g), self.grasp_height_m + rng.random_range(-g..=g) * 0.5);
        let grasp = pose_from_parts(a.translation.vector + offset, grasp_rot);
        let above = |p: &Pose, h: f64| pose_from_parts(p.translation.vector + Vec3::new(0.0, 0.0, h), p.rotation);
        let place_xy = Vec3::new(rng.random_range(-0.003..0.003), rng.random_range(-0.003..0.003), self.release_height_m);
        let place = pose_from_parts(b.translation.vector + place_xy + offset, grasp_rot);
        let (fast, slow) = (rng.random_range(0.012..0.025), rng.random_range(0.004..0.008));
        let plan: Vec<(Pose, f64, f64, usize)> = vec![
            (above(&grasp, rng.random_range(self.approach_height_m.0..self.approach_height_m.1)), fast, -1.0, rng.random_range(0..4)),
            (grasp, slow, -1.0, rng.random_range(2..5)),
            (grasp, slow, 1.0, rng.random_range(self.close_steps.0..=self.close_steps.1)),
            (above(&grasp, rng.random_range(self.lift_height_m.0..self.lift_height_m.1)), fast, 1.0, 0),
            (above(&place, rng.random_range(0.03..0.08)), fast, 1.0, rng.random_range(0..3)),
            (place, slow, 1.0, rng.random_range(1..4)),
            (place, slow, -1.0, rng.random_range(self.open_steps.0..=self.open_steps.1)),
            (above(&place, self.retreat_height_m), fast, -1.0, 0),
        ];
        let mut current = start;
        for (goal, speed, gripper, pause) in plan {
            let mut targets = moves(&current, &goal, speed);
            targets.extend(std::iter::repeat_n(goal, pause));
            for target in targets {
                let jitter = Vec3::new(rng.random_range(-5e-4..5e-4), rng.random_range(-5e-4..5e-4), rng.random_range(-5e-4..5e-4));
                let waypoint = Waypoint {
                    pose: pose_from_parts(target.translation.vector + jitter, target.rotation),
                    gripper: vec![gripper],
                    noise: 0.0,
                };
                execute_step(env, &waypoint, StepLabels { src_demo: 0, subtask: 0, kind: WaypointKind::Transformed }, traj, rng)?;
            }
            current = goal;
        }
        Ok(())
    }
}

/// Records several pick-and-places one after the other as one demo (e.g. Stack Three).
///
/// # Errors
/// As [`PickPlaceScript::record`].
pub fn record_sequence<E: Environment + ?Sized, R: Rng + ?Sized>(
    scripts: &[PickPlaceScript],
    env: &mut E,
    name: &str,
    rng: &mut R,
) -> Result<SourceDemo, EnvError> {
    let mut traj = Trajectory::new(env.state().len(), env.action_dim());
    for script in scripts {
        script.record_into(env, &mut traj, rng)?;
    }
    Ok(traj.to_source_demo(name))
}
