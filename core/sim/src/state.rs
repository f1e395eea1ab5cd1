//! What a simulated state tells: the scene's object poses and speeds, the end effector, contacts
//! and grasps. Tasks read their signals, success and observations from it; the environment that
//! steps the physics ([`crate::SimEnv`]) holds one.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; object indices are positions in the scene's objects, built from the task's own list"
)]

use std::sync::Arc;

use mimicgen_engine::pose::Pose;
use mujoco_rs::prelude::*;

use crate::scene::{Scene, pose_from_xpos_xmat};

/// A scene and its MuJoCo data.
pub struct SimState {
    pub(crate) scene: Arc<Scene>,
    pub(crate) data: MjData<Arc<MjModel>>,
    /// For each of the task's [`crate::task_file::Predicate::Ever`] conditions, whether it has
    /// held at some step since the episode's reset.
    pub(crate) ever: Vec<bool>,
}

impl std::fmt::Debug for SimState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimState").field("scene", &self.scene.origin).finish_non_exhaustive()
    }
}

impl SimState {
    /// The scene.
    #[must_use]
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The MuJoCo data (read-only), e.g. for rendering or extra observations.
    #[must_use]
    pub fn data(&self) -> &MjData<Arc<MjModel>> {
        &self.data
    }

    /// The indices of the contacts between a geom of `a` and a geom of `b`.
    fn contacts_between<'a>(&'a self, a: &'a [usize], b: &'a [usize]) -> impl Iterator<Item = usize> + 'a {
        self.data.contact().iter().enumerate().filter_map(move |(i, c)| {
            let (g1, g2) = (usize::try_from(c.geom[0]).unwrap_or(usize::MAX), usize::try_from(c.geom[1]).unwrap_or(usize::MAX));
            ((a.contains(&g1) && b.contains(&g2)) || (a.contains(&g2) && b.contains(&g1))).then_some(i)
        })
    }

    /// Whether any geom of `a` touches any geom of `b`.
    #[must_use]
    pub fn in_contact(&self, a: &[usize], b: &[usize]) -> bool {
        self.contacts_between(a, b).next().is_some()
    }

    /// The finger pads' contacts with object `i`: how many, and the sum of their normal forces
    /// (N, MuJoCo's `mj_contactForce`). With [`SimState::is_grasping`], what a physics comparison
    /// reads per step.
    #[must_use]
    pub fn pad_contacts(&self, object: usize) -> (usize, f64) {
        let geoms = &self.scene.objects[object].geoms;
        let pads: Vec<usize> = self.scene.robot.finger_pads.iter().flatten().copied().collect();
        let (mut count, mut force) = (0, 0.0);
        for i in self.contacts_between(&pads, geoms) {
            let mut wrench = [0.0; 6];
            #[allow(unsafe_code)]
            // SAFETY: `i` indexes one of the data's `ncon` contacts and `wrench` holds the 6
            // values mj_contactForce writes; the data belongs to the scene's model.
            unsafe {
                mujoco_rs::mujoco_c::mj_contactForce(
                    self.scene.model.ffi(),
                    self.data.ffi(),
                    i32::try_from(i).unwrap_or(i32::MAX),
                    &raw mut wrench,
                );
            }
            count += 1;
            force += wrench[0];
        }
        (count, force)
    }

    /// How many contacts the simulation holds now (MuJoCo's `ncon`).
    #[must_use]
    pub fn contact_count(&self) -> usize {
        self.data.contact().len()
    }

    /// robosuite's `_check_grasp`: both finger pads touch the object.
    #[must_use]
    pub fn is_grasping(&self, object: usize) -> bool {
        self.grasps(&self.scene.robot, &self.scene.objects[object].geoms)
    }

    /// robosuite's `_check_grasp` for `robot` (of a two-arm scene) and `geoms`: both its finger
    /// pads touch one of them.
    #[must_use]
    pub fn grasps(&self, robot: &crate::scene::RobotIndices, geoms: &[usize]) -> bool {
        robot.finger_pads.iter().all(|pad| self.in_contact(pad, geoms))
    }

    /// `world_from_object` of the scene's object `i`.
    #[must_use]
    pub fn object_pose(&self, i: usize) -> Pose {
        let body = self.scene.objects[i].body;
        let mat = self.data.xmat()[body];
        pose_from_xpos_xmat(&self.data.xpos()[body], &mat)
    }

    /// Linear speed of object `i` (m/s); 0 for a fixed one.
    #[must_use]
    pub fn object_speed(&self, i: usize) -> f64 {
        self.scene.objects[i].dof_adr.map_or(0.0, |v| {
            let qvel = self.data.qvel();
            (qvel[v].powi(2) + qvel[v + 1].powi(2) + qvel[v + 2].powi(2)).sqrt()
        })
    }

    /// robosuite's flattened state: `[time, qpos, qvel]`.
    #[must_use]
    pub fn flat_state(&self) -> Vec<f64> {
        let mut s = Vec::with_capacity(self.scene.state_dim());
        s.push(self.data.time());
        s.extend_from_slice(self.data.qpos());
        s.extend_from_slice(self.data.qvel());
        s
    }

    /// `qpos[index]` of a flattened robosuite state (`[time, qpos, qvel]`); `None` past its end.
    #[must_use]
    pub fn qpos_in_flat(state: &[f64], index: usize) -> Option<f64> {
        state.get(1 + index).copied()
    }

    /// Restores a flattened robosuite state (`[time, qpos, qvel]`) and forwards the kinematics.
    ///
    /// # Errors
    /// [`mimicgen_engine::EnvError::Fatal`] on a state of the wrong length.
    pub(crate) fn set_flat_state(&mut self, state: &[f64]) -> Result<(), mimicgen_engine::EnvError> {
        if state.len() != self.scene.state_dim() {
            return Err(mimicgen_engine::EnvError::Fatal {
                reason: format!("state has {} values, the scene {} needs {}", state.len(), self.scene.origin, self.scene.state_dim()),
            });
        }
        let nq = self.data.qpos().len();
        self.data.set_time(state[0]);
        self.data.qpos_mut().copy_from_slice(&state[1..=nq]);
        self.data.qvel_mut().copy_from_slice(&state[1 + nq..]);
        self.data.forward();
        Ok(())
    }

    /// `world_from_eef`: the robot's end-effector site.
    #[must_use]
    pub fn eef_pose(&self) -> Pose {
        self.eef_pose_of(&self.scene.robot)
    }

    /// `world_from_eef` of `robot` (of a two-arm scene).
    #[must_use]
    pub fn eef_pose_of(&self, robot: &crate::scene::RobotIndices) -> Pose {
        let site = robot.eef_site;
        pose_from_xpos_xmat(&self.data.site_xpos()[site], &self.data.site_xmat()[site])
    }
}
