//! What a viewer needs of a compiled scene, without MuJoCo types: the visible geoms' shapes and
//! colours, and their world poses at recorded states.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; a state is checked against the model's nq before it is read"
)]

use std::collections::BTreeMap;
use std::sync::Arc;

use mimicgen_engine::Pose;
use mujoco_rs::prelude::*;

use crate::{Scene, SimError};

/// MuJoCo's default geom colour: a geom `rgba` other than this overrides its material's colour.
const DEFAULT_RGBA: [f32; 4] = [0.5, 0.5, 0.5, 1.0];
/// Geom groups at or above this one are hidden by MuJoCo's viewer by default.
const FIRST_HIDDEN_GROUP: i32 = 3;

/// A geom's shape in its own frame (MuJoCo's conventions: half sizes, centred).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A plane of these half extents (0 = infinite).
    Plane {
        /// Half extents along x and y.
        half_m: [f64; 2],
    },
    /// A sphere.
    Sphere {
        /// Radius.
        radius_m: f64,
    },
    /// An ellipsoid.
    Ellipsoid {
        /// Semi-axes.
        half_m: [f64; 3],
    },
    /// A capsule along z, centred.
    Capsule {
        /// Radius.
        radius_m: f64,
        /// Half the length of the cylinder part.
        half_length_m: f64,
    },
    /// A cylinder along z, centred.
    Cylinder {
        /// Radius.
        radius_m: f64,
        /// Half its length.
        half_length_m: f64,
    },
    /// A box.
    Box {
        /// Half extents.
        half_m: [f64; 3],
    },
    /// A triangle mesh.
    Mesh {
        /// Vertices in the geom frame.
        vertices: Vec<[f32; 3]>,
        /// Triangles as vertex indices.
        triangles: Vec<[u32; 3]>,
    },
}

/// A geom's world position and row-major rotation matrix, as MuJoCo keeps them.
pub type GeomPose = ([f64; 3], [f64; 9]);

/// What a geom belongs to, so viewers can show the workspace without the arm and the room.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Part {
    /// The arm and its mount.
    Robot,
    /// The gripper and fingers.
    Gripper,
    /// A task object (or a part of one).
    Object,
    /// The table top.
    Table,
    /// Everything else: floor, table legs.
    Arena,
}

impl Part {
    /// Lower-case name (for entity paths).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Robot => "robot",
            Self::Gripper => "gripper",
            Self::Object => "objects",
            Self::Table => "table",
            Self::Arena => "arena",
        }
    }
}

/// One geom a person would see.
#[derive(Debug, Clone, PartialEq)]
pub struct VisibleGeom {
    /// MuJoCo's geom index.
    pub id: usize,
    /// Its name (may be empty).
    pub name: String,
    /// What it belongs to.
    pub part: Part,
    /// Its shape.
    pub shape: Shape,
    /// The colour MuJoCo's renderer would use (material colour unless the geom's own is set).
    pub rgba: [f32; 4],
}

fn is_collision(model: &MjModel, g: usize) -> bool {
    model.geom_contype()[g] != 0 || model.geom_conaffinity()[g] != 0
}

fn geom_rgba(model: &MjModel, g: usize) -> [f32; 4] {
    let own = model.geom_rgba()[g];
    let matid = model.geom_matid()[g];
    #[allow(clippy::float_cmp)] // comparing against MuJoCo's exact default constant
    let own_is_default = own == DEFAULT_RGBA;
    match usize::try_from(matid) {
        Ok(m) if own_is_default => model.mat_rgba()[m],
        _ => own,
    }
}

fn shape(model: &MjModel, g: usize) -> Option<Shape> {
    let size = model.geom_size()[g];
    Some(match model.geom_type()[g] {
        MjtGeomBase::mjGEOM_PLANE => Shape::Plane { half_m: [size[0], size[1]] },
        MjtGeomBase::mjGEOM_SPHERE => Shape::Sphere { radius_m: size[0] },
        MjtGeomBase::mjGEOM_ELLIPSOID => Shape::Ellipsoid { half_m: size },
        MjtGeomBase::mjGEOM_CAPSULE => Shape::Capsule { radius_m: size[0], half_length_m: size[1] },
        MjtGeomBase::mjGEOM_CYLINDER => Shape::Cylinder { radius_m: size[0], half_length_m: size[1] },
        MjtGeomBase::mjGEOM_BOX => Shape::Box { half_m: size },
        MjtGeomBase::mjGEOM_MESH => {
            let mesh = usize::try_from(model.geom_dataid()[g]).ok()?;
            let as_usize = |v: i32| usize::try_from(v).unwrap_or_default();
            let (vadr, vnum) = (as_usize(model.mesh_vertadr()[mesh]), as_usize(model.mesh_vertnum()[mesh]));
            let (fadr, fnum) = (as_usize(model.mesh_faceadr()[mesh]), as_usize(model.mesh_facenum()[mesh]));
            Shape::Mesh {
                vertices: model.mesh_vert().get(vadr..vadr + vnum).unwrap_or_default().to_vec(),
                triangles: model
                    .mesh_face()
                    .get(fadr..fadr + fnum)
                    .unwrap_or_default()
                    .iter()
                    .map(|f| f.map(|i| u32::try_from(i).unwrap_or_default()))
                    .collect(),
            }
        }
        _ => return None,
    })
}

impl Scene {
    /// The geoms a person would see: groups 0-2, not fully transparent, not robosuite's arena
    /// walls (they hide the robot from every outside viewpoint), and for a body that has
    /// visual-only geoms, only those (robosuite doubles every part as visual + collision).
    #[must_use]
    pub fn visible_geoms(&self) -> Vec<VisibleGeom> {
        let model = &self.model;
        let ngeom = model.geom_type().len();
        let mut body_has_visual = vec![false; model.body_parentid().len()];
        for g in 0..ngeom {
            if !is_collision(model, g)
                && model.geom_group()[g] < FIRST_HIDDEN_GROUP
                && let Some(slot) = usize::try_from(model.geom_bodyid()[g]).ok().and_then(|b| body_has_visual.get_mut(b))
            {
                *slot = true;
            }
        }
        (0..ngeom)
            .filter_map(|g| {
                let body = usize::try_from(model.geom_bodyid()[g]).unwrap_or_default();
                let name = model.id_to_name(MjtObjBase::mjOBJ_GEOM, g).unwrap_or_default().to_owned();
                let rgba = geom_rgba(model, g);
                let hidden = name.starts_with("wall")
                    || model.geom_group()[g] >= FIRST_HIDDEN_GROUP
                    || rgba[3] <= 0.0
                    || (is_collision(model, g) && body_has_visual.get(body).copied().unwrap_or(false));
                if hidden {
                    return None;
                }
                let part = self.part_of(body, &name);
                Some(VisibleGeom { id: g, name, part, shape: shape(model, g)?, rgba })
            })
            .collect()
    }

    /// What body `body` (holding geom `geom_name`) belongs to: robosuite's `robot0_` / `mount0_`
    /// bodies are the arm, `gripper0_` the gripper, the task's objects and their sub-bodies
    /// objects, the geom `table_*` (not a leg) the table top, the rest the arena.
    fn part_of(&self, body: usize, geom_name: &str) -> Part {
        let model = &self.model;
        let parents = model.body_parentid();
        let mut b = body;
        loop {
            if self.objects.iter().any(|o| o.body == b) {
                return Part::Object;
            }
            let name = model.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or_default();
            if name.starts_with("gripper0_") {
                return Part::Gripper;
            }
            if name.starts_with("robot0_") || name.starts_with("mount0_") {
                return Part::Robot;
            }
            match usize::try_from(parents[b]) {
                Ok(parent) if parent != b && b != 0 => b = parent,
                _ => break,
            }
        }
        if geom_name.starts_with("table") && !geom_name.starts_with("table_leg") { Part::Table } else { Part::Arena }
    }
}

/// Poses a scene's geoms at recorded states (robosuite's `[time, qpos, qvel]`), with a private
/// simulator state of its own.
pub struct GeomPoser {
    data: MjData<Arc<MjModel>>,
    ids: Vec<usize>,
    fixed: Vec<(String, usize)>,
    origin: String,
}

impl std::fmt::Debug for GeomPoser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GeomPoser").field("geoms", &self.ids.len()).field("origin", &self.origin).finish_non_exhaustive()
    }
}

impl GeomPoser {
    /// A poser for the geoms `ids` of `scene`, which also places the scene's fixed objects (pegs).
    #[must_use]
    pub fn new(scene: &Scene, ids: Vec<usize>) -> Self {
        Self { data: MjData::new(Arc::clone(&scene.model)), ids, fixed: scene.fixed_objects(), origin: scene.origin.clone() }
    }

    /// Values a state must have at least: `1 + nq`.
    #[must_use]
    pub fn min_state_len(&self) -> usize {
        1 + self.data.qpos().len()
    }

    /// Puts the fixed objects (pegs) where `world_from_objects` (an episode's initial object
    /// poses, by name) has them; recorded states do not hold them.
    pub fn place_fixed_objects(&mut self, world_from_objects: &BTreeMap<String, Pose>) {
        for (name, mocap) in &self.fixed {
            if let Some(pose) = world_from_objects.get(name) {
                crate::env::set_mocap_pose(&mut self.data, *mocap, pose);
            }
        }
    }

    /// The world position and row-major rotation of every geom of this poser at `state`.
    ///
    /// # Errors
    /// [`SimError::State`] for a state shorter than [`Self::min_state_len`].
    pub fn poses(&mut self, state: &[f64]) -> Result<Vec<GeomPose>, SimError> {
        let nq = self.data.qpos().len();
        if state.len() <= nq {
            return Err(SimError::State {
                file: self.origin.clone(),
                reason: format!("a state of {} values is too short; the scene needs at least {}", state.len(), 1 + nq),
            });
        }
        self.data.qpos_mut().copy_from_slice(&state[1..=nq]);
        self.data.kinematics();
        let (xpos, xmat) = (self.data.geom_xpos(), self.data.geom_xmat());
        Ok(self.ids.iter().map(|&g| (xpos[g], xmat[g])).collect())
    }
}
