//! A scripted two-arm demonstrator: each arm follows its own legs (a goal, a speed, the gripper,
//! a hold), at its own pace, and a leg may wait for the other arm to finish some of its legs: both
//! close on the same step and lift as one, or one receives only once the other has given. It records what a
//! teleoperated two-arm demo holds (both arms' actions in one row, each arm's poses, targets and
//! grippers, the objects and signals), as a [`TwoArmAttempt`] without plans.

use std::collections::{BTreeMap, VecDeque};

use rand::Rng;

use super::{ArmTrack, TwoArmAttempt, TwoArmEnvironment};
use crate::EngineError;
use crate::action::POSE_ACTION_DIM;
use crate::demo::Rows;
use crate::demonstrator::{HUMAN_IMPATIENCE, Style, human_moves, uniform_jitter};
use crate::env::EnvError;
use crate::pose::{Pose, Rot, Vec3, pose_from_parts, yaw_of};

/// Where a leg goes.
#[derive(Debug, Clone, PartialEq)]
pub enum Goal {
    /// A pose in the world.
    Fixed(Pose),
    /// A point of an object, seen when the leg starts: `point_m` in the object's frame, `height_m`
    /// above it, the hand turned about the vertical to the object's yaw plus `yaw_offset_rad`
    /// (modulo a half turn, the one nearest the hand's yaw).
    OnObject {
        /// The object.
        object: String,
        /// The point, in the object's frame (m).
        point_m: [f64; 3],
        /// Height above the point (m).
        height_m: f64,
        /// The hand's yaw relative to the object's (rad).
        yaw_offset_rad: f64,
    },
    /// Where the hand is commanded when the leg starts, moved by this much (m, world frame).
    Moved([f64; 3]),
    /// Over an object, seen when the leg starts: its origin moved by `offset_m` (world frame),
    /// the hand's rotation as commanded (carry what it holds there without turning it).
    Over {
        /// The object.
        object: String,
        /// The offset from its origin (m, world frame).
        offset_m: [f64; 3],
    },
}

/// One move of one arm.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmLeg {
    /// Where the end effector goes.
    pub goal: Goal,
    /// How far the commanded pose moves per step (m); turns go at 0.05 rad per step and at least
    /// as many steps as the move.
    pub speed_m: f64,
    /// The gripper action on the way (-1 open, 1 closed).
    pub gripper: f64,
    /// Steps to hold the goal once the arm is there (within 1 cm).
    pub hold: usize,
    /// The leg starts only once the other arm has finished this many of its legs: with its own
    /// index, both arms start it on the same step (close together, lift as one); with another,
    /// one waits for the other (receive once the give is done).
    pub after: Option<usize>,
}

impl ArmLeg {
    fn new(goal: Goal, speed_m: f64, gripper: f64, hold: usize, after: Option<usize>) -> Self {
        Self { goal, speed_m, gripper, hold, after }
    }

    fn fixed(goal: Pose, speed_m: f64, gripper: f64, hold: usize, after: Option<usize>) -> Self {
        Self::new(Goal::Fixed(goal), speed_m, gripper, hold, after)
    }
}

/// `pose` raised by `height_m`, turned as it is.
fn raised(pose: &Pose, height_m: f64) -> Pose {
    pose_from_parts(pose.translation.vector + Vec3::new(0.0, 0.0, height_m), pose.rotation)
}

/// A scripted two-arm lift of one object by two handles, one per arm.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmLiftScript {
    /// The lifted object (`pot`).
    pub object: String,
    /// Per arm: the point it grips, in the object's frame (m).
    pub grasp_points_m: [[f64; 3]; 2],
    /// The gripper's yaw relative to the object's at the grasp (rad), modulo a half turn.
    pub grasp_yaw_offset_rad: f64,
    /// Range of the hover height above the grasp before descending (m).
    pub approach_height_m: (f64, f64),
    /// Range of the lift height (m), the same for both arms in one demo.
    pub lift_height_m: (f64, f64),
    /// Steps to hold while closing, drawn from this range.
    pub close_steps: (usize, usize),
}

impl TwoArmLiftScript {
    /// robosuite's Two Arm Lift: the pot's handle bars, 16 cm out on either side of its centre and
    /// 6 cm up (arm 0 at handle 0, +y; arm 1 at handle 1, -y), gripped across.
    #[must_use]
    pub fn pot() -> Self {
        Self {
            object: "pot".to_owned(),
            grasp_points_m: [[0.0, 0.16, 0.06], [0.0, -0.16, 0.06]],
            grasp_yaw_offset_rad: std::f64::consts::FRAC_PI_2,
            approach_height_m: (0.06, 0.10),
            lift_height_m: (0.15, 0.18),
            close_steps: (10, 14),
        }
    }

    /// Records one demo from the environment's present state (call `reset` first), the operators
    /// moving in `style`.
    ///
    /// # Errors
    /// The environment's error if a step fails, [`EnvError::Fatal`] if the object is missing.
    pub fn record<E: TwoArmEnvironment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        style: Style,
        rng: &mut R,
    ) -> Result<TwoArmAttempt, EnvError> {
        let world_from_object = object_pose(&*env, &self.object)?;
        let spread = grasp_spread(style);
        let lift = rng.random_range(self.lift_height_m.0..self.lift_height_m.1);
        let lift_speed = rng.random_range(0.004..0.007);
        let mut legs = [Vec::new(), Vec::new()];
        for (arm, arm_legs) in legs.iter_mut().enumerate() {
            let start = env.eef_pose(arm);
            let yaw = yaw_of(&world_from_object) + self.grasp_yaw_offset_rad;
            let eef_yaw = yaw_of(&start);
            let grasp_yaw = yaw
                + ((eef_yaw - yaw) / std::f64::consts::PI).round() * std::f64::consts::PI
                + rng.random_range(-0.1 * spread..0.1 * spread);
            let rotation = Rot::from_axis_angle(&Vec3::z_axis(), grasp_yaw - eef_yaw) * start.rotation;
            let point = self.grasp_points_m.get(arm).copied().unwrap_or_default();
            let g = 0.004 * spread;
            let offset = Vec3::new(rng.random_range(-g..g), rng.random_range(-g / 2.0..g / 2.0), rng.random_range(-g..g));
            let grasp = pose_from_parts((world_from_object * nalgebra::Point3::from(Vec3::from(point))).coords + offset, rotation);
            let up = |h: f64| raised(&grasp, h);
            let (fast, slow) = (rng.random_range(0.012..0.022), rng.random_range(0.004..0.008));
            arm_legs.extend([
                ArmLeg::fixed(
                    up(rng.random_range(self.approach_height_m.0..self.approach_height_m.1)),
                    fast,
                    -1.0,
                    rng.random_range(0..4),
                    None,
                ),
                ArmLeg::fixed(grasp, slow, -1.0, rng.random_range(2..5), None),
                // Both close on the same step, and lift on the same step.
                ArmLeg::fixed(grasp, slow, 1.0, self.close_steps.0.max(1), Some(2)),
                ArmLeg::fixed(up(lift), lift_speed, 1.0, 6, Some(3)),
            ]);
        }
        let close = rng.random_range(self.close_steps.0..=self.close_steps.1);
        for arm_legs in &mut legs {
            if let Some(leg) = arm_legs.get_mut(2) {
                leg.hold = close;
            }
        }
        follow(env, &legs, style, rng)
    }
}

/// A scripted two-arm handover of a hammer lying on the table: arm 0 grasps its handle by the
/// head, lifts it, carries it to a point over the middle of the table with the handle
/// turned towards arm 1 and holds it there; only then arm 1 comes to the handle and grasps it;
/// only once arm 1 has closed does arm 0 open and back off, and arm 1 lifts the hammer.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmHandoverScript {
    /// The object handed over (`hammer`).
    pub object: String,
    /// Where arm 0 grips it, in its frame (m): the handle by the head.
    pub give_point_m: [f64; 3],
    /// Where arm 1 grips it, in its frame (m): the handle, away from the head.
    pub receive_point_m: [f64; 3],
    /// The object's axis (in its frame) that points from arm 0's grip towards arm 1's.
    pub towards_receiver: [f64; 3],
    /// Where arm 0 holds it for the handover (its end effector, world frame, m).
    pub handover_m: [f64; 3],
    /// The world direction the object's `towards_receiver` axis is turned to at the handover.
    pub receiver_direction: [f64; 3],
}

impl TwoArmHandoverScript {
    /// robosuite's Two Arm Handover: its hammer (`hammer_root`: the handle along its z axis, 17 cm
    /// long, the head at its +z end), given by the handle 5 cm towards the head and received by it
    /// 5 cm the other way, held across (the hand's x along the hammer's x), halfway between the
    /// arms.
    #[must_use]
    pub fn hammer() -> Self {
        Self {
            object: "hammer".to_owned(),
            give_point_m: [0.0, 0.0, 0.05],
            receive_point_m: [0.0, 0.0, -0.05],
            towards_receiver: [0.0, 0.0, -1.0],
            handover_m: [0.0, -0.05, 1.05],
            receiver_direction: [0.0, 1.0, 0.0],
        }
    }

    /// Arm 1's grasp of the handle, starting once arm 0 has finished `after` legs: over it, down
    /// to it, closed (across the handle: the hand's x along the object's).
    fn receive<R: Rng + ?Sized>(&self, fast: f64, slow: f64, after: usize, rng: &mut R) -> [ArmLeg; 3] {
        let on_handle =
            |height_m: f64| Goal::OnObject { object: self.object.clone(), point_m: self.receive_point_m, height_m, yaw_offset_rad: 0.0 };
        [
            ArmLeg::new(on_handle(rng.random_range(0.07..0.1)), fast, -1.0, rng.random_range(0..3), Some(after)),
            ArmLeg::new(on_handle(0.0), slow, -1.0, rng.random_range(2..4), None),
            ArmLeg::new(Goal::Moved([0.0, 0.0, 0.0]), slow, 1.0, rng.random_range(10..14), None),
        ]
    }

    /// Arm 0 lets go where it is, once arm 1 has finished `after` legs, and backs off up.
    fn let_go<R: Rng + ?Sized>(slow: f64, after: usize, rng: &mut R) -> [ArmLeg; 2] {
        [
            ArmLeg::new(Goal::Moved([0.0, 0.0, 0.0]), slow, -1.0, rng.random_range(8..11), Some(after)),
            ArmLeg::new(Goal::Moved([0.0, 0.0, 0.08]), slow, -1.0, 2, None),
        ]
    }

    /// Arm 0's grasp of the object lying at `world_from_object` and its pose at the handover, for a
    /// hand starting at `start`: the fingers close across the handle with the hand one way round
    /// or the other, the one that ends the handover turn nearer the hand's start (the wrist turns
    /// least); at the handover the handle points at the receiver.
    /// `spread` scales the grasp's offset and yaw error ([`grasp_spread`]).
    fn give<R: Rng + ?Sized>(&self, world_from_object: &Pose, start: &Pose, spread: f64, rng: &mut R) -> (Pose, Pose) {
        let axis = world_from_object.rotation * Vec3::from(self.towards_receiver);
        let want = Vec3::from(self.receiver_direction);
        let turn = want.y.atan2(want.x) - axis.y.atan2(axis.x);
        let turn = turn - (turn / std::f64::consts::TAU).round() * std::f64::consts::TAU;
        let grip = turned_to(start, yaw_of(world_from_object) + rng.random_range(-0.08 * spread..0.08 * spread));
        let wrapped = |a: f64| (a - (a / std::f64::consts::TAU).round() * std::f64::consts::TAU).abs();
        let rotation = [grip, Rot::from_axis_angle(&Vec3::z_axis(), std::f64::consts::PI) * grip]
            .into_iter()
            .min_by(|a, b| {
                let end = |r: &Rot| {
                    wrapped(yaw_of(&pose_from_parts(Vec3::zeros(), Rot::from_axis_angle(&Vec3::z_axis(), turn) * r)) - yaw_of(start))
                };
                end(a).total_cmp(&end(b))
            })
            .unwrap_or(grip);
        let g = 0.003 * spread;
        let offset = Vec3::new(rng.random_range(-g..g), rng.random_range(-g..g), rng.random_range(-g..g));
        let grasp = pose_from_parts((world_from_object * nalgebra::Point3::from(Vec3::from(self.give_point_m))).coords + offset, rotation);
        let handover = pose_from_parts(
            Vec3::from(self.handover_m)
                + Vec3::new(rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01)),
            Rot::from_axis_angle(&Vec3::z_axis(), turn) * rotation,
        );
        (grasp, handover)
    }

    /// Records one demo from the environment's present state (call `reset` first), the operators
    /// moving in `style`.
    ///
    /// # Errors
    /// The environment's error if a step fails, [`EnvError::Fatal`] if the object is missing.
    pub fn record<E: TwoArmEnvironment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        style: Style,
        rng: &mut R,
    ) -> Result<TwoArmAttempt, EnvError> {
        let world_from_object = object_pose(&*env, &self.object)?;
        let (grasp, handover) = self.give(&world_from_object, &env.eef_pose(0), grasp_spread(style), rng);
        let (fast, slow) = (rng.random_range(0.012..0.02), rng.random_range(0.004..0.007));
        let lifted = raised(&grasp, rng.random_range(0.12..0.16));
        let mut give = vec![
            ArmLeg::fixed(raised(&grasp, rng.random_range(0.06..0.09)), fast, -1.0, rng.random_range(0..3), None),
            ArmLeg::fixed(grasp, slow, -1.0, rng.random_range(2..4), None),
            ArmLeg::fixed(grasp, slow, 1.0, rng.random_range(10..14), None),
            ArmLeg::fixed(lifted, slow, 1.0, 0, None),
            ArmLeg::fixed(handover, fast, 1.0, rng.random_range(4..7), None),
        ];
        // Let go once arm 1 has closed on the handle (its third leg), then back off.
        give.extend(Self::let_go(slow, 3, rng));
        // Only once the hammer is held still at the handover (arm 0's fifth leg done).
        let mut receive = self.receive(fast, slow, 5, rng).to_vec();
        // Lift once arm 0 has let go and backed off.
        receive.push(ArmLeg::new(Goal::Moved([0.0, 0.05, 0.05]), slow, 1.0, 6, Some(7)));
        follow(env, &[give, receive], style, rng)
    }
}

/// How much wider than the careful operator's a style's grasp offsets and yaw errors are drawn:
/// twice for a person at a teleoperation device, as the one-arm demonstrator's.
fn grasp_spread(style: Style) -> f64 {
    if style == Style::Human { 2.0 } else { 1.0 }
}

/// `world_from_object` of `object` now.
fn object_pose<E: TwoArmEnvironment + ?Sized>(env: &E, object: &str) -> Result<Pose, EnvError> {
    env.object_poses().get(object).copied().ok_or_else(|| EnvError::Fatal { reason: format!("the scene has no object {object:?}") })
}

/// robosuite's (and robomimic's) Two Arm Transport, scripted as an operator pair does it: arm 0
/// lifts the lid off the start bin by its handle and lays it on the table beside the bin, grasps
/// the hammer in the bin by the handle near its head, lifts it out and carries it to the handover
/// point (as [`TwoArmHandoverScript`] does); meanwhile arm 1 takes the trash out of the target bin,
/// drops it into the trash bin and waits to the side. Once the hammer is held at the handover arm 1
/// grasps the handle's other end; only then arm 0 lets go and backs off, and only then arm 1
/// carries the hammer over the target bin and lowers it in.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoArmTransportScript {
    /// How arm 0 gives the hammer and arm 1 receives it (`object` is robosuite's `payload`).
    pub handover: TwoArmHandoverScript,
    /// The lid (its handle at `lid_handle_m` in its frame, long along its y).
    pub lid: String,
    /// The lid handle's centre in the lid's frame (m).
    pub lid_handle_m: [f64; 3],
    /// Where the lid is laid: its handle moved this far from where it was (m, world frame).
    pub lid_aside_m: [f64; 3],
    /// The trash (a cube), the trash bin and the target bin.
    pub trash: String,
    /// The bin the trash goes to.
    pub trash_bin: String,
    /// The bin the hammer goes to.
    pub target_bin: String,
    /// Where arm 1 waits after the trash (m, world frame).
    pub wait_m: [f64; 3],
    /// Where arm 1's hand goes over the target bin with the hammer: from the bin's origin (m,
    /// world frame): the hammer's length centred over the bin, its handle this high.
    pub place_m: [f64; 3],
}

impl TwoArmTransportScript {
    /// robosuite's Two Arm Transport: its lid (`transport_start_bin_lid`, the handle 5 mm over
    /// its origin), laid 40 cm towards -x on table 0; its hammer (`payload`: the handle along its
    /// z axis, 20 cm long, the head at +z) handed over as Two Arm Handover's; the trash (a 4 cm
    /// cube) dropped from 15 cm over the trash bin; the hammer lowered into the target bin with arm
    /// 1's hand 7 cm towards arm 1 from the bin's centre (the hammer's length centred).
    #[must_use]
    pub fn transport() -> Self {
        Self {
            handover: TwoArmHandoverScript {
                object: "payload".to_owned(),
                give_point_m: [0.0, 0.0, 0.056],
                ..TwoArmHandoverScript::hammer()
            },
            lid: "lid".to_owned(),
            lid_handle_m: [0.0, 0.0, 0.005],
            lid_aside_m: [-0.40, 0.0, -0.02],
            trash: "trash".to_owned(),
            trash_bin: "trash_bin".to_owned(),
            target_bin: "target_bin".to_owned(),
            wait_m: [0.0, 0.28, 1.10],
            place_m: [0.0, 0.07, 0.0],
        }
    }

    /// Records one demo from the environment's present state (call `reset` first), the operators
    /// moving in `style`.
    ///
    /// # Errors
    /// The environment's error if a step fails, [`EnvError::Fatal`] if an object is missing.
    pub fn record<E: TwoArmEnvironment + ?Sized, R: Rng + ?Sized>(
        &self,
        env: &mut E,
        style: Style,
        rng: &mut R,
    ) -> Result<TwoArmAttempt, EnvError> {
        let (fast, slow) = (rng.random_range(0.012..0.02), rng.random_range(0.004..0.007));
        let leg = ArmLeg::new;
        let moved = |x: f64, y: f64, z: f64| Goal::Moved([x, y, z]);
        // Arm 0: the lid, lifted off by its handle (across it: the hand's x along the lid's x)
        // and laid beside the bin.
        let on_lid = |height_m: f64| Goal::OnObject { object: self.lid.clone(), point_m: self.lid_handle_m, height_m, yaw_offset_rad: 0.0 };
        let lift_lid = rng.random_range(0.08..0.11);
        let aside = Vec3::from(self.lid_aside_m) + Vec3::new(rng.random_range(-0.02..0.02), rng.random_range(-0.02..0.02), 0.0);
        let mut give = vec![
            leg(on_lid(rng.random_range(0.06..0.09)), fast, -1.0, rng.random_range(0..3), None),
            leg(on_lid(0.0), slow, -1.0, rng.random_range(2..4), None),
            leg(moved(0.0, 0.0, 0.0), slow, 1.0, rng.random_range(10..14), None),
            leg(moved(0.0, 0.0, lift_lid), slow, 1.0, 0, None),
            leg(moved(aside.x, aside.y, 0.0), fast, 1.0, rng.random_range(0..3), None),
            // The lid's bottom to 2 cm over the table (it was on the bin's rim, 15 cm up).
            leg(moved(0.0, 0.0, aside.z - 0.15 - lift_lid + 0.02), slow, 1.0, 2, None),
            leg(moved(0.0, 0.0, 0.0), slow, -1.0, rng.random_range(6..9), None),
            leg(moved(0.0, 0.0, 0.12), fast, -1.0, 0, None),
        ];
        // Then the hammer out of the bin and to the handover.
        let world_from_hammer = object_pose(&*env, &self.handover.object)?;
        let start = env.eef_pose(0);
        let (grasp, handover) = self.handover.give(&world_from_hammer, &start, grasp_spread(style), rng);
        let carry = rng.random_range(0.008..0.012);
        // Over the bin's walls first (the fingers 10 cm over them), then straight down into it.
        give.extend([
            leg(Goal::Fixed(raised(&grasp, rng.random_range(0.24..0.27))), fast, -1.0, rng.random_range(0..3), None),
            leg(Goal::Fixed(raised(&grasp, rng.random_range(0.06..0.08))), fast, -1.0, 0, None),
            leg(Goal::Fixed(grasp), slow, -1.0, rng.random_range(2..4), None),
            leg(Goal::Fixed(grasp), slow, 1.0, rng.random_range(10..14), None),
            leg(Goal::Fixed(raised(&grasp, rng.random_range(0.22..0.25))), slow, 1.0, 0, None),
            leg(Goal::Fixed(handover), carry, 1.0, rng.random_range(4..7), None),
        ]);
        let at_handover = give.len();
        // Arm 1: the trash, across the cube the way nearer the hand's yaw.
        let world_from_trash = object_pose(&*env, &self.trash)?;
        let hand = env.eef_pose(1);
        let wrapped = |a: f64| (a - (a / std::f64::consts::PI).round() * std::f64::consts::PI).abs();
        let trash_yaw = [0.0, std::f64::consts::FRAC_PI_2]
            .into_iter()
            .min_by(|a, b| {
                wrapped(yaw_of(&world_from_trash) + a - yaw_of(&hand)).total_cmp(&wrapped(yaw_of(&world_from_trash) + b - yaw_of(&hand)))
            })
            .unwrap_or(0.0);
        let on_trash =
            |height_m: f64| Goal::OnObject { object: self.trash.clone(), point_m: [0.0; 3], height_m, yaw_offset_rad: trash_yaw };
        let wait = pose_from_parts(
            Vec3::from(self.wait_m) + Vec3::new(rng.random_range(-0.03..0.03), rng.random_range(-0.03..0.03), 0.0),
            hand.rotation,
        );
        // Over the target bin's walls, then down into it.
        let mut receive = vec![
            leg(on_trash(rng.random_range(0.24..0.27)), fast, -1.0, rng.random_range(0..3), None),
            leg(on_trash(rng.random_range(0.05..0.07)), fast, -1.0, 0, None),
            leg(on_trash(0.0), slow, -1.0, rng.random_range(2..4), None),
            leg(moved(0.0, 0.0, 0.0), slow, 1.0, rng.random_range(10..14), None),
            leg(moved(0.0, 0.0, rng.random_range(0.20..0.23)), slow, 1.0, 0, None),
            leg(
                Goal::Over {
                    object: self.trash_bin.clone(),
                    offset_m: [rng.random_range(-0.03..0.03), rng.random_range(-0.03..0.03), rng.random_range(0.15..0.18)],
                },
                fast,
                1.0,
                0,
                None,
            ),
            leg(moved(0.0, 0.0, 0.0), slow, -1.0, rng.random_range(8..11), None),
            leg(Goal::Fixed(wait), fast, -1.0, 0, None),
        ];
        // The handle, once arm 0 holds the hammer still at the handover.
        receive.extend(self.handover.receive(fast, slow, at_handover, rng));
        let grasped = receive.len();
        // Arm 0 lets go once arm 1 has closed on the handle, then backs off.
        give.extend(TwoArmHandoverScript::let_go(slow, grasped, rng));
        let released = give.len();
        // Arm 1 carries the hammer over the target bin, only once arm 0 is clear, and lowers it in.
        let place = Vec3::from(self.place_m) + Vec3::new(rng.random_range(-0.02..0.02), rng.random_range(-0.02..0.02), 0.0);
        receive.extend([
            leg(moved(0.0, 0.03, 0.05), slow, 1.0, 2, Some(released)),
            leg(
                Goal::Over { object: self.target_bin.clone(), offset_m: [place.x, place.y, rng.random_range(0.14..0.17)] },
                fast,
                1.0,
                rng.random_range(0..3),
                None,
            ),
            leg(
                Goal::Over { object: self.target_bin.clone(), offset_m: [place.x, place.y, rng.random_range(0.02..0.03)] },
                slow,
                1.0,
                2,
                None,
            ),
            leg(moved(0.0, 0.0, 0.0), slow, -1.0, rng.random_range(6..9), None),
            leg(moved(0.0, 0.0, 0.10), fast, -1.0, 2, None),
        ]);
        follow(env, &[give, receive], style, rng)
    }
}

/// One arm as it follows its legs.
struct Follower<'a> {
    legs: &'a [ArmLeg],
    leg: usize,
    /// Where the present leg goes, once it has started.
    goal: Option<Pose>,
    commanded: Pose,
    held: usize,
    /// Steps since the commanded pose reached the goal.
    waited: usize,
    gripper: f64,
    /// A person's moves: the commanded poses planned to the present leg's goal, next first.
    planned: VecDeque<Pose>,
    /// A person's reaction: steps still to wait before the present leg starts (`None`: not drawn).
    reaction: Option<usize>,
    /// Go on once the commanded pose is at the goal, without waiting for the arm to get there.
    impatient: bool,
    /// A person's hand drifting slowly about the commanded pose (m).
    drift: Vec3,
}

/// Steps both arms through their legs, the operators moving in `style`, and records every step.
/// Careful: even, straight moves, each leg held until the arm is there. Hasty: on as soon as the
/// commanded pose is at the goal. Human, per arm: a reaction time at the start and whenever the
/// arm has waited for the other (never between legs the two start together), moves that speed up
/// and slow down, descents before the gripper acts aimed a few millimetres off and corrected or
/// paused partway, a hand drifting by about a millimetre, and now and then no wait for the arm.
/// Only the human style draws from `rng`.
///
/// # Errors
/// The environment's error if a step fails.
pub fn follow<E: TwoArmEnvironment + ?Sized, R: Rng + ?Sized>(
    env: &mut E,
    legs: &[Vec<ArmLeg>; 2],
    style: Style,
    rng: &mut R,
) -> Result<TwoArmAttempt, EnvError> {
    let fatal = |e: EngineError| EnvError::Fatal { reason: e.to_string() };
    let human = style == Style::Human;
    let action_dim: usize = (0..2).map(|a| POSE_ACTION_DIM + env.gripper_dim(a)).sum();
    let initial_state = env.state();
    let mut attempt = TwoArmAttempt {
        index: 0,
        success: false,
        failure: None,
        initial_object_poses: env.object_poses(),
        states: Rows::new(initial_state.len()),
        initial_state,
        actions: Rows::new(action_dim),
        object_poses: BTreeMap::new(),
        subtask_term_signals: BTreeMap::new(),
        arms: (0..2).map(|a| ArmTrack { gripper_actions: Rows::new(env.gripper_dim(a)), ..ArmTrack::default() }).collect(),
    };
    let mut followers: Vec<Follower<'_>> = legs
        .iter()
        .enumerate()
        .map(|(arm, legs)| Follower {
            legs,
            leg: 0,
            goal: None,
            commanded: env.eef_pose(arm),
            held: 0,
            waited: 0,
            gripper: -1.0,
            planned: VecDeque::new(),
            reaction: None,
            impatient: style == Style::Hasty,
            drift: Vec3::zeros(),
        })
        .collect();
    // A bound on the recording: no demo of a scripted table-top task is this long.
    for _ in 0..3000 {
        if followers.iter().all(|f| f.leg >= f.legs.len()) {
            return Ok(attempt);
        }
        // How far each arm is (done: past every leg).
        let progress: Vec<usize> = followers.iter().map(|f| if f.leg < f.legs.len() { f.leg } else { usize::MAX }).collect();
        let mut action = Vec::with_capacity(action_dim);
        for (arm, f) in followers.iter_mut().enumerate() {
            if let Some(leg) = f.legs.get(f.leg)
                && leg.after.is_none_or(|n| progress.get(1 - arm).is_none_or(|&other| other >= n))
            {
                // A reaction before the first leg and after waiting for the other arm; legs the
                // two arms start together (`after` is the leg's own index) start at once.
                let reacts = human && f.goal.is_none() && (f.leg == 0 || leg.after.is_some_and(|n| n != f.leg));
                let reaction = f.reaction.get_or_insert_with(|| if reacts { rng.random_range(3..10) } else { 0 });
                if *reaction > 0 {
                    *reaction -= 1;
                } else {
                    let goal = match f.goal {
                        Some(goal) => goal,
                        None => {
                            let goal = resolve(&leg.goal, &f.commanded, &*env)?;
                            if human {
                                // Precise: the gripper acts once the leg is done (a descent to grasp or to let go).
                                let precise = f.legs.get(f.leg + 1).is_some_and(|next| (next.gripper - leg.gripper).abs() > 0.5);
                                f.planned = human_moves(&f.commanded, &goal, leg.speed_m, precise, rng).into();
                                f.impatient = precise && rng.random_bool(HUMAN_IMPATIENCE);
                            }
                            *f.goal.insert(goal)
                        }
                    };
                    f.gripper = leg.gripper;
                    f.commanded =
                        if human { f.planned.pop_front().unwrap_or(goal) } else { step_towards(&f.commanded, &goal, leg.speed_m) };
                    if f.commanded == goal {
                        f.waited += 1;
                    }
                    // There within 1 cm; an arm that cannot get closer (a joint at its limit) goes
                    // on after a second and a half, as an operator would.
                    let arrived = f.commanded == goal
                        && (f.impatient || (env.eef_pose(arm).translation.vector - goal.translation.vector).norm() < 0.01 || f.waited > 30);
                    if arrived || (f.commanded == goal && f.held > 0) {
                        f.held += 1;
                    }
                    if f.held > leg.hold {
                        (f.leg, f.held, f.waited, f.goal, f.reaction) = (f.leg + 1, 0, 0, None, None);
                        f.impatient = style == Style::Hasty;
                    }
                }
            }
            let mut target = f.commanded;
            if human {
                f.drift = f.drift * 0.8 + uniform_jitter(rng, 7e-4);
                target = pose_from_parts(target.translation.vector + f.drift, target.rotation);
            }
            let pose_action = env.target_pose_to_action(arm, &target);
            let arm_action: Vec<f64> = pose_action.iter().copied().chain(std::iter::repeat_n(f.gripper, env.gripper_dim(arm))).collect();
            let track = attempt.arms.get_mut(arm).ok_or_else(|| EnvError::Fatal { reason: format!("no arm {arm}") })?;
            track.eef_poses.push(env.eef_pose(arm));
            track.target_poses.push(env.action_to_target_pose(arm, &arm_action));
            track.gripper_actions.push(arm_action.get(POSE_ACTION_DIM..).unwrap_or_default()).map_err(fatal)?;
            track.src_demo_labels.push(0);
            track.subtask_labels.push(0);
            track.holding.push(false);
            action.extend(arm_action);
        }
        attempt.states.push(&env.state()).map_err(fatal)?;
        attempt.actions.push(&action).map_err(fatal)?;
        for (name, pose) in env.object_poses() {
            attempt.object_poses.entry(name).or_default().push(pose);
        }
        for (name, value) in env.subtask_term_signals() {
            attempt.subtask_term_signals.entry(name).or_default().push(value);
        }
        env.step(&action)?;
        attempt.success |= env.is_success();
    }
    Err(EnvError::Fatal { reason: "the script did not end within 3000 steps".to_owned() })
}

/// The pose `goal` names now, for a hand commanded at `commanded`.
fn resolve<E: TwoArmEnvironment + ?Sized>(goal: &Goal, commanded: &Pose, env: &E) -> Result<Pose, EnvError> {
    Ok(match goal {
        Goal::Fixed(pose) => *pose,
        Goal::Moved(by) => pose_from_parts(commanded.translation.vector + Vec3::from(*by), commanded.rotation),
        Goal::Over { object, offset_m } => {
            pose_from_parts(object_pose(env, object)?.translation.vector + Vec3::from(*offset_m), commanded.rotation)
        }
        Goal::OnObject { object, point_m, height_m, yaw_offset_rad } => {
            let world_from_object = object_pose(env, object)?;
            let point = (world_from_object * nalgebra::Point3::from(Vec3::from(*point_m))).coords + Vec3::new(0.0, 0.0, *height_m);
            let rotation = turned_to(commanded, yaw_of(&world_from_object) + yaw_offset_rad);
            pose_from_parts(point, rotation)
        }
    })
}

/// `hand`'s rotation turned about the vertical to `yaw` modulo a half turn, the nearest to its own.
fn turned_to(hand: &Pose, yaw: f64) -> Rot {
    let own = yaw_of(hand);
    let target = yaw + ((own - yaw) / std::f64::consts::PI).round() * std::f64::consts::PI;
    Rot::from_axis_angle(&Vec3::z_axis(), target - own) * hand.rotation
}

/// `from` moved towards `to` by at most `speed_m` (and 0.05 rad), along the straight line and the
/// shortest turn; `to` itself once within reach.
fn step_towards(from: &Pose, to: &Pose, speed_m: f64) -> Pose {
    let delta = to.translation.vector - from.translation.vector;
    let angle = from.rotation.angle_to(&to.rotation);
    #[allow(clippy::cast_precision_loss, reason = "a step count, far below 2^52")]
    let steps = (delta.norm() / speed_m.max(1e-6)).max(angle / 0.05).ceil();
    if steps <= 1.0 {
        return *to;
    }
    let f = 1.0 / steps;
    pose_from_parts(from.translation.vector + delta * f, from.rotation.slerp(&to.rotation, f))
}
