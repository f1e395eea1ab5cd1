//! An arm on a mobile base: the base scene's arm and its mount given three joints (forward along
//! the world's x, sideways along its y, a turn about the vertical through the arm's base), each
//! driven by a velocity actuator, as robosuite's mobile bases are. An action's base part
//! (`[forward, sideways, turn]` in `[-1, 1]`, in the base's own frame) sets those actuators'
//! speeds, turned into the world's frame at each control step; the arm's pose part is taken in the
//! base's frame ([`crate::env::SimEnv`]).
//!
//! The base glides: it is held at its height by its joints, and the mount's collision geoms (the
//! pedestal, its feet, the controller box) are switched off so that it neither rubs on the floor
//! nor catches on a counter's edge. Its drives run parallel to the counters; a base that ran into
//! one would pass through it (a task's own check, not the physics', if it matters).
//!
//! ```toml
//! [mobile_base]
//! top_speed_m_s = 0.3      # forward or sideways at a full command
//! top_turn_deg_s = 45      # turning at a full command
//! ```

use std::fmt::Write as _;
use std::sync::Arc;

use mimicgen_engine::pose::{Pose, Vec3, pose_from_parts, quat_from_wxyz};
use mujoco_rs::prelude::*;
use serde::Deserialize;

/// The base's joints (and their actuators), in the order of an action's base part.
pub const BASE_JOINTS: [&str; 3] = ["mobile_base_x", "mobile_base_y", "mobile_base_yaw"];
/// The body the base moves: the arm's base, with its mount.
const BASE_BODY: &str = "robot0_base";
/// The mount's collision geoms, switched off on a mobile base.
const MOUNT_GEOMS: [&str; 3] = ["mount0_controller_box_col", "mount0_pedestal_feet_col", "mount0_pedestal_col"];
/// How fast the actuators bring the base to its commanded speed (s): stiff enough that a copied
/// drive ends where the source's did.
const SPEED_TIME_CONSTANT_S: f64 = 0.04;
/// The mass (kg) and the inertia about the vertical (kg m^2) the actuators' gains are set for:
/// the arm with its mount.
const MOVED_MASS_KG: f64 = 300.0;
const MOVED_INERTIA_KG_M2: f64 = 40.0;

/// A task file's `[mobile_base]`: the arm stands on a base that drives.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MobileBaseModel {
    /// Speed forward or sideways at a full command (m/s).
    pub top_speed_m_s: f64,
    /// Turning speed at a full command (deg/s).
    pub top_turn_deg_s: f64,
}

impl MobileBaseModel {
    /// Checks the speeds, naming the field.
    ///
    /// # Errors
    /// A message naming the field out of range.
    pub fn check(&self) -> Result<(), String> {
        if !(self.top_speed_m_s.is_finite() && self.top_speed_m_s > 0.0 && self.top_speed_m_s <= 2.0) {
            return Err(format!("field `mobile_base.top_speed_m_s` {} must be in (0, 2]", self.top_speed_m_s));
        }
        if !(self.top_turn_deg_s.is_finite() && self.top_turn_deg_s > 0.0 && self.top_turn_deg_s <= 360.0) {
            return Err(format!("field `mobile_base.top_turn_deg_s` {} must be in (0, 360]", self.top_turn_deg_s));
        }
        Ok(())
    }

    /// `xml` (a single-arm base scene) with the arm's base on this mobile base.
    ///
    /// # Errors
    /// A message when the scene has no `robot0_base` body or no actuator section.
    pub fn mount(&self, xml: &str) -> Result<String, String> {
        let open = format!("<body name=\"{BASE_BODY}\"");
        let at = xml.find(&open).ok_or_else(|| format!("the base scene has no body {BASE_BODY:?} to put on a mobile base"))?;
        let body_end = at + xml[at..].find('>').ok_or_else(|| format!("body {BASE_BODY:?} is not closed"))? + 1;
        let mut joints = String::new();
        let _ = write!(
            joints,
            "\n      <joint name=\"{}\" type=\"slide\" axis=\"1 0 0\" limited=\"false\"/>\
             \n      <joint name=\"{}\" type=\"slide\" axis=\"0 1 0\" limited=\"false\"/>\
             \n      <joint name=\"{}\" type=\"hinge\" axis=\"0 0 1\" limited=\"false\"/>",
            BASE_JOINTS[0], BASE_JOINTS[1], BASE_JOINTS[2]
        );
        let mut out = format!("{}{joints}{}", &xml[..body_end], &xml[body_end..]);
        for geom in MOUNT_GEOMS {
            out = crate::mjcf_edit::edit_element(&out, "geom", geom, &[("contype", "0".to_owned()), ("conaffinity", "0".to_owned())], &[])
                .unwrap_or(out);
        }
        let (kv_slide, kv_turn) = (MOVED_MASS_KG / SPEED_TIME_CONSTANT_S, MOVED_INERTIA_KG_M2 / SPEED_TIME_CONSTANT_S);
        let turn = self.top_turn_deg_s.to_radians();
        let mut actuators = String::new();
        for (joint, kv, top) in [
            (BASE_JOINTS[0], kv_slide, self.top_speed_m_s),
            (BASE_JOINTS[1], kv_slide, self.top_speed_m_s),
            (BASE_JOINTS[2], kv_turn, turn),
        ] {
            let _ = writeln!(
                actuators,
                "    <velocity name=\"{joint}\" joint=\"{joint}\" kv=\"{kv}\" ctrllimited=\"true\" ctrlrange=\"{} {top}\"/>",
                -top
            );
        }
        let close = out.rfind("  </actuator>").ok_or_else(|| "the base scene has no actuator section".to_owned())?;
        out.insert_str(close, &actuators);
        Ok(out)
    }
}

/// A compiled scene's mobile base.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseIndices {
    /// The moved body (`robot0_base`).
    pub body: usize,
    /// `qpos` addresses of the three joints.
    pub qpos: [usize; 3],
    /// Their actuators, with the top speed each takes (m/s, m/s, rad/s).
    pub actuators: [(usize, f64); 3],
}

impl BaseIndices {
    /// The base of `model`, if it has one (the joints [`BASE_JOINTS`]).
    #[must_use]
    pub fn resolve(model: &MjModel) -> Option<Self> {
        let joint = |name: &str| model.name_to_id(MjtObjBase::mjOBJ_JOINT, name);
        let actuator = |name: &str| {
            let a = model.name_to_id(MjtObjBase::mjOBJ_ACTUATOR, name)?;
            Some((a, model.actuator_ctrlrange().get(a)?[1]))
        };
        let qpos = |name: &str| joint(name).and_then(|j| usize::try_from(*model.jnt_qposadr().get(j)?).ok());
        Some(Self {
            body: model.name_to_id(MjtObjBase::mjOBJ_BODY, BASE_BODY)?,
            qpos: [qpos(BASE_JOINTS[0])?, qpos(BASE_JOINTS[1])?, qpos(BASE_JOINTS[2])?],
            actuators: [actuator(BASE_JOINTS[0])?, actuator(BASE_JOINTS[1])?, actuator(BASE_JOINTS[2])?],
        })
    }

    /// `world_from_base` in `data` (after a forward pass).
    #[must_use]
    pub fn world_from_base(&self, data: &MjData<Arc<MjModel>>) -> Pose {
        let p = data.xpos().get(self.body).copied().unwrap_or_default();
        let q = data.xquat().get(self.body).copied().unwrap_or([1.0, 0.0, 0.0, 0.0]);
        pose_from_parts(Vec3::new(p[0], p[1], p[2]), quat_from_wxyz(q))
    }

    /// The engine's view of the base in `data`: its frame and how far a full command moves it in
    /// one control step of `control_dt_s`.
    #[must_use]
    pub fn describe(&self, data: &MjData<Arc<MjModel>>, control_dt_s: f64) -> mimicgen_engine::base::MobileBase {
        mimicgen_engine::base::MobileBase {
            world_from_base: self.world_from_base(data),
            max_step_m: self.actuators[0].1 * control_dt_s,
            max_turn_rad: self.actuators[2].1 * control_dt_s,
        }
    }

    /// Sets the actuators for `command` (`[forward, sideways, turn]`, each clipped to `[-1, 1]`,
    /// in the base's frame), turned into the world's frame by the base's present heading.
    pub fn drive(&self, data: &mut MjData<Arc<MjModel>>, command: &[f64]) {
        let c = |i: usize| command.get(i).map_or(0.0, |v| v.clamp(-1.0, 1.0));
        let yaw = data.qpos().get(self.qpos[2]).copied().unwrap_or_default();
        let (forward, sideways) = (c(0) * self.actuators[0].1, c(1) * self.actuators[1].1);
        let speeds = [yaw.cos() * forward - yaw.sin() * sideways, yaw.sin() * forward + yaw.cos() * sideways, c(2) * self.actuators[2].1];
        let ctrl = data.ctrl_mut();
        for ((actuator, _), speed) in self.actuators.iter().zip(speeds) {
            if let Some(slot) = ctrl.get_mut(*actuator) {
                *slot = speed;
            }
        }
    }
}
