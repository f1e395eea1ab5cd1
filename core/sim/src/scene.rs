//! A compiled robosuite-style scene: the MuJoCo model plus every name resolved to an index once.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays"
)]

use std::sync::Arc;

use mimicgen_engine::pose::{Pose, Vec3, pose_from_parts};
use mujoco_rs::prelude::*;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

use crate::SimError;

/// A movable object of the task: its body and the collision geoms used for contact checks.
#[derive(Debug, Clone)]
pub struct SceneObject {
    /// Name the task uses (`cubeA`).
    pub name: String,
    /// Name of its body in the MJCF (`cubeA_main`).
    pub body_name: String,
    /// Body whose frame is the object's pose (`cubeA_main`).
    pub body: usize,
    /// Address of its free joint in `qpos` (7 values: xyz, wxyz), if it has one.
    pub qpos_adr: Option<usize>,
    /// Address of its free joint in `qvel` (6 values).
    pub dof_adr: Option<usize>,
    /// Its mocap index, for an object fixed in the world that resets may move (a peg).
    pub mocap: Option<usize>,
    /// Its collision geoms (its body's and its descendants').
    pub geoms: Vec<usize>,
}

/// The arm and gripper of a robosuite scene (prefixes `robot0_`, `gripper0_`).
#[derive(Debug, Clone)]
pub struct RobotIndices {
    /// Which arm it is.
    pub model: &'static crate::robot::RobotModel,
    /// `qpos` addresses of the arm joints.
    pub arm_qpos: Vec<usize>,
    /// `qvel` addresses of the arm joints.
    pub arm_dof: Vec<usize>,
    /// Torque actuators of the arm, with their control ranges.
    pub arm_actuators: Vec<(usize, [f64; 2])>,
    /// `qpos` addresses of the finger joints.
    pub finger_qpos: Vec<usize>,
    /// `qvel` addresses of the finger joints.
    pub finger_dof: Vec<usize>,
    /// Body whose orientation robosuite reports as `robot0_eef_quat` (`robot0_right_hand`).
    pub hand_body: usize,
    /// Position actuators of the fingers, with their control ranges.
    pub finger_actuators: Vec<(usize, [f64; 2])>,
    /// The controlled end-effector site (`gripper0_grip_site`).
    pub eef_site: usize,
    /// Left and right finger pad collision geoms (robosuite's grasp check).
    pub finger_pads: [Vec<usize>; 2],
}

/// A compiled scene with resolved names.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The compiled model, shared by every worker's data.
    pub model: Arc<MjModel>,
    /// The robot's indices (a two-arm scene's first arm, `robot0_`).
    pub robot: RobotIndices,
    /// A two-arm scene's second arm (`robot1_`/`gripper1_`, the same model as the first).
    pub second_robot: Option<RobotIndices>,
    /// The mobile base under the arm, if it stands on one ([`crate::mobile_base`]).
    pub base: Option<crate::mobile_base::BaseIndices>,
    /// The task's objects, in the order the task lists them.
    pub objects: Vec<SceneObject>,
    /// Physics steps per control step (robosuite: 0.05 s / 0.002 s = 25).
    pub substeps: usize,
    /// Where the scene came from, for error messages.
    pub origin: String,
    /// The MJCF compiled (local asset paths, image textures kept: what cameras render).
    pub xml: String,
}

fn id(model: &MjModel, kind: MjtObjBase, name: &str, origin: &str) -> Result<usize, SimError> {
    model.name_to_id(kind, name).ok_or_else(|| SimError::MissingName {
        file: origin.to_owned(),
        kind: format!("{kind:?}").trim_start_matches("mjOBJ_").to_lowercase(),
        name: name.to_owned(),
    })
}

/// `name` (robosuite's, for the first arm: `robot0_joint1`, `gripper0_grip_site`) for arm `arm`.
fn arm_name(name: &str, arm: usize) -> String {
    if arm == 0 {
        return name.to_owned();
    }
    name.replacen("robot0_", &format!("robot{arm}_"), 1).replacen("gripper0_", &format!("gripper{arm}_"), 1)
}

/// The indices of arm `arm` (robosuite's `robot<arm>_`, `gripper<arm>_` prefixes) of `robot_model`.
fn resolve_robot(
    model: &MjModel,
    robot_model: &'static crate::robot::RobotModel,
    arm: usize,
    origin: &str,
) -> Result<RobotIndices, SimError> {
    let named = |kind: MjtObjBase, name: &str| id(model, kind, &arm_name(name, arm), origin);
    let joint = |name: &str| named(MjtObjBase::mjOBJ_JOINT, name);
    let actuator = |name: &str| -> Result<(usize, [f64; 2]), SimError> {
        let a = named(MjtObjBase::mjOBJ_ACTUATOR, name)?;
        Ok((a, model.actuator_ctrlrange()[a]))
    };
    let mut robot = RobotIndices {
        model: robot_model,
        arm_qpos: Vec::new(),
        arm_dof: Vec::new(),
        arm_actuators: Vec::new(),
        finger_qpos: Vec::new(),
        finger_dof: Vec::new(),
        hand_body: named(MjtObjBase::mjOBJ_BODY, "robot0_right_hand")?,
        finger_actuators: Vec::new(),
        eef_site: named(MjtObjBase::mjOBJ_SITE, "gripper0_grip_site")?,
        finger_pads: [
            vec![named(MjtObjBase::mjOBJ_GEOM, robot_model.finger_pads[0])?],
            vec![named(MjtObjBase::mjOBJ_GEOM, robot_model.finger_pads[1])?],
        ],
    };
    for (name, actuator_name) in robot_model.arm_joints.iter().zip(robot_model.arm_actuators) {
        let j = joint(name)?;
        robot.arm_qpos.push(usize::try_from(model.jnt_qposadr()[j]).unwrap_or_default());
        robot.arm_dof.push(usize::try_from(model.jnt_dofadr()[j]).unwrap_or_default());
        robot.arm_actuators.push(actuator(actuator_name)?);
    }
    for name in robot_model.finger_joints {
        let j = joint(name)?;
        robot.finger_qpos.push(usize::try_from(model.jnt_qposadr()[j]).unwrap_or_default());
        robot.finger_dof.push(usize::try_from(model.jnt_dofadr()[j]).unwrap_or_default());
    }
    for actuator_name in robot_model.finger_actuators {
        robot.finger_actuators.push(actuator(actuator_name)?);
    }
    Ok(robot)
}

/// How MuJoCo computes contacts between convex geoms that have no collider of their own
/// (cylinders against boxes, meshes): robosuite 1.4's MuJoCo 2.3 runs libccd; MuJoCo 3.17 runs its
/// native CCD by default, which puts the contacts elsewhere. Three of Two Arm Transport's scripted
/// demos, replayed in robosuite, part from our states by 2 cm within 62 to 189 steps with the
/// native collider (the trash, the lid and the hammer settle otherwise) and after 467 steps or
/// never with libccd (BENCHMARKS.md). Only the simulation changes, never the `model_file` written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ConvexCollider {
    /// MuJoCo 3.17's native CCD (its default).
    #[default]
    Native,
    /// libccd, as the MuJoCo robosuite 1.4 runs computes them (`nativeccd` disabled).
    Libccd,
}

/// The option that makes MuJoCo 3.17 compute convex contacts with libccd.
const LIBCCD_SECTION: &str = "<option><flag nativeccd=\"disable\"/></option>";

impl Scene {
    /// The arms: the first, then a two-arm scene's second.
    #[must_use]
    pub fn robots(&self) -> Vec<&RobotIndices> {
        std::iter::once(&self.robot).chain(self.second_robot.as_ref()).collect()
    }

    /// Compiles `xml` (asset paths already local) and resolves the Panda and the named objects
    /// (`(task name, body name)` pairs, e.g. `("cubeA", "cubeA_main")`).
    ///
    /// # Errors
    /// [`SimError::Compile`] if MuJoCo rejects the XML, [`SimError::MissingName`] for a missing
    /// joint, actuator, site, body or geom.
    ///
    /// An object body without joints that is not a mocap body yet (robosuite's pegs) is made one,
    /// so that resets can move it while it stays fixed during an episode.
    pub fn compile(xml: &str, origin: &str, objects: &[(String, String)], control_freq_hz: f64) -> Result<Self, SimError> {
        Self::compile_with(xml, origin, objects, control_freq_hz, ConvexCollider::Native)
    }

    /// [`Scene::compile`] with convex contacts (cylinders, meshes) computed by `convex`.
    ///
    /// # Errors
    /// As [`Scene::compile`].
    pub fn compile_with(
        xml: &str,
        origin: &str,
        objects: &[(String, String)],
        control_freq_hz: f64,
        convex: ConvexCollider,
    ) -> Result<Self, SimError> {
        let robot_model = crate::robot::detect(|name| xml.contains(&format!("\"{name}\"")));
        let physics_xml =
            crate::robot::for_simulation(&crate::mjcf_edit::with_arena(&crate::mjcf_edit::without_image_textures(xml), "32M"), robot_model);
        let physics_xml = match convex {
            ConvexCollider::Native => physics_xml,
            ConvexCollider::Libccd => crate::mjcf_edit::with_section(&physics_xml, LIBCCD_SECTION),
        };
        let model = compile_mjcf(&physics_xml).map_err(|reason| SimError::Compile { file: origin.to_owned(), reason })?;
        let section = if crate::legacy_contacts::enabled() { crate::legacy_contacts::contact_section(&model) } else { None };
        let model = match section {
            Some(section) => {
                drop(model); // one compiled scene in memory at a time
                compile_mjcf(&crate::mjcf_edit::with_section(&physics_xml, &section))
                    .map_err(|reason| SimError::Compile { file: origin.to_owned(), reason })?
            }
            None => model,
        };
        let mut to_mocap = Vec::new();
        for (_, body_name) in objects {
            let body = id(&model, MjtObjBase::mjOBJ_BODY, body_name, origin)?;
            if model.body_jntnum()[body] == 0 && model.body_mocapid()[body] < 0 {
                if model.body_parentid()[body] != 0 {
                    return Err(SimError::MissingName {
                        file: origin.to_owned(),
                        kind: "joint (or a parent that is the world) of body".to_owned(),
                        name: body_name.clone(),
                    });
                }
                to_mocap.push(body_name.as_str());
            }
        }
        if !to_mocap.is_empty() {
            let mut edited = xml.to_owned();
            for body in to_mocap {
                edited = crate::mjcf_edit::edit_body(&edited, body, &[("mocap", "true".to_owned())], &[])
                    .ok_or_else(|| SimError::MissingName { file: origin.to_owned(), kind: "body tag".to_owned(), name: body.to_owned() })?;
            }
            return Self::compile_with(&edited, origin, objects, control_freq_hz, convex);
        }
        let robot = resolve_robot(&model, robot_model, 0, origin)?;
        let second_robot = if model.name_to_id(MjtObjBase::mjOBJ_BODY, "robot1_base").is_some() {
            Some(resolve_robot(&model, robot_model, 1, origin)?)
        } else {
            None
        };
        let mut scene_objects = Vec::with_capacity(objects.len());
        for (name, body_name) in objects {
            let body = id(&model, MjtObjBase::mjOBJ_BODY, body_name, origin)?;
            let body_i32 = i32::try_from(body).unwrap_or(-1);
            let free =
                (0..model.jnt_bodyid().len()).find(|&j| model.jnt_bodyid()[j] == body_i32 && model.jnt_type()[j] == MjtJoint::mjJNT_FREE);
            let in_subtree = |mut b: i32| loop {
                if b == body_i32 {
                    break true;
                }
                if b <= 0 {
                    break false;
                }
                b = model.body_parentid()[usize::try_from(b).unwrap_or_default()];
            };
            let geoms: Vec<usize> = (0..model.geom_bodyid().len())
                .filter(|&g| in_subtree(model.geom_bodyid()[g]) && (model.geom_contype()[g] != 0 || model.geom_conaffinity()[g] != 0))
                .collect();
            // A fixed object may be drawn only (a serving region painted on the table): it
            // touches nothing. A free one without a collision geom would fall through the table.
            if geoms.is_empty() && model.body_mocapid()[body] < 0 {
                return Err(SimError::MissingName {
                    file: origin.to_owned(),
                    kind: "collision geom of body".to_owned(),
                    name: (*body_name).to_owned(),
                });
            }
            scene_objects.push(SceneObject {
                name: (*name).to_owned(),
                body_name: (*body_name).to_owned(),
                body,
                qpos_adr: free.map(|j| usize::try_from(model.jnt_qposadr()[j]).unwrap_or_default()),
                dof_adr: free.map(|j| usize::try_from(model.jnt_dofadr()[j]).unwrap_or_default()),
                mocap: usize::try_from(model.body_mocapid()[body]).ok(),
                geoms,
            });
        }
        let timestep = model.opt().timestep;
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let substeps = ((1.0 / control_freq_hz) / timestep).round().max(1.0) as usize;
        let base = crate::mobile_base::BaseIndices::resolve(&model);
        Ok(Self {
            model: Arc::new(model),
            robot,
            second_robot,
            base,
            objects: scene_objects,
            substeps,
            origin: origin.to_owned(),
            xml: xml.to_owned(),
        })
    }

    /// Loads a dataset's scene (robosuite's `model_file` XML): re-points its asset paths at the
    /// local robosuite assets, compiles it, and resolves the Panda and `task`'s objects.
    ///
    /// # Errors
    /// [`SimError::Assets`] without local assets, else as [`Scene::compile`].
    pub fn from_model_file(xml: &str, origin: &str, task: &dyn crate::Task) -> Result<Self, SimError> {
        let assets = crate::assets::robosuite_assets_dir()?;
        let scene = Self::compile(&crate::assets::remap_asset_paths(xml, &assets), origin, &task.objects(), 20.0)?;
        scene.check_joints_read(task, origin)?;
        Ok(scene)
    }

    /// [`SimError::TaskJoint`] for the first joint `task` reads that this scene lacks.
    fn check_joints_read(&self, task: &dyn crate::Task, origin: &str) -> Result<(), SimError> {
        match task.joints_read().into_iter().find(|(_, joint)| self.model.name_to_id(MjtObjBase::mjOBJ_JOINT, joint).is_none()) {
            Some((field, joint)) => Err(SimError::TaskJoint { task: task.name().to_owned(), field, joint, file: origin.to_owned() }),
            None => Ok(()),
        }
    }

    /// Composes `task`'s scene from our base scene and its object models, and compiles it.
    ///
    /// # Errors
    /// [`SimError::Assets`] without local assets, else as [`Scene::compile`].
    pub fn for_task(task: &dyn crate::Task) -> Result<Self, SimError> {
        Self::for_task_with_xml(task).map(|(scene, _)| scene)
    }

    /// [`Scene::for_task`], with the composed MJCF (the `model_file` its episodes are written with).
    ///
    /// # Errors
    /// As [`Scene::for_task`].
    pub fn for_task_with_xml(task: &dyn crate::Task) -> Result<(Self, String), SimError> {
        Self::for_task_with_robot(task, &crate::robot::PANDA)
    }

    /// [`Scene::for_task_with_xml`] with `robot` in place of the Panda.
    ///
    /// # Errors
    /// As [`Scene::for_task`].
    pub fn for_task_with_robot(task: &dyn crate::Task, robot: &crate::robot::RobotModel) -> Result<(Self, String), SimError> {
        let origin = if robot.name == crate::robot::PANDA.name {
            format!("composed {} scene", task.name())
        } else {
            format!("composed {} scene with {}", task.name(), robot.robosuite_name)
        };
        Self::compose(task, robot, &task.object_models(), &origin)
    }

    /// The scenes of `task`'s object instances ([`crate::Task::instances`]) with `robot`, each
    /// composed and compiled once: `(label, scene)`; empty for a variant without instances.
    ///
    /// # Errors
    /// As [`Scene::for_task`].
    pub fn instances_for_task(task: &dyn crate::Task, robot: &crate::robot::RobotModel) -> Result<Vec<(String, Self)>, SimError> {
        task.instances()
            .into_iter()
            .map(|(label, models)| {
                let origin = format!("composed {} scene with {} {label}", task.name(), robot.robosuite_name);
                Self::compose(task, robot, &models, &origin).map(|(scene, _)| (label, scene))
            })
            .collect()
    }

    fn compose(
        task: &dyn crate::Task,
        robot: &crate::robot::RobotModel,
        models: &[crate::compose::ObjectModel],
        origin: &str,
    ) -> Result<(Self, String), SimError> {
        let assets = crate::assets::robosuite_assets_dir()?;
        let xml = crate::compose::compose_scene_with(robot, &assets, models, task.table_top_z(), task.robot_offset_m());
        let xml = match task.mobile_base() {
            Some(base) => base.mount(&xml).map_err(|reason| SimError::Compile { file: origin.to_owned(), reason })?,
            None => xml,
        };
        let scene = Self::compile(&xml, origin, &task.objects(), 20.0)?;
        scene.check_joints_read(task, origin)?;
        Ok((scene, xml))
    }

    /// The objects fixed in the world that resets place (pegs): `(object name, mocap index)`.
    #[must_use]
    pub fn fixed_objects(&self) -> Vec<(String, usize)> {
        self.objects.iter().filter_map(|o| o.mocap.map(|m| (o.name.clone(), m))).collect()
    }

    /// `xml` (this scene's MJCF) with the fixed objects (pegs) where `world_from_objects` has them:
    /// the `model_file` of an episode, since robosuite's flattened state does not hold them.
    ///
    /// # Errors
    /// [`SimError::MissingName`] if the XML lacks a fixed object's body.
    pub fn xml_with_fixed_objects(
        &self,
        xml: &str,
        world_from_objects: &std::collections::BTreeMap<String, Pose>,
    ) -> Result<String, SimError> {
        let mut out = xml.to_owned();
        for object in self.objects.iter().filter(|o| o.mocap.is_some()) {
            if let Some(pose) = world_from_objects.get(&object.name) {
                out = crate::mjcf_edit::place_body(&out, &object.body_name, pose).ok_or_else(|| SimError::MissingName {
                    file: self.origin.clone(),
                    kind: "body tag".to_owned(),
                    name: object.body_name.clone(),
                })?;
            }
        }
        Ok(out)
    }

    /// The collision geoms of object `object`'s parts named `part` (`<object>_<part>_g<k>`, on
    /// the object's body, its lid or its drawer: [`crate::compose::Part::name`]).
    #[must_use]
    pub fn part_geoms(&self, object: &str, part: &str) -> Vec<usize> {
        let mut geoms = Vec::new();
        for owner in [object.to_owned(), format!("{object}_lid"), format!("{object}_drawer")] {
            geoms.extend((0..).map_while(|k| self.model.name_to_id(MjtObjBase::mjOBJ_GEOM, &format!("{owner}_{part}_g{k}"))));
        }
        geoms
    }

    /// The names of these geoms (empty for an unnamed one).
    #[must_use]
    pub fn geom_names(&self, geoms: &[usize]) -> Vec<String> {
        geoms.iter().map(|&g| self.model.id_to_name(MjtObjBase::mjOBJ_GEOM, g).unwrap_or_default().to_owned()).collect()
    }

    /// The name of a site.
    #[must_use]
    pub fn site_name(&self, site: usize) -> String {
        self.model.id_to_name(MjtObjBase::mjOBJ_SITE, site).unwrap_or_default().to_owned()
    }

    /// Length of robosuite's flattened state: `[time, qpos, qvel]`.
    #[must_use]
    pub fn state_dim(&self) -> usize {
        1 + usize::try_from(self.model.ffi().nq).unwrap_or_default() + usize::try_from(self.model.ffi().nv).unwrap_or_default()
    }
}

/// Compiles an MJCF string, or loads the model it compiled to before (see [`crate::model_cache`]).
///
/// # Errors
/// MuJoCo's message.
pub fn compile_mjcf(xml: &str) -> Result<MjModel, String> {
    crate::model_cache::load_or_compile(xml, compile_uncached)
}

/// Compiles `xml` and stores the model in the model cache (what `mimicgen compile-model` runs in
/// the child process [`crate::model_cache::compile_in_child`] starts).
///
/// # Errors
/// MuJoCo's message, or why the model could not be stored.
pub fn store_compiled(xml: &str) -> Result<(), String> {
    crate::model_cache::store_compiled_with(xml, compile_uncached)
}

/// Compiles an MJCF string. MuJoCo 3 refuses meshes whose volume is too small to give an inertia
/// (some of Sawyer's visual meshes), which MuJoCo 2.3, robosuite 1.4.1's, accepted: each mesh it
/// names so is given shell inertia, one at a time, and the scene compiled again (only that mesh
/// changes; the XML written to datasets is left as it was).
///
/// MuJoCo's own cache of processed meshes is turned off: it kept about 80 MB of them alive for
/// the rest of the run, for the next compile, which the model cache makes rare.
///
/// # Errors
/// MuJoCo's message.
pub(crate) fn compile_uncached(xml: &str) -> Result<MjModel, String> {
    static NO_ASSET_CACHE: std::sync::Once = std::sync::Once::new();
    NO_ASSET_CACHE.call_once(|| {
        MjCache::current().set_capacity(0);
    });
    const TOO_SMALL: &str = "mesh volume is too small: ";
    let mut xml = std::borrow::Cow::Borrowed(xml);
    for _ in 0..64 {
        let message = match MjModel::from_xml_string(&xml) {
            Ok(model) => return Ok(model),
            Err(e) => format!("{e:?}"),
        };
        let Some(name) = message.split_once(TOO_SMALL).and_then(|(_, rest)| rest.split([' ', '.', '"', '\\']).next()) else {
            return Err(message);
        };
        let tag = format!(r#"<mesh name="{name}""#);
        if !xml.contains(&tag) {
            return Err(message);
        }
        xml = std::borrow::Cow::Owned(xml.replace(&tag, &format!(r#"<mesh inertia="shell" name="{name}""#)));
    }
    MjModel::from_xml_string(&xml).map_err(|e| format!("{e:?}"))
}

/// `world_from_frame` of a frame given by MuJoCo's position and row-major 3x3 rotation.
#[must_use]
pub fn pose_from_xpos_xmat(xpos: &[f64; 3], xmat: &[f64; 9]) -> Pose {
    let r = Matrix3::from_row_slice(xmat);
    pose_from_parts(Vec3::new(xpos[0], xpos[1], xpos[2]), UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)))
}

impl Scene {
    /// The distance between the fingers (m) at each recorded state (robosuite's
    /// `[time, qpos, qvel]`): the finger opening that auto-detection of subtask ends reads. `None`
    /// for a gripper that is not two sliding fingers (the UR5e's Robotiq linkage): detection then
    /// reads the gripper commands and object poses alone.
    ///
    /// # Errors
    /// [`SimError::State`] for states too short for this scene.
    pub fn finger_widths(&self, states: &mimicgen_engine::Rows) -> Result<Option<Vec<f64>>, SimError> {
        self.finger_widths_of(&self.robot, states)
    }

    /// [`Scene::finger_widths`] of `robot` (a two-arm scene's second arm, say).
    ///
    /// # Errors
    /// As [`Scene::finger_widths`].
    pub fn finger_widths_of(&self, robot: &RobotIndices, states: &mimicgen_engine::Rows) -> Result<Option<Vec<f64>>, SimError> {
        let [left, right] = match robot.finger_qpos.as_slice() {
            [l, r] => [*l, *r],
            _ => return Ok(None),
        };
        if states.width() <= 1 + left.max(right) {
            return Err(SimError::State {
                file: self.origin.clone(),
                reason: format!("states have {} values, the fingers are at qpos {left} and {right}", states.width()),
            });
        }
        Ok(Some(states.iter().map(|s| (s[1 + left] - s[1 + right]).abs()).collect()))
    }
}
