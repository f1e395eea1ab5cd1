//! [`DataTask`]: the [`Task`] a task file ([`crate::task_file`]) describes, in one of its
//! variants: scenes sampled from its regions, signals and success from its predicates, the object
//! observation from its terms, and its scripted demonstrator.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::f64::consts::{PI, TAU};

use mimicgen_engine::EnvError;
use mimicgen_engine::coverage::{Coordinate, Dimension};
use mimicgen_engine::demonstrator::PickPlaceScript;
use mimicgen_engine::pose::{Pose, Rot, Vec3, pose_from_parts, quat_from_wxyz};
use rand::{Rng, RngCore};

use crate::compose::ObjectModel;
use crate::state::SimState;
use crate::task::Task;
use crate::task_file::{ObsTerm, Predicate, Region, TaskFile};

/// The task a [`TaskFile`] describes, in one of its variants.
#[derive(Debug, Clone, PartialEq)]
pub struct DataTask {
    file: TaskFile,
    variant: String,
    /// Each object's region in this variant, in object order.
    regions: Vec<Region>,
    /// The variant's object instances: `(label, every object's model)`; empty when it has none.
    instances: Vec<(String, Vec<ObjectModel>)>,
    /// The conditions of every [`Predicate::Ever`] in the signals and success, in the order of
    /// [`SimState`]'s history flags.
    remembered: Vec<Predicate>,
}

impl DataTask {
    /// `file`'s task in `variant` (any case).
    ///
    /// # Errors
    /// A message listing the variants when `variant` is not one of them.
    pub fn new(file: TaskFile, variant: &str) -> Result<Self, String> {
        let wanted = variant.to_ascii_uppercase();
        let Some(variant) = file.variants.iter().find(|v| v.eq_ignore_ascii_case(&wanted)).cloned() else {
            return Err(format!("{} has variants {}, not {variant:?}", file.name, and_list(&file.variants)));
        };
        // Objects of other variants only are not in this one's scene at all.
        let mut file = file;
        file.objects.retain(|o| o.variants.is_empty() || o.variants.contains(&variant));
        let names: Vec<String> = file.objects.iter().map(|o| o.name.clone()).collect();
        file.place_order.retain(|name| names.contains(name));
        let regions = file
            .objects
            .iter()
            .map(|o| o.place.get(&variant).copied().unwrap_or(Region { x: [0.0; 2], y: [0.0; 2], yaw_deg: [0.0; 2], flip: false }))
            .collect();
        // With instances for several objects, every combination (Mobile Kitchen: 3 pans times 3
        // carrots), labelled by its instances joined with `+` in the objects' order.
        let mut instances: Vec<(String, Vec<ObjectModel>)> = Vec::new();
        for (i, object) in file.objects.iter().enumerate() {
            let choices: Vec<&crate::task_file::Instance> = object.instances.iter().filter(|x| x.variants.contains(&variant)).collect();
            if choices.is_empty() {
                continue;
            }
            let base = if instances.is_empty() {
                vec![(String::new(), file.objects.iter().map(|o| o.model.clone()).collect::<Vec<_>>())]
            } else {
                std::mem::take(&mut instances)
            };
            for (label, models) in &base {
                for instance in &choices {
                    let mut models = models.clone();
                    if let Some(slot) = models.get_mut(i) {
                        *slot = instance.model.clone();
                    }
                    let label = if label.is_empty() { instance.label.clone() } else { format!("{label}+{}", instance.label) };
                    instances.push((label, models));
                }
            }
        }
        let mut remembered = Vec::new();
        for predicate in file.signals.values().chain([&file.success]) {
            collect_ever(predicate, &mut remembered);
        }
        Ok(Self { file, variant, regions, instances, remembered })
    }

    /// The task file.
    #[must_use]
    pub fn file(&self) -> &TaskFile {
        &self.file
    }

    /// The variant.
    #[must_use]
    pub fn variant(&self) -> &str {
        &self.variant
    }

    fn index(&self, name: &str) -> Option<usize> {
        self.file.objects.iter().position(|o| o.name == name)
    }

    /// World position of object `name`, or of the grip site for `eef`.
    fn position(&self, env: &SimState, name: &str) -> Vec3 {
        match self.index(name) {
            Some(i) => env.object_pose(i).translation.vector,
            None => env.eef_pose().translation.vector,
        }
    }

    /// Whether `predicate` holds in `env`'s current state.
    #[must_use]
    pub fn holds(&self, predicate: &Predicate, env: &SimState) -> bool {
        // `check` refused every name that is not an object where an object is needed.
        let index = |name: &str| self.index(name).unwrap_or_default();
        match predicate {
            Predicate::Grasped(o) => env.is_grasping(index(o)),
            Predicate::Lifted { object, above_m } => self.position(env, object).z > self.file.table_top_z + above_m,
            Predicate::Contact([a, b]) => {
                // An object's geoms, or those of its parts named `object.part`.
                let geoms = |name: &str| match name.split_once('.') {
                    Some((object, part)) => Cow::Owned(env.scene().part_geoms(object, part)),
                    None => Cow::Borrowed(env.scene().objects.get(index(name)).map(|o| o.geoms.as_slice()).unwrap_or_default()),
                };
                env.in_contact(&geoms(a), &geoms(b))
            }
            Predicate::Inside { object, of, of_point_m, xy_m, dz_m } => {
                let point = match self.index(of) {
                    Some(i) => {
                        let pose = env.object_pose(i);
                        pose.translation.vector + pose.rotation * Vec3::from(*of_point_m)
                    }
                    None => self.position(env, of),
                };
                let d = self.position(env, object) - point;
                xy_m.holds(d.x, d.y) && d.z >= dz_m[0] && d.z <= dz_m[1]
            }
            Predicate::Near { object, point_m, of, of_point_m, within_m } => {
                let point = |name: &str, p: &[f64; 3]| {
                    let pose = env.object_pose(index(name));
                    pose.translation.vector + pose.rotation * Vec3::from(*p)
                };
                (point(object, point_m) - point(of, of_point_m)).norm() < *within_m
            }
            Predicate::Joint { joint, min, max } => {
                // A hinge's bounds are in degrees, a slide's in metres.
                joint_position(env, joint).is_some_and(|(q, hinge)| {
                    let q = if hinge { q.to_degrees() } else { q };
                    q >= *min && q <= *max
                })
            }
            Predicate::Aligned { object, with, tolerance_deg, symmetry_deg } => {
                let yaw = |name: &str| mimicgen_engine::pose::yaw_of(&env.object_pose(index(name)));
                let period = symmetry_deg.to_radians();
                let diff = (yaw(object) - yaw(with)).rem_euclid(period);
                diff.min(period - diff) <= tolerance_deg.to_radians()
            }
            Predicate::Apart { object, from, min_m } => (self.position(env, object) - self.position(env, from)).norm() >= *min_m,
            Predicate::AtRest { object, max_speed_m_s } => env.object_speed(index(object)) < *max_speed_m_s,
            Predicate::Upright { object, tolerance_deg } => {
                let z = env.object_pose(index(object)).rotation * Vec3::z();
                z.z >= tolerance_deg.to_radians().cos()
            }
            Predicate::Ever(p) => {
                let flag = self.remembered.iter().position(|r| r == p.as_ref());
                flag.and_then(|i| env.ever.get(i)).copied().unwrap_or(false)
            }
            Predicate::All(all) => all.iter().all(|p| self.holds(p, env)),
            Predicate::Any(any) => any.iter().any(|p| self.holds(p, env)),
            Predicate::Not(p) => !self.holds(p, env),
        }
    }

    #[allow(
        clippy::indexing_slicing,
        reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays"
    )]
    fn observe(&self, term: &ObsTerm, env: &SimState, out: &mut Vec<f64>) {
        // `check` refused every name that is not an object where an object is needed.
        let index = |name: &str| self.index(name).unwrap_or_default();
        let eef = env.eef_pose().translation.vector;
        match term {
            ObsTerm::Pose(o) => {
                let i = index(o);
                out.extend(env.object_pose(i).translation.vector.iter());
                let [w, x, y, z] = env.data().xquat()[env.scene().objects[i].body];
                out.extend([x, y, z, w]);
            }
            ObsTerm::Position(o) => out.extend(self.position(env, o).iter()),
            ObsTerm::FromEef(o) => out.extend((self.position(env, o) - eef).iter()),
            ObsTerm::ToEef(o) => out.extend((eef - self.position(env, o)).iter()),
            ObsTerm::Between([a, b]) => out.extend((self.position(env, b) - self.position(env, a)).iter()),
            ObsTerm::Joint(j) => out.push(joint_position(env, j).map_or(0.0, |(q, _)| q)),
            ObsTerm::InGripper(o) => {
                let hand = env.data().xquat()[env.scene().robot.hand_body];
                let world_from_gripper =
                    pose_from_parts(eef, Rot::from_quaternion(nalgebra::Quaternion::new(hand[0], hand[1], hand[2], hand[3])));
                let gripper_from_object = world_from_gripper.inverse() * env.object_pose(index(o));
                let q = gripper_from_object.rotation.quaternion();
                let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
                out.extend(gripper_from_object.translation.vector.iter());
                out.extend([sign * q.i, sign * q.j, sign * q.k, sign * q.w]);
            }
        }
    }
}

/// Adds the condition of every [`Predicate::Ever`] in `predicate` to `out`, each once.
fn collect_ever(predicate: &Predicate, out: &mut Vec<Predicate>) {
    match predicate {
        Predicate::Ever(p) => {
            collect_ever(p, out);
            if !out.contains(p) {
                out.push(p.as_ref().clone());
            }
        }
        Predicate::All(all) | Predicate::Any(all) => all.iter().for_each(|p| collect_ever(p, out)),
        Predicate::Not(p) => collect_ever(p, out),
        _ => {}
    }
}

/// Position of joint `name` and whether it is a hinge; `None` if the scene has no such joint.
#[allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays"
)]
fn joint_position(env: &SimState, name: &str) -> Option<(f64, bool)> {
    use mujoco_rs::prelude::*;
    let model = &env.scene().model;
    let j = model.name_to_id(MjtObjBase::mjOBJ_JOINT, name)?;
    let adr = usize::try_from(model.jnt_qposadr()[j]).ok()?;
    Some((env.data().qpos()[adr], model.jnt_type()[j] == MjtJoint::mjJNT_HINGE))
}

fn and_list(items: &[String]) -> String {
    match items {
        [] => String::new(),
        [one] => one.clone(),
        [init @ .., last] => format!("{} and {last}", init.join(", ")),
    }
}

fn uniform(rng: &mut dyn RngCore, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo { rng.random_range(lo..hi) } else { lo }
}

impl Task for DataTask {
    fn name(&self) -> &str {
        &self.file.name
    }

    fn objects(&self) -> Vec<(String, String)> {
        self.file.objects.iter().map(|o| (o.name.clone(), o.model.body_name())).collect()
    }

    fn object_models(&self) -> Vec<ObjectModel> {
        match self.instances.first() {
            Some((_, models)) => models.clone(),
            None => self.file.objects.iter().map(|o| o.model.clone()).collect(),
        }
    }

    fn instances(&self) -> Vec<(String, Vec<ObjectModel>)> {
        self.instances.clone()
    }

    fn joints_read(&self) -> Vec<(String, String)> {
        self.file.joints_read()
    }

    fn obstacles(&self) -> Vec<usize> {
        self.file.objects.iter().enumerate().filter_map(|(i, o)| o.obstacle.then_some(i)).collect()
    }

    #[allow(
        clippy::indexing_slicing,
        reason = "placement_order gives indices of file.objects, and regions and poses have one entry per object"
    )]
    fn sample_scene(&self, rng: &mut dyn RngCore, instance: Option<&str>) -> Result<Vec<Pose>, EnvError> {
        let models = self.instances.iter().find(|(label, _)| Some(label.as_str()) == instance).map(|(_, models)| models);
        // robosuite's `UniformRandomSampler`: objects one by one, each position redrawn (up to
        // 10 000 times) until its circle clears those of the objects placed before it.
        let mut poses = vec![Pose::identity(); self.file.objects.len()];
        let mut placed: Vec<(f64, f64, f64)> = Vec::new();
        for i in self.file.placement_order() {
            let (object, region) = (&self.file.objects[i], self.regions[i]);
            let mut found = None;
            for _ in 0..10_000 {
                let (x, y) = (uniform(rng, region.x), uniform(rng, region.y));
                if placed.iter().all(|(px, py, pr)| (px - x).hypot(py - y) > pr + object.radius_m) {
                    found = Some((x, y));
                    break;
                }
            }
            let (x, y) = found.ok_or_else(|| EnvError::Fatal {
                reason: format!("cannot place {} in {region:?} clear of the objects placed before it", object.name),
            })?;
            let yaw = uniform(rng, region.yaw_deg).to_radians();
            // Drawn only where a region flips, so other tasks' scenes keep their random streams.
            let flipped = region.flip && rng.random_bool(0.5);
            // A fixture of radius 0 (a bin the objects start in) keeps nothing clear.
            if object.radius_m > 0.0 {
                placed.push((x, y, object.radius_m));
            }
            let mut world_from_object = Rot::from_axis_angle(&Vec3::z_axis(), yaw);
            if flipped {
                world_from_object *= Rot::from_axis_angle(&Vec3::x_axis(), PI);
            }
            world_from_object *= quat_from_wxyz(object.init_quat);
            // robosuite's sampler stands an object's bottom on the table: a mesh's origin is
            // above it.
            let model = models.and_then(|m| m.get(i)).unwrap_or(&object.model);
            let z = self.file.table_top_z + object.height_m + model.origin_above_bottom_m();
            poses[i] = pose_from_parts(Vec3::new(x, y, z), world_from_object);
        }
        Ok(poses)
    }

    fn signals(&self, env: &SimState) -> BTreeMap<String, i64> {
        self.file.signals.iter().map(|(name, p)| (name.clone(), i64::from(self.holds(p, env)))).collect()
    }

    fn is_success(&self, env: &SimState) -> bool {
        self.holds(&self.file.success, env)
    }

    fn record_history(&self, env: &mut SimState) {
        if self.remembered.is_empty() {
            return;
        }
        let now: Vec<bool> = self.remembered.iter().map(|p| self.holds(p, env)).collect();
        env.ever.resize(now.len(), false);
        for (flag, holds) in env.ever.iter_mut().zip(now) {
            *flag |= holds;
        }
    }

    fn unmet_success(&self, env: &SimState) -> Option<String> {
        let clauses = match &self.file.success {
            Predicate::All(all) => all.as_slice(),
            one => std::slice::from_ref(one),
        };
        let unmet: Vec<String> = clauses.iter().filter(|p| !self.holds(p, env)).map(Predicate::words).collect();
        (!unmet.is_empty()).then(|| unmet.join(" and "))
    }

    fn object_obs(&self, env: &SimState) -> Vec<f64> {
        let mut obs = Vec::new();
        for entry in &self.file.observation {
            if entry.variants.is_empty() || entry.variants.contains(&self.variant) {
                self.observe(&entry.term, env, &mut obs);
            }
        }
        obs
    }

    fn scripts(&self) -> Vec<PickPlaceScript> {
        self.file.scripts.clone()
    }

    fn coverage_dimensions(&self) -> Vec<Dimension> {
        let mut dims = Vec::with_capacity(self.file.objects.len() * 3);
        for (object, r) in self.file.objects.iter().zip(&self.regions) {
            let [lo, hi] = r.yaw_deg.map(f64::to_radians);
            let yaw = if hi - lo >= TAU - 1e-9 { (-PI, PI) } else { (lo, hi) };
            for (coordinate, (low, high)) in [(Coordinate::X, (r.x[0], r.x[1])), (Coordinate::Y, (r.y[0], r.y[1])), (Coordinate::Yaw, yaw)]
            {
                dims.push(Dimension { object: object.name.clone(), coordinate, low, high });
            }
        }
        dims
    }

    fn table_top_z(&self) -> f64 {
        self.file.table_top_z
    }

    fn robot_offset_m(&self) -> [f64; 2] {
        self.file.robot_offset_m
    }

    fn mobile_base(&self) -> Option<crate::mobile_base::MobileBaseModel> {
        self.file.mobile_base
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn each_mug_stands_its_own_bottom_on_the_table() {
        let task = crate::registry::task("mug_cleanup", "O2").unwrap_or_else(|e| panic!("{e}"));
        let mut heights = Vec::new();
        for (label, models) in task.instances() {
            let mut rng = rand::rngs::StdRng::seed_from_u64(1);
            let poses = task.sample_scene(&mut rng, Some(&label)).unwrap_or_else(|e| panic!("{e}"));
            let mug = task.objects().iter().position(|(name, _)| name == "object").unwrap_or_default();
            let z = poses[mug].translation.vector.z - task.table_top_z();
            let bottom = models[mug].origin_above_bottom_m();
            assert!((z - 0.001 - bottom).abs() < 1e-12, "{label}: origin {z} above the table, its bottom {bottom} below it");
            heights.push(bottom);
        }
        // The twelve mugs' origins stand 1.8 to 4.2 cm above their bottoms.
        let (low, high) = heights.iter().fold((f64::MAX, f64::MIN), |(l, h), z| (l.min(*z), h.max(*z)));
        assert!((low, high) == (0.018, 0.0423), "{low} {high}");
    }

    #[test]
    fn the_hammer_lies_with_its_handle_along_x_flipped_half_the_time() {
        let task = crate::registry::task("hammer_cleanup", "D0").unwrap_or_else(|e| panic!("{e}"));
        let hammer = task.objects().iter().position(|(name, _)| name == "hammer").unwrap_or_default();
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut face_left = 0;
        for _ in 0..200 {
            let poses = task.sample_scene(&mut rng, None).unwrap_or_else(|e| panic!("{e}"));
            let r = poses[hammer].rotation;
            // robosuite's frame: z along the handle, to world +x; y vertical; x across, +y or -y.
            assert!((r * Vec3::z() - Vec3::x()).norm() < 1e-9, "{:?}", r * Vec3::z());
            assert!((r * Vec3::y()).z.abs() > 1.0 - 1e-9);
            face_left += usize::from((r * Vec3::x()).y > 0.0);
        }
        assert!((70..=130).contains(&face_left), "{face_left} of 200 unflipped");
    }
}
