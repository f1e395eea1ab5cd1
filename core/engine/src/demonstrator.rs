//! A scripted pick-and-place demonstrator that records demos the way a teleoperator's would be
//! recorded (actions, states, eef and target poses, object poses, signals), with the variation a
//! person brings: grasp offsets and yaw, approach heights, speeds, pauses and small jitter.
//! It drives any [`Environment`], so the same script makes source demos for the kinematic test
//! environment and for MuJoCo.

use std::f64::consts::PI;

use rand::Rng;

use crate::SourceDemo;
use crate::env::{EnvError, Environment};
use crate::generate::{StepLabels, Trajectory, execute_step};
use crate::pose::{Pose, Rot, Vec3, pose_from_parts, yaw_of};
use crate::transform::{Waypoint, WaypointKind, interpolate_poses};

/// What to pick, where to put it, and the timing of the gripper. A task file's `[[script]]`
/// table: fields it leaves out take [`PickPlaceScript::default`]'s values. With `path_on` set it
/// is a path instead (a pull on a drawer's handle, a push on its front): the gripper closes where
/// it is and moves through `path_m`, and `pick` and `place_on` stay empty.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PickPlaceScript {
    /// Object to pick.
    pub pick: String,
    /// Object to place it on.
    pub place_on: String,
    /// Where to grip, in the picked object's frame (m): its centre for a cube, the handle of a nut.
    pub grasp_point_m: [f64; 3],
    /// Height of the grip point above `grasp_point_m` when grasping (m).
    pub grasp_height_m: f64,
    /// The grasp's yaw symmetry (rad): a quarter turn for a cube, a half turn for a handle.
    pub grasp_symmetry_rad: f64,
    /// Yaw of the gripper relative to the object at a symmetric grasp (rad).
    pub grasp_yaw_offset_rad: f64,
    /// Lean the hand's top this far (deg) towards the picked object's +y at the grasp, about the
    /// object's x axis, and keep that lean to the place: a mug held by its handle and pushed in
    /// under a coffee machine's holder, the wrist leaning back from the machine's lid. 0: the
    /// gripper's starting tilt.
    pub grasp_lean_deg: f64,
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
    /// Range of the hover height above the release pose before descending onto the target (m).
    pub preplace_height_m: (f64, f64),
    /// Height of the retreat above the release pose at the end (m).
    pub retreat_height_m: f64,
    /// Turn the carried object to the target's yaw modulo this angle before placing it (a square
    /// nut onto a square peg: a quarter turn); `None` keeps the gripper's yaw.
    pub place_yaw_symmetry_rad: Option<f64>,
    /// With `place_yaw_symmetry_rad`: the carried object's yaw at the place is the target's plus
    /// this (rad): a hammer laid along a drawer rather than across it.
    pub place_yaw_offset_rad: f64,
    /// Steps to wait, holding still, before looking at the scene (objects that reset in the
    /// air, as robosuite's nuts do, land first).
    pub settle_steps: usize,
    /// How the operator moves: a choice of the recording, not of the task, so task files
    /// cannot set it.
    #[serde(skip)]
    pub style: Style,
    /// The point of the picked object that is placed (in its frame, m): its centre for a cube,
    /// a needle's tip half for threading.
    pub place_point_m: [f64; 3],
    /// Where on the target it goes (in the target's frame, m): its centre for a cube, the centre
    /// of a ring raised above its base.
    pub target_point_m: [f64; 3],
    /// Approach the place along this offset (in the picked object's frame once turned, m): the
    /// pre-place pose is the place pose moved by it, reached from above, and the last motion is a
    /// straight push from there (a needle into a ring). `None`: hover above and descend.
    pub approach_m: Option<[f64; 3]>,
    /// Let go at the place and retreat; `false` holds the object there to the end (threading).
    pub release: bool,
    /// After the place, move the closed gripper through these points (in the target's frame, m),
    /// keeping its orientation: a push (closing a lid).
    pub then_m: Vec<[f64; 3]>,
    /// At the place, before letting go, turn the held object about the vertical through
    /// `target_point_m` by this much (deg; positive is counter-clockwise seen from above), slowly,
    /// in steps of at most 10 deg so the hand follows the arc: a gear turned on its shaft by its
    /// hub, driving the gear it meshes with. 0: no turn.
    pub turn_deg: f64,
    /// A path instead of a pick-and-place: the object whose frame `path_m` is in.
    pub path_on: String,
    /// The closed gripper's path (in `path_on`'s frame at the path's start, m), keeping its
    /// orientation: the first point reached quickly, the others slowly, each before the next.
    pub path_m: Vec<[f64; 3]>,
    /// Turn the gripper for the path so its fingers close along `path_on`'s x axis turned by this
    /// (rad, either way round: a half-turn symmetry), and back on the way to the last point;
    /// `None` keeps its yaw.
    pub path_yaw_rad: Option<f64>,
    /// A robot on a mobile base drives it to `[x, y, yaw_deg]` (in the world) before the pick,
    /// the arm holding still on it: to the sink, say. `None`: the base stays where it is.
    pub drive_before_pick: Option<[f64; 3]>,
    /// The same after the lift, before the place: from the counter to the stove, say.
    pub drive_before_place: Option<[f64; 3]>,
}

/// How the scripted operator moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Style {
    /// Straight moves at an even speed; before descending to grasp or place it hovers until the
    /// arm has caught up with its target.
    #[default]
    Careful,
    /// As careful, but it goes on as soon as a motion has been commanded, never waiting for the arm.
    Hasty,
    /// Like a person at a teleoperation device: a reaction time before each pick-and-place, moves
    /// that speed up and slow down, a hand that drifts by about a millimetre, twice the grasp
    /// offset and yaw error, pauses partway down (hesitation), descents aimed a few millimetres
    /// off and then corrected, and now and then no wait for the arm. Every draw is from the
    /// recording's seeded generator.
    Human,
}

/// One leg of a scripted motion: goal, speed (m per step), gripper command, steps to pause at the
/// goal, and whether to wait there until the arm has arrived.
type Leg = (Pose, f64, f64, usize, bool);
/// How close the arm must be to a precise leg's goal before the script goes on (m).
const SETTLE_TOLERANCE_M: f64 = 0.004;
/// The largest turn of the wrist about the vertical the script makes to fit an object (rad).
const MAX_PLACE_TURN_RAD: f64 = 2.4;
/// The longest the script waits for that (steps).
const SETTLE_MAX_STEPS: usize = 40;
/// How close a drive brings the base to its goal (m, rad), and the longest it may take (steps).
const DRIVE_TOLERANCE_M: f64 = 0.004;
const DRIVE_TOLERANCE_RAD: f64 = 0.008;
const MAX_DRIVE_STEPS: usize = 400;

/// How far a leg goes (m): its translation, or its rotation counted at 5 cm per radian if longer.
fn leg_length(from: &Pose, to: &Pose) -> f64 {
    (to.translation.vector - from.translation.vector).norm().max(from.rotation.angle_to(&to.rotation) * 0.05)
}

/// A draw from the cube of half-side `half_m` about zero (m), x then y then z.
pub(crate) fn uniform_jitter<R: Rng + ?Sized>(rng: &mut R, half_m: f64) -> Vec3 {
    Vec3::new(rng.random_range(-half_m..half_m), rng.random_range(-half_m..half_m), rng.random_range(-half_m..half_m))
}

/// Target poses from `from` to `to` moving at most `speed_m` per step (and a matching share of the
/// rotation), ending exactly at `to`.
fn moves(from: &Pose, to: &Pose, speed_m: f64) -> Vec<Pose> {
    let distance = leg_length(from, to);
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let steps = (distance / speed_m).ceil().max(1.0) as usize;
    interpolate_poses(from, to, steps - 1).into_iter().skip(1).collect()
}

/// How often a person goes on without waiting for the arm to arrive (per precise leg).
pub(crate) const HUMAN_IMPATIENCE: f64 = 0.2;

/// Target poses from `from` to `to` as a person moves: speeding up and slowing down (a
/// minimum-jerk profile peaking at about 1.25 `speed_m`). A precise leg (a descent to grasp or
/// place) is aimed a few millimetres off half of the time and then corrected, and a third of the
/// time pauses partway (hesitation). Ends exactly at `to`.
pub(crate) fn human_moves<R: Rng + ?Sized>(from: &Pose, to: &Pose, speed_m: f64, precise: bool, rng: &mut R) -> Vec<Pose> {
    let smooth = |a: &Pose, b: &Pose, speed: f64| -> Vec<Pose> {
        let distance = leg_length(a, b);
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let steps = (1.5 * distance / speed).ceil().max(1.0) as usize;
        (1..=steps)
            .map(|i| {
                #[allow(clippy::cast_precision_loss)]
                let tau = i as f64 / steps as f64;
                a.lerp_slerp(b, tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau))
            })
            .collect()
    };
    let mut targets = if precise && rng.random_bool(0.5) {
        let heading = rng.random_range(0.0..2.0 * PI);
        let miss = rng.random_range(0.003..0.008);
        let aimed = pose_from_parts(
            to.translation.vector + Vec3::new(miss * heading.cos(), miss * heading.sin(), rng.random_range(0.0..0.004)),
            to.rotation,
        );
        let mut targets = smooth(from, &aimed, speed_m);
        targets.extend(std::iter::repeat_n(aimed, rng.random_range(1..3)));
        targets.extend(smooth(&aimed, to, 0.5 * speed_m));
        targets
    } else {
        smooth(from, to, speed_m)
    };
    if precise && rng.random_bool(0.35) {
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
        let at = ((targets.len() as f64 * rng.random_range(0.5..0.85)) as usize).min(targets.len().saturating_sub(1));
        if let Some(&pose) = targets.get(at) {
            let pause = rng.random_range(3..10);
            targets.splice(at..at, std::iter::repeat_n(pose, pause));
        }
    }
    targets
}

/// Of the yaws `yaw + k * symmetry`, the one closest to `current` (rad).
fn nearest_symmetric_yaw(yaw: f64, current: f64, symmetry: f64) -> f64 {
    yaw + ((current - yaw) / symmetry).round() * symmetry
}

fn env_err(what: &str) -> EnvError {
    EnvError::Fatal { reason: format!("the scene has no object {what:?}") }
}

impl Default for PickPlaceScript {
    /// A careful operator's pick-and-place of a small cube (grasp at its centre, any quarter turn)
    /// onto another; `pick` and `place_on` empty.
    fn default() -> Self {
        Self {
            pick: String::new(),
            place_on: String::new(),
            grasp_point_m: [0.0; 3],
            grasp_height_m: -0.002,
            grasp_symmetry_rad: std::f64::consts::FRAC_PI_2,
            grasp_yaw_offset_rad: 0.0,
            grasp_lean_deg: 0.0,
            release_height_m: 0.051,
            close_steps: (6, 9),
            open_steps: (3, 5),
            grasp_offset_m: 0.003,
            approach_height_m: (0.06, 0.12),
            lift_height_m: (0.12, 0.18),
            preplace_height_m: (0.03, 0.08),
            retreat_height_m: 0.08,
            place_yaw_symmetry_rad: None,
            place_yaw_offset_rad: 0.0,
            settle_steps: 0,
            style: Style::Careful,
            place_point_m: [0.0; 3],
            target_point_m: [0.0; 3],
            approach_m: None,
            release: true,
            then_m: Vec::new(),
            turn_deg: 0.0,
            path_on: String::new(),
            path_m: Vec::new(),
            path_yaw_rad: None,
            drive_before_pick: None,
            drive_before_place: None,
        }
    }
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
        if !self.path_on.is_empty() {
            return self.record_path(env, traj, rng);
        }
        hold_open(env, traj, rng, self.settle_steps)?;
        let mut start = env.eef_pose();
        if let Some(goal) = self.drive_before_pick {
            self.drive(env, traj, rng, &mut start, goal, -1.0)?;
        }
        let objects = env.object_poses();
        let world_from_pick = *objects.get(&self.pick).ok_or_else(|| env_err(&self.pick))?;
        let mut world_from_target = *objects.get(&self.place_on).ok_or_else(|| env_err(&self.place_on))?;
        // Grasp about one of the object's symmetric yaws, the one closest to the gripper's.
        let symmetry = self.grasp_symmetry_rad;
        let (object_yaw, eef_yaw) = (yaw_of(&world_from_pick) + self.grasp_yaw_offset_rad, yaw_of(&start));
        let human = self.style == Style::Human;
        if human {
            react(env, traj, rng)?;
        }
        let yaw_error = if human { 0.3 } else { 0.15 };
        let grasp_yaw = nearest_symmetric_yaw(object_yaw, eef_yaw, symmetry) + rng.random_range(-yaw_error..yaw_error);
        let mut grasp_rot = Rot::from_axis_angle(&Vec3::z_axis(), grasp_yaw - eef_yaw) * start.rotation;
        if self.grasp_lean_deg != 0.0 {
            // About the object's x axis, laid level: a turn by minus the lean takes "up" towards +y.
            let x = world_from_pick.rotation * Vec3::x();
            if let Some(axis) = nalgebra::Unit::try_new(Vec3::new(x.x, x.y, 0.0), 1e-9) {
                grasp_rot = Rot::from_axis_angle(&axis, -self.grasp_lean_deg.to_radians()) * grasp_rot;
            }
        }
        let g = if human { 2.0 * self.grasp_offset_m } else { self.grasp_offset_m };
        let grip_point = world_from_pick.rotation * Vec3::from(self.grasp_point_m);
        // The grip point relative to the object's centre, in the world frame; the carried object
        // keeps it while the gripper does not turn.
        let offset = grip_point
            + Vec3::new(rng.random_range(-g..=g), rng.random_range(-g..=g), self.grasp_height_m + rng.random_range(-g..=g) * 0.5);
        let grasp = pose_from_parts(world_from_pick.translation.vector + offset, grasp_rot);
        let above = |p: &Pose, h: f64| pose_from_parts(p.translation.vector + Vec3::new(0.0, 0.0, h), p.rotation);
        let (fast, slow) = self.speeds(rng);
        // Hover above the grasp until the arm has caught up, then go straight down.
        let pick: Vec<Leg> = vec![
            (above(&grasp, rng.random_range(self.approach_height_m.0..self.approach_height_m.1)), fast, -1.0, rng.random_range(0..4), true),
            (grasp, slow, -1.0, rng.random_range(2..5), true),
            (grasp, slow, 1.0, rng.random_range(self.close_steps.0..=self.close_steps.1), false),
            (above(&grasp, rng.random_range(self.lift_height_m.0..self.lift_height_m.1)), fast, 1.0, 0, false),
        ];
        let mut current = start;
        self.follow(env, traj, rng, &mut current, pick)?;
        let mut home = start.translation.vector;
        if let Some(goal) = self.drive_before_place {
            self.drive(env, traj, rng, &mut current, goal, 1.0)?;
            world_from_target = *env.object_poses().get(&self.place_on).ok_or_else(|| env_err(&self.place_on))?;
            home = current.translation.vector;
        }
        // Like an operator watching the object in the hand: aim the place from where the object
        // actually sits in the gripper (closing the fingers may have pushed it), turning it to
        // the target's yaw when the fit needs it; aim again once above the target.
        let place_xy = Vec3::new(rng.random_range(-0.003..0.003), rng.random_range(-0.003..0.003), self.release_height_m)
            + world_from_target.rotation * Vec3::from(self.target_point_m);
        let place = self.aim(env, &world_from_target, place_xy, &grasp_rot, &home)?;
        let (hover, pause) = (rng.random_range(self.preplace_height_m.0..self.preplace_height_m.1), rng.random_range(0..3));
        // The pre-place pose: above the place, or back along the approach (the held object's
        // frame, as it will be turned at the place) and first above that.
        let before = |place: &Pose, env: &E| -> Result<Pose, EnvError> {
            let Some(approach) = self.approach_m else { return Ok(above(place, hover)) };
            let now = env.object_poses().get(&self.pick).copied().ok_or_else(|| env_err(&self.pick))?;
            let turned = place.rotation * env.eef_pose().rotation.inverse() * now.rotation;
            Ok(pose_from_parts(place.translation.vector + turned * Vec3::from(approach), place.rotation))
        };
        let pre = before(&place, &*env)?;
        let mut legs = Vec::new();
        if self.approach_m.is_some() {
            legs.push((above(&pre, hover), fast, 1.0, 0, false));
        }
        legs.push((pre, fast, 1.0, pause, true));
        self.follow(env, traj, rng, &mut current, legs)?;
        let place = self.aim(env, &world_from_target, place_xy, &place.rotation, &home)?;
        current = before(&place, &*env)?;
        let mut put: Vec<Leg> = vec![(place, slow, 1.0, rng.random_range(1..4), true)];
        let mut place = place;
        if self.turn_deg != 0.0 {
            let axis = world_from_target.translation.vector + world_from_target.rotation * Vec3::from(self.target_point_m);
            let total = self.turn_deg.to_radians();
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let legs = (self.turn_deg.abs() / 10.0).ceil() as usize;
            let start = place;
            for k in 1..=legs {
                #[allow(clippy::cast_precision_loss)]
                let turn = Rot::from_axis_angle(&Vec3::z_axis(), total * k as f64 / legs as f64);
                place = pose_from_parts(axis + turn * (start.translation.vector - axis), turn * start.rotation);
                put.push((place, 0.5 * slow, 1.0, 0, false));
            }
            put.push((place, slow, 1.0, rng.random_range(3..6), true));
        }
        if self.release {
            put.push((place, slow, -1.0, rng.random_range(self.open_steps.0..=self.open_steps.1), false));
            // Retreat, and hold a moment before the recording stops, as an operator would.
            put.push((above(&place, self.retreat_height_m), fast, -1.0, rng.random_range(3..6), false));
        } else {
            put.push((place, slow, 1.0, rng.random_range(3..6), false));
        }
        self.follow(env, traj, rng, &mut current, put)?;
        if !self.then_m.is_empty() {
            let target = *env.object_poses().get(&self.place_on).ok_or_else(|| env_err(&self.place_on))?;
            let mut push: Vec<Leg> = self
                .then_m
                .iter()
                .map(|p| {
                    (pose_from_parts(target.translation.vector + target.rotation * Vec3::from(*p), current.rotation), fast, 1.0, 0, false)
                })
                .collect();
            // Hold the last point (a press) until the arm is there and a while after.
            if let Some(last) = push.last_mut() {
                last.3 = rng.random_range(10..16);
                last.4 = true;
            }
            self.follow(env, traj, rng, &mut current, push)?;
        }
        Ok(())
    }

    /// A path: close the fingers where the gripper is, then through `path_m`, all of it offset
    /// by one small error of the operator's hand.
    fn record_path<E: Environment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        traj: &mut Trajectory,
        rng: &mut R,
    ) -> Result<(), EnvError> {
        let frame = *env.object_poses().get(&self.path_on).ok_or_else(|| env_err(&self.path_on))?;
        if self.style == Style::Human {
            react(env, traj, rng)?;
        }
        let mut current = env.eef_pose();
        let g = self.grasp_offset_m;
        let offset = Vec3::new(rng.random_range(-g..=g), rng.random_range(-g..=g), rng.random_range(-g..=g));
        let (fast, slow) = self.speeds(rng);
        let rotation = match self.path_yaw_rad {
            Some(yaw_offset) => {
                let eef_yaw = yaw_of(&current);
                let turn = nearest_symmetric_yaw(yaw_of(&frame) + yaw_offset, eef_yaw, PI) - eef_yaw;
                Rot::from_axis_angle(&Vec3::z_axis(), turn) * current.rotation
            }
            None => current.rotation,
        };
        let mut legs: Vec<Leg> = vec![(current, slow, 1.0, rng.random_range(self.close_steps.0..=self.close_steps.1), false)];
        let last = self.path_m.len().saturating_sub(1);
        for (k, point) in self.path_m.iter().enumerate() {
            // A turned hand turns back on the way to the last point (a relaxed wrist).
            let rotation = if k == last && k > 0 { current.rotation } else { rotation };
            let goal = pose_from_parts(frame.translation.vector + frame.rotation * Vec3::from(*point) + offset, rotation);
            legs.push((goal, if k == 0 { fast } else { slow }, 1.0, rng.random_range(0..3), true));
        }
        self.follow(env, traj, rng, &mut current, legs)
    }

    /// Drives the mobile base to `goal` (`[x, y, yaw_deg]`), the arm's target (`current`, moved
    /// with the base) and the gripper (`gripper`) held, then lets the base come to rest. A
    /// person's drive is slower or faster and starts after a reaction time.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] for a robot without a base; the environment's error from a step.
    fn drive<E: Environment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        traj: &mut Trajectory,
        rng: &mut R,
        current: &mut Pose,
        goal: [f64; 3],
        gripper: f64,
    ) -> Result<(), EnvError> {
        let no_base =
            || EnvError::Fatal { reason: "the script drives a mobile base (drive_before_*), but this robot stands on none".to_owned() };
        let base = env.mobile_base().ok_or_else(no_base)?;
        let goal = [goal[0], goal[1], goal[2].to_radians()];
        let base_from_target = base.world_from_base.inverse() * *current;
        let human = self.style == Style::Human;
        let speed = if human { rng.random_range(0.5..1.0) } else { 0.8 };
        let pause = if human { rng.random_range(3..12) } else { 2 };
        let labels = StepLabels { src_demo: 0, subtask: 0, kind: WaypointKind::Transformed };
        let hold = |base: &crate::base::MobileBase, command: Vec<f64>| Waypoint {
            pose: base.world_from_base * base_from_target,
            gripper: vec![gripper],
            noise: 0.0,
            base: command,
        };
        for _ in 0..pause {
            execute_step(env, &hold(&base, Vec::new()), labels, traj, rng)?;
        }
        // The arm gets where it was sent (a lift) before the base moves: the base and the arm do
        // not move at once, and the source's hand then rides the drive still on the base.
        for _ in 0..SETTLE_MAX_STEPS {
            let base = env.mobile_base().ok_or_else(no_base)?;
            let target = base.world_from_base * base_from_target;
            if (env.eef_pose().translation.vector - target.translation.vector).norm() < SETTLE_TOLERANCE_M {
                break;
            }
            execute_step(env, &hold(&base, Vec::new()), labels, traj, rng)?;
        }
        for _ in 0..MAX_DRIVE_STEPS {
            let base = env.mobile_base().ok_or_else(no_base)?;
            if crate::base::at_goal(&base, goal, DRIVE_TOLERANCE_M, DRIVE_TOLERANCE_RAD) {
                break;
            }
            let command = crate::base::drive_command(&base, goal, speed);
            execute_step(env, &hold(&base, command.to_vec()), labels, traj, rng)?;
        }
        // The base comes to rest before the arm moves again.
        for _ in 0..pause.max(4) {
            let base = env.mobile_base().ok_or_else(no_base)?;
            execute_step(env, &hold(&base, Vec::new()), labels, traj, rng)?;
        }
        *current = env.mobile_base().ok_or_else(no_base)?.world_from_base * base_from_target;
        Ok(())
    }

    /// The fast and slow speeds of one pick-and-place (m per step).
    fn speeds<R: Rng + ?Sized>(&self, rng: &mut R) -> (f64, f64) {
        match self.style {
            Style::Careful | Style::Hasty => (rng.random_range(0.012..0.025), rng.random_range(0.004..0.008)),
            Style::Human => (rng.random_range(0.012..0.030), rng.random_range(0.004..0.010)),
        }
    }

    /// The gripper pose that puts the held object `place_offset` from `target`'s centre, given
    /// where it sits in the gripper now; `commanded` is the gripper orientation being commanded.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] if the scene has no such object.
    fn aim<E: Environment + ?Sized>(
        &self,
        env: &E,
        target: &Pose,
        place_offset: Vec3,
        commanded: &Rot,
        home: &Vec3,
    ) -> Result<Pose, EnvError> {
        let objects = env.object_poses();
        let now = objects.get(&self.pick).ok_or_else(|| env_err(&self.pick))?;
        let held = env.eef_pose().translation.vector - (now.translation.vector + now.rotation * Vec3::from(self.place_point_m));
        let place = |turn: f64| {
            let turn = Rot::from_axis_angle(&Vec3::z_axis(), turn);
            pose_from_parts(target.translation.vector + place_offset + turn * held, turn * commanded)
        };
        let Some(sym) = self.place_yaw_symmetry_rad else { return Ok(place(0.0)) };
        // Of the turns that fit, the one that keeps the hand nearest where it started (the
        // robot's side of the target), within what the wrist comfortably turns.
        let error = yaw_of(target) + self.place_yaw_offset_rad - yaw_of(now);
        let base = error - (error / sym).round() * sym;
        let mut best: Option<(f64, Pose)> = None;
        for k in -4_i32..=4 {
            let turn = base + f64::from(k) * sym;
            if turn.abs() > MAX_PLACE_TURN_RAD {
                continue;
            }
            let pose = place(turn);
            let reach = (pose.translation.vector - home).xy().norm();
            if best.as_ref().is_none_or(|(r, _)| reach < *r) {
                best = Some((reach, pose));
            }
        }
        // `base` is within half a symmetry of zero, so the unturned-by-k candidate always qualifies.
        Ok(best.map_or_else(|| place(base), |(_, pose)| pose))
    }

    /// Drives the controller target through `legs`
    /// from `current`, with the small jitter of a hand, recording every step into `traj`.
    fn follow<E: Environment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        traj: &mut Trajectory,
        rng: &mut R,
        current: &mut Pose,
        legs: Vec<Leg>,
    ) -> Result<(), EnvError> {
        let human = self.style == Style::Human;
        // A person's hand drifts slowly rather than shaking from step to step.
        let mut drift = Vec3::zeros();
        for (goal, speed, gripper, pause, precise) in legs {
            let mut targets = if human { human_moves(current, &goal, speed, precise, rng) } else { moves(current, &goal, speed) };
            targets.extend(std::iter::repeat_n(goal, pause));
            let wait = precise
                && match self.style {
                    Style::Careful => true,
                    Style::Hasty => false,
                    Style::Human => !rng.random_bool(HUMAN_IMPATIENCE),
                };
            for target in targets {
                let jitter = if human {
                    drift = drift * 0.8 + uniform_jitter(rng, 7e-4);
                    drift
                } else {
                    uniform_jitter(rng, 5e-4)
                };
                let waypoint = Waypoint {
                    pose: pose_from_parts(target.translation.vector + jitter, target.rotation),
                    gripper: vec![gripper],
                    noise: 0.0,
                    base: Vec::new(),
                };
                execute_step(env, &waypoint, StepLabels { src_demo: 0, subtask: 0, kind: WaypointKind::Transformed }, traj, rng)?;
            }
            // Before anything that needs precision, wait (a little) until the arm is there and
            // has stopped.
            let mut last = Vec3::repeat(f64::INFINITY);
            for _ in 0..if wait { SETTLE_MAX_STEPS } else { 0 } {
                let now = env.eef_pose().translation.vector;
                let (off, moved) = ((now - goal.translation.vector).norm(), (now - last).norm());
                // There and still, or stopped short (touching something): go on.
                if (off < SETTLE_TOLERANCE_M && moved < SETTLE_TOLERANCE_M / 4.0) || moved < SETTLE_TOLERANCE_M / 20.0 {
                    break;
                }
                last = now;
                let waypoint = Waypoint { pose: goal, gripper: vec![gripper], noise: 0.0, base: Vec::new() };
                execute_step(env, &waypoint, StepLabels { src_demo: 0, subtask: 0, kind: WaypointKind::Transformed }, traj, rng)?;
            }
            *current = goal;
        }
        Ok(())
    }
}

/// Holds the gripper where it is, open, for `steps` steps, recording them into `traj`.
fn hold_open<E: Environment + ?Sized, R: Rng + ?Sized>(
    env: &mut E,
    traj: &mut Trajectory,
    rng: &mut R,
    steps: usize,
) -> Result<(), EnvError> {
    let hold = Waypoint { pose: env.eef_pose(), gripper: vec![-1.0], noise: 0.0, base: Vec::new() };
    for _ in 0..steps {
        execute_step(env, &hold, StepLabels { src_demo: 0, subtask: 0, kind: WaypointKind::Transformed }, traj, rng)?;
    }
    Ok(())
}

/// A person's reaction time: the hand holds still, open, for 3 to 11 steps.
fn react<E: Environment + ?Sized, R: Rng + ?Sized>(env: &mut E, traj: &mut Trajectory, rng: &mut R) -> Result<(), EnvError> {
    let steps = rng.random_range(3..12);
    hold_open(env, traj, rng, steps)
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
    let mut traj = Trajectory::for_env(env);
    for script in scripts {
        script.record_into(env, &mut traj, rng)?;
    }
    Ok(traj.to_source_demo(name))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use rand::SeedableRng as _;
    use rand_chacha::ChaCha8Rng;

    use super::*;

    fn at(x: f64, y: f64, z: f64) -> Pose {
        pose_from_parts(Vec3::new(x, y, z), Rot::identity())
    }

    /// The longest run of equal consecutive poses.
    fn longest_hold(targets: &[Pose]) -> usize {
        let (mut longest, mut run) = (1, 1);
        for pair in targets.windows(2) {
            run = if pair[0] == pair[1] { run + 1 } else { 1 };
            longest = longest.max(run);
        }
        longest
    }

    #[test]
    fn a_persons_move_speeds_up_slows_down_and_ends_at_the_goal() {
        let (from, to) = (at(0.0, 0.0, 0.2), at(0.3, 0.1, 0.0));
        let speed = 0.02;
        for seed in 0..20 {
            let targets = human_moves(&from, &to, speed, false, &mut ChaCha8Rng::seed_from_u64(seed));
            let last = targets.last().unwrap();
            assert!((last.translation.vector - to.translation.vector).norm() < 1e-12, "ends at the goal");
            let steps: Vec<f64> = std::iter::once(&from)
                .chain(&targets)
                .collect::<Vec<_>>()
                .windows(2)
                .map(|p| (p[1].translation.vector - p[0].translation.vector).norm())
                .collect();
            let peak = steps.iter().copied().fold(0.0, f64::max);
            assert!(peak > speed && peak < 1.5 * speed, "peak step {peak} for a speed of {speed}");
            assert!(steps[0] < 0.2 * peak && steps[steps.len() - 1] < 0.2 * peak, "starts and stops gently: {steps:?}");
            // An even-speed move of the careful style takes fewer steps.
            assert!(targets.len() > moves(&from, &to, speed).len());
        }
    }

    #[test]
    fn a_persons_descents_are_sometimes_corrected_and_sometimes_paused() {
        let (from, to) = (at(0.0, 0.0, 0.1), at(0.0, 0.0, 0.0));
        let (mut corrected, mut paused) = (0, 0);
        let trials = 400;
        for seed in 0..trials {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let targets = human_moves(&from, &to, 0.01, true, &mut rng);
            let off = targets.iter().map(|p| p.translation.vector.xy().norm()).fold(0.0, f64::max);
            if off > 0.0 {
                assert!((0.003..0.008).contains(&off), "aimed {off} m off");
                corrected += 1;
            }
            // A pause holds a pose four times or more; a corrected aim holds it two or three.
            if longest_hold(&targets) >= 4 {
                paused += 1;
            }
            // Travel (as opposed to a descent) is never corrected nor paused.
            let travel = human_moves(&from, &to, 0.01, false, &mut rng);
            assert!(travel.iter().all(|p| p.translation.vector.xy().norm() == 0.0));
            assert_eq!(longest_hold(&travel), 1);
        }
        let share = |n: u64| f64::from(u32::try_from(n).unwrap()) / f64::from(u32::try_from(trials).unwrap());
        assert!((0.4..0.6).contains(&share(corrected)), "corrected {corrected} of {trials}");
        assert!((0.25..0.45).contains(&share(paused)), "paused {paused} of {trials}");
    }
}
