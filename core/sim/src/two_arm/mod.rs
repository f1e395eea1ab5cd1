//! Two-arm environments as robosuite 1.4.1 builds them: its own scene (both Pandas, each with
//! robosuite's OSC_POSE controller at 20 Hz, and the task's objects), its resets, signals and
//! success, and its observations (`robot0_*`, `robot1_*`, `object`), implementing the engine's
//! [`mimicgen_engine::two_arm::TwoArmEnvironment`]. Actions are robosuite's two-arm layout: arm
//! 0's pose and gripper (7), then arm 1's (7).
//!
//! The tasks here (`mod.rs`), the environment in `env.rs`.
//!
//! Tasks: Two Arm Lift (robosuite's `TwoArmLift`: a pot lifted by its two handles), Two Arm
//! Handover (robosuite's `TwoArmHandover`: a hammer handed from one arm to the other) and Two Arm
//! Transport (robosuite's `TwoArmTransport`, robomimic's Transport: a hammer taken out of a
//! lidded bin and handed over into another bin, whose trash goes to a trash bin; `transport.rs`).
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; states and actions are checked for length where they come in (set_state, step)"
)]

use mimicgen_engine::pose::Rot;
use mujoco_rs::prelude::*;

use crate::SimError;
use crate::scene::{ConvexCollider, Scene};

/// robosuite 1.4.1's Two Arm Lift scene as its `TwoArmLift` compiles it: two Pandas facing each
/// other across the table ("single-arm-opposed", `robot0_` at y = -0.56 m, `robot1_` at +0.56 m)
/// and its pot with handles, with `{ASSETS}` for robosuite's assets directory
/// (`scripts/make_two_arm_scene.py` writes it).
pub const TWO_ARM_LIFT_XML: &str = include_str!("../../../../viewer_assets/scenes/two_arm_lift.xml");

/// robosuite 1.4.1's Two Arm Handover scene as its `TwoArmHandover` compiles it: the narrow table
/// (0.8 x 0.3 m, centred at y = -0.45 m), the Pandas at y = -0.81 and +0.81 m facing each other,
/// and its hammer (`hammer_root`; the handle along its z axis, the head at its end), of the size
/// robosuite drew when the scene was written (`scripts/make_two_arm_scene.py`).
pub const TWO_ARM_HANDOVER_XML: &str = include_str!("../../../../viewer_assets/scenes/two_arm_handover.xml");

/// robosuite 1.4.1's Two Arm Transport scene as its `TwoArmTransport` compiles it: two tables (0.8
/// x 0.3 m, at y = -0.45 and +0.45 m), the Pandas at y = -0.81 and +0.81 m facing each other, the
/// start bin with its lid and the hammer (`payload_root`) on table 0, the target bin with the trash
/// and the trash bin on table 1 (`scripts/make_two_arm_scene.py`).
pub const TWO_ARM_TRANSPORT_XML: &str = include_str!("../../../../viewer_assets/scenes/two_arm_transport.xml");

/// A robosuite two-arm task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TwoArmTask {
    /// robosuite's `TwoArmLift`: lift the pot by its two handles, its bottom 10 cm over the table.
    Lift,
    /// robosuite's `TwoArmHandover`: arm 0 picks the hammer up and hands it to arm 1, which holds
    /// it by the handle 10 cm over the table with arm 0 let go.
    Handover,
    /// robosuite's `TwoArmTransport`: arm 0 takes the lid off the start bin and the hammer out of
    /// it, and hands the hammer to arm 1, which has meanwhile moved the trash from the target bin
    /// to the trash bin and puts the hammer into the target bin.
    Transport,
}

/// The pot's half height (robosuite's `PotWithHandlesObject.top_offset`).
pub(crate) const POT_HALF_HEIGHT_M: f64 = 0.07;
/// How far over the table the pot's bottom must be (robosuite's `TwoArmLift._check_success`).
pub(crate) const LIFT_M: f64 = 0.10;

impl TwoArmTask {
    /// Every two-arm task.
    pub const ALL: [Self; 3] = [Self::Lift, Self::Handover, Self::Transport];

    /// The name on the command line (`two_arm_lift`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Lift => "two_arm_lift",
            Self::Handover => "two_arm_handover",
            Self::Transport => "two_arm_transport",
        }
    }

    /// The task named `name`.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// robosuite's environment (`env_args.env_name`).
    #[must_use]
    pub fn env_name(self) -> &'static str {
        match self {
            Self::Lift => "TwoArmLift",
            Self::Handover => "TwoArmHandover",
            Self::Transport => "TwoArmTransport",
        }
    }

    /// robosuite's `env_configuration` of the two arms.
    #[must_use]
    pub fn env_configuration(self) -> &'static str {
        match self {
            Self::Lift | Self::Handover | Self::Transport => "single-arm-opposed",
        }
    }

    /// Its variants: D0 robosuite's reset, D1 wider.
    #[must_use]
    pub fn variants(self) -> &'static [&'static str] {
        &["D0", "D1"]
    }

    /// One line on what it is.
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Self::Lift => {
                "two Pandas lift the pot by its handles (robosuite's TwoArmLift); D0 robosuite's reset (0.06 m square, yaw 180 +- 60 deg), D1 0.20 m square"
            }
            Self::Handover => {
                "arm 0 hands the hammer to arm 1 (robosuite's TwoArmHandover); D0 robosuite's reset (0.2 x 0.1 m, any yaw, either face up), D1 0.4 x 0.16 m"
            }
            Self::Transport => {
                "arm 0 uncovers the start bin and hands its hammer to arm 1, which has emptied the target bin's trash into the trash bin and puts the hammer in the target bin (robosuite's TwoArmTransport, robomimic's Transport); D0 robosuite's reset (bins within 5 mm, hammer turned +-30 deg), D1 bins within 4 cm, hammer +-60 deg, trash any yaw"
            }
        }
    }

    /// The task's objects: `(name, body)`.
    #[must_use]
    pub fn objects(self) -> Vec<(String, String)> {
        match self {
            Self::Lift => vec![("pot".to_owned(), "pot_root".to_owned())],
            Self::Handover => vec![("hammer".to_owned(), "hammer_root".to_owned())],
            Self::Transport => transport::OBJECTS.iter().map(|(name, body)| ((*name).to_owned(), (*body).to_owned())).collect(),
        }
    }

    /// Its subtask-end signals, both arms'.
    #[must_use]
    pub fn signal_names(self) -> &'static [&'static str] {
        match self {
            Self::Lift => &["grasp_handle0", "grasp_handle1"],
            Self::Handover => &["lift", "at_handover", "handle_grasp"],
            Self::Transport => &transport::SIGNALS,
        }
    }

    /// Its generation spec (`core/sim/tasks/<name>.two_arm.toml`): each arm's subtasks and the
    /// ties between them.
    #[must_use]
    pub fn spec_toml(self) -> &'static str {
        match self {
            Self::Lift => include_str!("../../tasks/two_arm_lift.two_arm.toml"),
            Self::Handover => include_str!("../../tasks/two_arm_handover.two_arm.toml"),
            Self::Transport => include_str!("../../tasks/two_arm_transport.two_arm.toml"),
        }
    }

    /// Its generation spec, parsed.
    ///
    /// # Errors
    /// [`mimicgen_engine::EngineError::Config`] if the bundled spec does not parse (a build
    /// that changed it).
    pub fn spec(self) -> Result<mimicgen_engine::two_arm::TwoArmSpec, mimicgen_engine::EngineError> {
        mimicgen_engine::two_arm::TwoArmSpec::from_toml_str(self.spec_toml(), &format!("core/sim/tasks/{}.two_arm.toml", self.name()))
    }

    fn xml(self) -> &'static str {
        match self {
            Self::Lift => TWO_ARM_LIFT_XML,
            Self::Handover => TWO_ARM_HANDOVER_XML,
            Self::Transport => TWO_ARM_TRANSPORT_XML,
        }
    }

    /// robomimic's `env_args` for a dataset of this task: both Pandas, each with robosuite's
    /// OSC_POSE, at 20 Hz.
    #[must_use]
    pub fn env_args(self) -> String {
        let controller = serde_json::json!({
            "type": "OSC_POSE", "input_max": 1, "input_min": -1,
            "output_max": [0.05, 0.05, 0.05, 0.5, 0.5, 0.5], "output_min": [-0.05, -0.05, -0.05, -0.5, -0.5, -0.5],
            "kp": 150, "damping": 1, "impedance_mode": "fixed", "kp_limits": [0, 300], "damping_limits": [0, 10],
            "position_limits": null, "orientation_limits": null, "uncouple_pos_ori": true, "control_delta": true,
            "interpolation": null, "ramp_ratio": 0.2
        });
        serde_json::json!({
            "env_name": self.env_name(),
            "type": 1,
            "env_kwargs": {
                "robots": ["Panda", "Panda"],
                "env_configuration": self.env_configuration(),
                "controller_configs": controller,
                "control_freq": 20,
                "has_renderer": false,
                "has_offscreen_renderer": false,
                "ignore_done": true,
                "use_object_obs": true,
                "use_camera_obs": false,
                "camera_depths": false,
                "reward_shaping": false
            }
        })
        .to_string()
    }

    /// Compiles the task's scene (robosuite's, asset paths pointed at the local robosuite assets),
    /// its convex contacts computed by libccd as robosuite's MuJoCo computes them
    /// ([`ConvexCollider::Libccd`]).
    ///
    /// # Errors
    /// [`SimError::Assets`] without local assets, else as [`Scene::compile`]; a scene without a
    /// second arm is [`SimError::MissingName`].
    pub fn scene(self) -> Result<Scene, SimError> {
        let assets = crate::assets::robosuite_assets_dir()?;
        let origin = format!("robosuite's {} scene", self.env_name());
        let xml = self.xml().replace("{ASSETS}", &assets.display().to_string());
        let scene = Scene::compile_with(&xml, &origin, &self.objects(), 20.0, ConvexCollider::Libccd)?;
        if scene.second_robot.is_none() {
            return Err(SimError::MissingName { file: origin, kind: "body".to_owned(), name: "robot1_base".to_owned() });
        }
        Ok(scene)
    }

    /// The two-arm task whose robosuite environment `env_args` (robomimic's JSON) names.
    #[must_use]
    pub fn from_env_args(env_args: &str) -> Option<Self> {
        let value: serde_json::Value = serde_json::from_str(env_args).ok()?;
        let name = value.get("env_name")?.as_str()?;
        Self::ALL.into_iter().find(|t| t.env_name() == name)
    }

    /// Compiles a dataset's scene (its `model_file`: robosuite's XML, asset paths re-pointed at
    /// the local robosuite assets) for this task.
    ///
    /// # Errors
    /// As [`TwoArmTask::scene`].
    pub fn scene_from_model_file(self, xml: &str, origin: &str) -> Result<Scene, SimError> {
        let assets = crate::assets::robosuite_assets_dir()?;
        let scene =
            Scene::compile_with(&crate::assets::remap_asset_paths(xml, &assets), origin, &self.objects(), 20.0, ConvexCollider::Libccd)?;
        if scene.second_robot.is_none() {
            return Err(SimError::MissingName { file: origin.to_owned(), kind: "body".to_owned(), name: "robot1_base".to_owned() });
        }
        Ok(scene)
    }

    /// The site on the top of the (first) table.
    pub(crate) fn table_site(self) -> &'static str {
        match self {
            Self::Lift | Self::Handover => "table_top",
            Self::Transport => "table0_top",
        }
    }

    /// Where `variant` places the task's object: x and y around the table's centre (m). Two Arm
    /// Transport places its six objects itself (`transport.rs`): none here.
    pub(crate) fn placement(self, variant: &str) -> ([f64; 2], [f64; 2]) {
        match (self, variant) {
            (Self::Lift, "D1") => ([-0.10, 0.10], [-0.10, 0.10]),
            (Self::Lift, _) => ([-0.03, 0.03], [-0.03, 0.03]),
            (Self::Handover, "D1") => ([-0.20, 0.20], [-0.08, 0.08]),
            (Self::Handover, _) => ([-0.10, 0.10], [-0.05, 0.05]),
            (Self::Transport, _) => ([0.0, 0.0], [0.0, 0.0]),
        }
    }
}

/// Where the handover is: the hammer's centre within this of [`HANDOVER_XY_M`], this high over
/// the table (the scripted demonstrator holds it there).
pub(crate) const HANDOVER_TOLERANCE_M: f64 = 0.04;
/// The hammer's centre at the handover (x, y; m): halfway between the arms, 5 cm from arm 0's hand.
pub(crate) const HANDOVER_XY_M: [f64; 2] = [0.0, 0.0];
/// How high over the table the hammer is held at the handover (m).
pub(crate) const HANDOVER_HEIGHT_M: f64 = 0.15;
/// How high over the table the hammer must be held at the end (robosuite's `height_threshold`).
pub(crate) const HANDOVER_SUCCESS_M: f64 = 0.10;

/// The sites and geoms a task reads, resolved once.
#[derive(Debug, Clone)]
pub(crate) enum TaskIndices {
    Lift {
        /// Per handle (`handle0` by arm 0, `handle1` by arm 1): its collision geoms.
        handle_geoms: [Vec<usize>; 2],
        /// Per handle: its site.
        handle_sites: [usize; 2],
        /// The pot's centre site.
        center_site: usize,
    },
    Handover {
        /// The handle's geom.
        handle: usize,
        /// The handle's half length and radius, the head's half size (m): robosuite's
        /// `handle_length / 2`, `top_offset`, `head_halfsize`.
        handle_half_length_m: f64,
        handle_radius_m: f64,
        head_half_size_m: f64,
    },
    Transport(transport::Transport),
}

impl TaskIndices {
    pub(crate) fn resolve(task: TwoArmTask, scene: &Scene) -> Result<Self, SimError> {
        let model = &scene.model;
        let missing =
            |kind: &str, name: &str| SimError::MissingName { file: scene.origin.clone(), kind: kind.to_owned(), name: name.to_owned() };
        let site = |name: &str| model.name_to_id(MjtObjBase::mjOBJ_SITE, name).ok_or_else(|| missing("site", name));
        let geom = |name: &str| model.name_to_id(MjtObjBase::mjOBJ_GEOM, name).ok_or_else(|| missing("geom", name));
        match task {
            TwoArmTask::Lift => {
                let handle = |k: usize| -> Result<Vec<usize>, SimError> {
                    let geoms: Vec<usize> = ["c", "-", "+"]
                        .iter()
                        .filter_map(|part| model.name_to_id(MjtObjBase::mjOBJ_GEOM, &format!("pot_handle{k}_{part}")))
                        .collect();
                    if geoms.is_empty() {
                        return Err(missing("geom", &format!("pot_handle{k}_c")));
                    }
                    Ok(geoms)
                };
                Ok(Self::Lift {
                    handle_geoms: [handle(0)?, handle(1)?],
                    handle_sites: [site("pot_handle0")?, site("pot_handle1")?],
                    center_site: site("pot_center")?,
                })
            }
            TwoArmTask::Handover => {
                let (handle, head) = (geom("hammer_handle")?, geom("hammer_head")?);
                let [radius, _, half_length] = model.geom_size()[handle];
                Ok(Self::Handover {
                    handle,
                    handle_half_length_m: half_length,
                    handle_radius_m: radius,
                    head_half_size_m: model.geom_size()[head][1],
                })
            }
            TwoArmTask::Transport => Ok(Self::Transport(transport::Transport::resolve(scene)?)),
        }
    }
}

/// robosuite's orientation of a placed hammer: its placement sampler's turn about y (`w, x, y, z`)
/// multiplied, as if both were `x, y, z, w`, by the hammer's `init_quat` (one of two flips), and
/// the product written to the joint as `w, x, y, z`. The hammer lies on its side, the handle
/// level at a random yaw, either face up.
pub(crate) fn robosuite_hammer_quat(angle: f64, flip: bool) -> Rot {
    let (c, s) = ((angle / 2.0).cos(), (angle / 2.0).sin());
    // The sampler's quaternion read as x, y, z, w.
    let a = nalgebra::Quaternion::new(0.0, c, 0.0, s);
    let init = if flip { [-0.5, -0.5, -0.5, -0.5] } else { [0.5, -0.5, 0.5, -0.5] };
    let b = nalgebra::Quaternion::new(init[3], init[0], init[1], init[2]);
    let product = a * b; // (x, y, z, w) = product.i, j, k, w
    // The joint reads x, y, z, w as w, x, y, z.
    Rot::from_quaternion(nalgebra::Quaternion::new(product.i, product.j, product.k, product.w))
}

mod env;
mod transport;
pub use env::TwoArmSimEnv;
