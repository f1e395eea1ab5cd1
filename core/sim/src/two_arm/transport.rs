//! robosuite's Two Arm Transport (`TwoArmTransport`, robomimic's "Transport"): a hammer (robosuite's
//! "payload") lies in a start bin under a lid on one table; on the other table a piece of trash
//! lies in the target bin, beside an empty trash bin. Success: the hammer touches the target bin's
//! base and the trash the trash bin's (robosuite's `_check_success`).
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids come from the compiled model (name_to_id, resolved once) and index that model's own arrays; object indices are positions in the task's own object list"
)]

use std::collections::BTreeMap;
use std::f64::consts::PI;

use mimicgen_engine::pose::{Pose, Rot, Vec3, pose_from_parts, quat_to_xyzw};
use mujoco_rs::prelude::*;
use rand::{Rng as _, RngCore};

use crate::SimError;
use crate::scene::{RobotIndices, Scene, pose_from_xpos_xmat};
use crate::state::SimState;

/// The task's objects, `(name, body)`, in the order of the scene's objects: robosuite's names
/// (`payload` is the hammer).
pub(crate) const OBJECTS: [(&str, &str); 6] = [
    ("payload", "payload_root"),
    ("trash", "trash_main"),
    ("lid", "transport_start_bin_lid_root"),
    ("start_bin", "transport_start_bin_root"),
    ("target_bin", "transport_target_bin_root"),
    ("trash_bin", "transport_trash_bin_root"),
];
const PAYLOAD: usize = 0;
const TRASH: usize = 1;
const LID: usize = 2;
const START_BIN: usize = 3;
const TARGET_BIN: usize = 4;
const TRASH_BIN: usize = 5;

/// The subtask-end signals, both arms'.
pub(crate) const SIGNALS: [&str; 7] =
    ["lid_grasp", "lid_off", "payload_lift", "at_handover", "trash_grasp", "trash_in_bin", "handle_grasp"];

/// robosuite's placements (`TwoArmTransport._get_placement_initializer`): each bin within 5 mm of
/// its spot, the tables at y = -+0.45 m and 0.8 m high.
const START_BIN_XY: [f64; 2] = [0.2, -0.45];
const TARGET_BIN_XY: [f64; 2] = [-0.2, 0.45];
const TRASH_BIN_XY: [f64; 2] = [0.2, 0.45];
/// The placement sampler's `z_offset` (m).
const Z_OFFSET_M: f64 = 0.001;
/// A bin's half height and its walls' thickness (robosuite's `Bin`, `bin_size` 0.3 x 0.3 x 0.15).
const BIN_HALF_HEIGHT_M: f64 = 0.075;
const BIN_WALL_M: f64 = 0.01;
/// The lid's half height (its plate and handle: 0.01 + 0.03 m).
const LID_HALF_HEIGHT_M: f64 = 0.02;
/// The trash's half size (a 4 cm cube).
const TRASH_HALF_M: f64 = 0.02;

/// Where the handover is: the hammer's centre within this (m) of the point over the gap between
/// the tables ([`HANDOVER_XY_M`]), at least [`HANDOVER_HEIGHT_M`] over the tables, held still
/// (slower than [`HANDOVER_STILL_M_S`]): the receiver's grasp is planned relative to it.
const HANDOVER_TOLERANCE_M: f64 = 0.05;
const HANDOVER_STILL_M_S: f64 = 0.03;
const HANDOVER_XY_M: [f64; 2] = [0.0, 0.0];
const HANDOVER_HEIGHT_M: f64 = 0.15;
/// The hammer is lifted once it is this high over the tables: its handle over the bin's walls.
const LIFT_HEIGHT_M: f64 = 0.16;
/// The lid is off once its centre is this far (m) from the start bin's, on a level.
const LID_OFF_M: f64 = 0.25;

/// The geoms and sites the task reads, resolved once.
#[derive(Debug, Clone)]
pub(crate) struct Transport {
    lid_handle: usize,
    target_bin_base: usize,
    trash_bin_base: usize,
    /// The tables' top sites (table 0: the start bin's, table 1: the other two bins').
    table_tops: [usize; 2],
    /// The hammer's half radius (its handle's half width), for its placement.
    handle_radius_m: f64,
}

impl Transport {
    pub(crate) fn resolve(scene: &Scene) -> Result<Self, SimError> {
        let model = &scene.model;
        let missing =
            |kind: &str, name: &str| SimError::MissingName { file: scene.origin.clone(), kind: kind.to_owned(), name: name.to_owned() };
        let geom = |name: &str| model.name_to_id(MjtObjBase::mjOBJ_GEOM, name).ok_or_else(|| missing("geom", name));
        let site = |name: &str| model.name_to_id(MjtObjBase::mjOBJ_SITE, name).ok_or_else(|| missing("site", name));
        let payload_handle = geom("payload_handle")?;
        Ok(Self {
            lid_handle: geom("transport_start_bin_lid_handle")?,
            target_bin_base: geom("transport_target_bin_base")?,
            trash_bin_base: geom("transport_trash_bin_base")?,
            table_tops: [site("table0_top")?, site("table1_top")?],
            handle_radius_m: model.geom_size()[payload_handle][0],
        })
    }

    /// The tables' height (m).
    fn table_z(&self, state: &SimState) -> f64 {
        state.data.site_xpos()[self.table_tops[0]][2]
    }

    /// Where `variant` places every object, drawn as robosuite's reset draws them: `(object
    /// index, world_from_object)`. D0: robosuite's (each bin within 5 mm of its spot, the hammer
    /// on its side in the start bin turned within 30 deg, the trash in the target bin turned within
    /// 54 deg); D1: the bins within 4 cm, the hammer within 60 deg, the trash any way round.
    pub(crate) fn placements(&self, state: &SimState, variant: &str, rng: &mut dyn RngCore) -> Vec<(usize, Pose)> {
        let wide = variant == "D1";
        let (bin_tolerance, hammer_turn, trash_turn) = if wide { (0.04, PI / 3.0, PI) } else { (0.005, PI / 6.0, 0.3 * PI) };
        let z = self.table_z(state);
        let mut near = |xy: [f64; 2]| {
            [xy[0] + rng.random_range(-bin_tolerance..=bin_tolerance), xy[1] + rng.random_range(-bin_tolerance..=bin_tolerance)]
        };
        let (start, target, trash_bin) = (near(START_BIN_XY), near(TARGET_BIN_XY), near(TRASH_BIN_XY));
        let at = |xy: [f64; 2], height: f64, rotation: Rot| pose_from_parts(Vec3::new(xy[0], xy[1], z + Z_OFFSET_M + height), rotation);
        let level = Rot::identity();
        let hammer =
            crate::two_arm::robosuite_hammer_quat(rng.random_range(PI / 2.0 - hammer_turn..=PI / 2.0 + hammer_turn), rng.random_bool(0.5));
        let trash = Rot::from_axis_angle(&Vec3::z_axis(), rng.random_range(-trash_turn..=trash_turn));
        vec![
            (START_BIN, at(start, BIN_HALF_HEIGHT_M, level)),
            (LID, at(start, 2.0 * BIN_HALF_HEIGHT_M + LID_HALF_HEIGHT_M, level)),
            (PAYLOAD, at(start, self.handle_radius_m + BIN_WALL_M, hammer)),
            (TARGET_BIN, at(target, BIN_HALF_HEIGHT_M, level)),
            (TRASH, at(target, TRASH_HALF_M + BIN_WALL_M, trash)),
            (TRASH_BIN, at(trash_bin, BIN_HALF_HEIGHT_M, level)),
        ]
    }

    /// robosuite's `payload_in_target_bin` and `trash_in_trash_bin`: each touches its bin's base.
    fn delivered(&self, state: &SimState) -> (bool, bool) {
        let objects = &state.scene.objects;
        (
            state.in_contact(&objects[PAYLOAD].geoms, &[self.target_bin_base]),
            state.in_contact(&objects[TRASH].geoms, &[self.trash_bin_base]),
        )
    }

    pub(crate) fn signals(&self, state: &SimState, robots: &[RobotIndices; 2]) -> BTreeMap<String, i64> {
        let objects = &state.scene.objects;
        let z = self.table_z(state);
        let lid_held = state.grasps(&robots[0], &[self.lid_handle]);
        let (lid, bin) = (state.object_pose(LID).translation.vector, state.object_pose(START_BIN).translation.vector);
        let payload = state.object_pose(PAYLOAD).translation.vector;
        let arm0_holds = state.grasps(&robots[0], &objects[PAYLOAD].geoms);
        let near = (payload.x - HANDOVER_XY_M[0]).hypot(payload.y - HANDOVER_XY_M[1]) < HANDOVER_TOLERANCE_M
            && state.object_speed(PAYLOAD) < HANDOVER_STILL_M_S;
        let (_, trash_in_bin) = self.delivered(state);
        [
            ("lid_grasp", lid_held),
            ("lid_off", !lid_held && (lid.x - bin.x).hypot(lid.y - bin.y) > LID_OFF_M),
            ("payload_lift", arm0_holds && payload.z - z > LIFT_HEIGHT_M),
            ("at_handover", near && payload.z - z > HANDOVER_HEIGHT_M),
            ("trash_grasp", state.grasps(&robots[1], &objects[TRASH].geoms)),
            ("trash_in_bin", trash_in_bin),
            ("handle_grasp", state.grasps(&robots[1], &objects[PAYLOAD].geoms)),
        ]
        .into_iter()
        .map(|(name, on)| (name.to_owned(), i64::from(on)))
        .collect()
    }

    pub(crate) fn is_success(&self, state: &SimState) -> bool {
        let (payload, trash) = self.delivered(state);
        payload && trash
    }

    pub(crate) fn unmet_success(&self, state: &SimState) -> Vec<String> {
        let (payload, trash) = self.delivered(state);
        [
            (!payload).then(|| "the hammer does not touch the target bin's base".to_owned()),
            (!trash).then(|| "the trash does not touch the trash bin's base".to_owned()),
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    /// robosuite's `object-state` (41 values): the hammer's position and `xyzw` quaternion, the
    /// trash's, the lid handle's, both bins' base positions, the hammer and the lid handle from
    /// arm 0's gripper, the hammer and the trash from arm 1's, and the two deliveries (1 or 0).
    pub(crate) fn object_observation(&self, state: &SimState, robots: &[RobotIndices; 2]) -> Vec<f64> {
        let data = &state.data;
        let mut out = Vec::with_capacity(41);
        let pose = |pose: Pose| {
            let mut v: Vec<f64> = pose.translation.vector.iter().copied().collect();
            v.extend(quat_to_xyzw(&pose.rotation));
            v
        };
        let payload = state.object_pose(PAYLOAD);
        let trash = state.object_pose(TRASH);
        let lid_handle = pose_from_xpos_xmat(&data.geom_xpos()[self.lid_handle], &data.geom_xmat()[self.lid_handle]);
        out.extend(pose(payload));
        out.extend(pose(trash));
        out.extend(pose(lid_handle));
        out.extend(data.geom_xpos()[self.target_bin_base]);
        out.extend(data.geom_xpos()[self.trash_bin_base]);
        let eef = |arm: usize| Vec3::from(data.site_xpos()[robots[arm].eef_site]);
        for (arm, point) in [
            (0, payload.translation.vector),
            (0, lid_handle.translation.vector),
            (1, payload.translation.vector),
            (1, trash.translation.vector),
        ] {
            out.extend((point - eef(arm)).iter().copied());
        }
        let (payload_in, trash_in) = self.delivered(state);
        out.extend([f64::from(u8::from(payload_in)), f64::from(u8::from(trash_in))]);
        out
    }
}
