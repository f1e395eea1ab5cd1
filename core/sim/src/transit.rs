//! The arm's configuration space for planned transit ([`mimicgen_engine::transit`]), over MuJoCo's
//! own collision detection.
//!
//! A [`Planning`] model is a copy of the scene's with every robot and object geom inflated by a
//! clearance margin, so that a planned path keeps that distance from the scene while the controller tracks
//! it. A [`ArmSpace`] is made for one transit from the environment's present state: it copies the
//! state into scratch data, notes which objects the gripper holds (they move with the hand and
//! are checked too) and which contacts exist already (allowed along the path: a held object
//! touching the fingers, a cube resting under an open gripper).
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; configurations have one value per arm joint (ArmSpace makes them)"
)]

use std::collections::BTreeSet;
use std::sync::Arc;

use mimicgen_engine::pose::{Pose, quat_to_wxyz};
use mimicgen_engine::transit::TransitSpace;
use mujoco_rs::prelude::*;
use nalgebra::{DMatrix, DVector};

use crate::osc::orientation_error;
use crate::scene::{Scene, pose_from_xpos_xmat};

/// How far (m) planned paths keep the robot, and what it holds, from everything else: room for
/// the controller's tracking error (about 1.5 cm at the planner's cruising speed).
pub const CLEARANCE_M: f64 = 0.015;

/// The scene's model with the robot's geoms inflated by [`CLEARANCE_M`], and which geoms are the
/// robot's. Made once per scene and environment.
pub struct Planning {
    model: Arc<MjModel>,
    /// The model it was made from (to notice a change of scene).
    source: Arc<MjModel>,
    /// Per geom: part of the robot (arm, gripper, mount).
    robot_geom: Vec<bool>,
}

impl Planning {
    /// The planning model of `scene`.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        let mut model = (*scene.model).clone();
        let robot_geom = robot_geoms(scene);
        // The objects' geoms too, so that a held object keeps the clearance (a pair's margin is
        // the larger of its two geoms', so two inflated geoms keep the same distance).
        let mut inflated = robot_geom.clone();
        for g in scene.objects.iter().flat_map(|o| &o.geoms) {
            if let Some(i) = inflated.get_mut(*g) {
                *i = true;
            }
        }
        for (margin, inflate) in model.geom_margin_mut().iter_mut().zip(&inflated) {
            if *inflate {
                *margin += CLEARANCE_M;
            }
        }
        Self { model: Arc::new(model), source: Arc::clone(&scene.model), robot_geom }
    }

    /// Whether this was made for `scene`'s model.
    #[must_use]
    pub fn is_for(&self, scene: &Scene) -> bool {
        Arc::ptr_eq(&self.source, &scene.model)
    }
}

/// Per geom of `scene`: whether it is the robot's (arm, gripper, mount: the bodies under the
/// hand's top-level ancestor).
#[must_use]
pub fn robot_geoms(scene: &Scene) -> Vec<bool> {
    let model = &scene.model;
    let roots = model.body_rootid();
    let root = roots[scene.robot.hand_body];
    model.geom_bodyid().iter().map(|&b| usize::try_from(b).ok().and_then(|b| roots.get(b)).is_some_and(|&r| r == root)).collect()
}

/// One transit's configuration space: the arm's joints, from the state it was made in.
pub struct ArmSpace<'a> {
    scene: &'a Scene,
    planning: &'a Planning,
    data: MjData<Arc<MjModel>>,
    start: Vec<f64>,
    limits: Vec<[f64; 2]>,
    /// Held objects: `(qpos address, eef_from_object)`.
    held: Vec<(usize, Pose)>,
    /// Per geom: the robot's or a held object's.
    moving: Vec<bool>,
    /// Geom pairs touching where the path starts.
    allowed: BTreeSet<(usize, usize)>,
    jacp: Vec<f64>,
    jacr: Vec<f64>,
    /// The posture the controller's null-space term pulls the arm towards.
    posture: Vec<f64>,
}

/// Gain of the posture term per inverse-kinematics iteration (a fraction of the way there).
const POSTURE_GAIN: f64 = 0.2;
/// Inverse-kinematics iterations at least, so that the posture term has acted.
const SETTLE_ITERATIONS: usize = 15;

impl<'a> ArmSpace<'a> {
    /// The space from `data`'s present state, holding the objects of `scene` listed in `held`,
    /// for a controller whose null-space term pulls towards `posture`.
    #[must_use]
    pub fn new(scene: &'a Scene, planning: &'a Planning, state: &MjData<Arc<MjModel>>, held: &[usize], posture: &[f64]) -> Self {
        let mut data = MjData::new(Arc::clone(&planning.model));
        data.qpos_mut().copy_from_slice(state.qpos());
        data.mocap_pos_mut().copy_from_slice(state.mocap_pos());
        data.mocap_quat_mut().copy_from_slice(state.mocap_quat());
        let model = &planning.model;
        let (qpos, ranges, limited) = (model.jnt_qposadr(), model.jnt_range(), model.jnt_limited());
        let limits = scene
            .robot
            .arm_qpos
            .iter()
            .map(|&adr| {
                let j = qpos.iter().position(|&a| usize::try_from(a).ok() == Some(adr));
                match j {
                    Some(j) if limited[j] => ranges[j],
                    _ => [-std::f64::consts::PI, std::f64::consts::PI],
                }
            })
            .collect();
        let start = scene.robot.arm_qpos.iter().map(|&i| state.qpos()[i]).collect();
        let eef = site_pose(state, scene.robot.eef_site);
        let mut moving = planning.robot_geom.clone();
        let mut carried = Vec::new();
        for &i in held {
            let object = &scene.objects[i];
            if let Some(adr) = object.qpos_adr {
                let q = &state.qpos()[adr..adr + 7];
                let world_from_object = mimicgen_engine::pose::pose_from_parts(
                    mimicgen_engine::pose::Vec3::new(q[0], q[1], q[2]),
                    mimicgen_engine::pose::quat_from_wxyz([q[3], q[4], q[5], q[6]]),
                );
                carried.push((adr, eef.inverse() * world_from_object));
                for &g in &object.geoms {
                    if let Some(m) = moving.get_mut(g) {
                        *m = true;
                    }
                }
            }
        }
        let nv = usize::try_from(model.ffi().nv).unwrap_or_default();
        let mut space = Self {
            scene,
            planning,
            data,
            start,
            limits,
            held: carried,
            moving,
            allowed: BTreeSet::new(),
            jacp: vec![0.0; 3 * nv],
            jacr: vec![0.0; 3 * nv],
            posture: posture.to_vec(),
        };
        let start = space.start.clone();
        space.pose_robot(&start);
        space.collide();
        space.allowed = space.touching().collect();
        space
    }

    /// Puts the arm at `q` and what it holds with it; kinematics computed.
    fn pose_robot(&mut self, q: &[f64]) {
        for (&adr, v) in self.scene.robot.arm_qpos.iter().zip(q) {
            self.data.qpos_mut()[adr] = *v;
        }
        self.kinematics();
        if !self.held.is_empty() {
            let eef = site_pose(&self.data, self.scene.robot.eef_site);
            for (adr, eef_from_object) in &self.held {
                let pose = eef * eef_from_object;
                let qpos = self.data.qpos_mut();
                qpos[*adr..*adr + 3].copy_from_slice(pose.translation.vector.as_slice());
                qpos[*adr + 3..*adr + 7].copy_from_slice(&quat_to_wxyz(&pose.rotation));
            }
            self.kinematics();
        }
    }

    fn kinematics(&mut self) {
        #[allow(unsafe_code)]
        // SAFETY: the data was made from this model.
        unsafe {
            mujoco_rs::mujoco_c::mj_kinematics(self.planning.model.ffi(), self.data.ffi_mut());
        }
    }

    fn collide(&mut self) {
        #[allow(unsafe_code)]
        // SAFETY: the data was made from this model, and its kinematics are current.
        unsafe {
            mujoco_rs::mujoco_c::mj_collision(self.planning.model.ffi(), self.data.ffi_mut());
        }
    }

    /// The geom pairs (lower id first) where something moving touches something that is not.
    fn touching(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.data.contact().iter().filter_map(|c| {
            let (a, b) = (usize::try_from(c.geom[0]).ok()?, usize::try_from(c.geom[1]).ok()?);
            (self.moving.get(a)? != self.moving.get(b)?).then_some((a.min(b), a.max(b)))
        })
    }
}

impl ArmSpace<'_> {
    /// The geom pairs (by name) that make configuration `q` not free: what a failed plan hit.
    pub fn collisions_at(&mut self, q: &[f64]) -> Vec<(String, String)> {
        self.pose_robot(q);
        self.collide();
        let pairs: Vec<(usize, usize)> = self.touching().filter(|pair| !self.allowed.contains(pair)).collect();
        pairs.into_iter().map(|(a, b)| (geom_name(&self.planning.model, a), geom_name(&self.planning.model, b))).collect()
    }
}

fn geom_name(model: &MjModel, geom: usize) -> String {
    model.id_to_name(MjtObjBase::mjOBJ_GEOM, geom).map_or_else(|| format!("geom {geom}"), str::to_owned)
}

/// `world_from_site` of `site` in `data` (kinematics current).
fn site_pose(data: &MjData<Arc<MjModel>>, site: usize) -> Pose {
    pose_from_xpos_xmat(&data.site_xpos()[site], &data.site_xmat()[site])
}

impl TransitSpace for ArmSpace<'_> {
    fn joint_limits(&self) -> Vec<[f64; 2]> {
        self.limits.clone()
    }

    fn joints(&self) -> Vec<f64> {
        self.start.clone()
    }

    fn is_free(&mut self, q: &[f64]) -> bool {
        self.pose_robot(q);
        self.collide();
        self.touching().all(|pair| self.allowed.contains(&pair))
    }

    fn eef_pose_at(&mut self, q: &[f64]) -> Pose {
        for (&adr, v) in self.scene.robot.arm_qpos.iter().zip(q) {
            self.data.qpos_mut()[adr] = *v;
        }
        self.kinematics();
        site_pose(&self.data, self.scene.robot.eef_site)
    }

    /// Damped least squares on the site Jacobian with the controller's posture term in its null
    /// space, within the joint limits (100 iterations at most; converged at 1 mm and 0.01 rad).
    fn inverse_kinematics(&mut self, world_from_eef: &Pose, seed: &[f64]) -> Option<Vec<f64>> {
        self.solve(world_from_eef, seed, 0)
    }

    fn settle(&mut self, q: &[f64]) -> Option<Vec<f64>> {
        let pose = self.eef_pose_at(q);
        self.solve(&pose, q, SETTLE_ITERATIONS)
    }
}

impl ArmSpace<'_> {
    /// [`TransitSpace::inverse_kinematics`], iterating at least `min_iterations` times.
    fn solve(&mut self, world_from_eef: &Pose, seed: &[f64], min_iterations: usize) -> Option<Vec<f64>> {
        let robot = &self.scene.robot;
        let n = robot.arm_dof.len();
        let nv = self.jacp.len() / 3;
        let goal_rot = world_from_eef.rotation.to_rotation_matrix().into_inner();
        let mut q = seed.to_vec();
        for iteration in 0..100 {
            for (&adr, v) in robot.arm_qpos.iter().zip(&q) {
                self.data.qpos_mut()[adr] = *v;
            }
            #[allow(unsafe_code)]
            // SAFETY: the data was made from this model; the buffers hold the 3 nv values
            // mj_jacSite writes; mj_comPos after mj_kinematics is what the Jacobian reads.
            unsafe {
                let (m, d) = (self.planning.model.ffi(), self.data.ffi_mut());
                mujoco_rs::mujoco_c::mj_kinematics(m, d);
                mujoco_rs::mujoco_c::mj_comPos(m, d);
                let site = i32::try_from(robot.eef_site).unwrap_or_default();
                mujoco_rs::mujoco_c::mj_jacSite(m, d, self.jacp.as_mut_ptr(), self.jacr.as_mut_ptr(), site);
            }
            let now = site_pose(&self.data, robot.eef_site);
            let dp = world_from_eef.translation.vector - now.translation.vector;
            let dr = orientation_error(&goal_rot, &now.rotation.to_rotation_matrix().into_inner());
            if dp.norm() < 1e-3 && dr.norm() < 0.01 && iteration >= min_iterations {
                return Some(q);
            }
            let j = DMatrix::from_fn(6, n, |r, c| {
                if r < 3 { self.jacp[r * nv + robot.arm_dof[c]] } else { self.jacr[(r - 3) * nv + robot.arm_dof[c]] }
            });
            let e = DVector::from_iterator(6, dp.iter().chain(dr.iter()).copied());
            let damped = &j * j.transpose() + DMatrix::identity(6, 6) * 1e-4;
            let lu = damped.lu();
            let dq_task = j.transpose() * lu.solve(&e)?;
            // The posture term, projected into the Jacobian's null space: I - J+ J.
            let towards = DVector::from_iterator(n, self.posture.iter().zip(&q).map(|(p, v)| POSTURE_GAIN * (p - v)));
            let dq_posture = &towards - j.transpose() * lu.solve(&(&j * &towards))?;
            for (((v, d), p), [lo, hi]) in q.iter_mut().zip(dq_task.iter()).zip(dq_posture.iter()).zip(&self.limits) {
                *v = (*v + (d + p).clamp(-0.2, 0.2)).clamp(*lo, *hi);
            }
        }
        None
    }
}
