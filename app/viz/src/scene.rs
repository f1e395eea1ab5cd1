//! The MuJoCo scene as Rerun primitives: every visible geom logged once, then its pose per step.

use std::sync::Arc;

use mimicgen_engine::Rows;
use mujoco_rs::prelude::*;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use rerun::{RecordingStream, TimeColumn};

use crate::VizError;

/// MuJoCo's default geom colour: a geom `rgba` other than this overrides its material's colour.
const DEFAULT_RGBA: [f32; 4] = [0.5, 0.5, 0.5, 1.0];
/// Geom groups at or above this one are hidden by MuJoCo's viewer by default.
const FIRST_HIDDEN_GROUP: i32 = 3;
/// Largest half extent drawn for a plane (MuJoCo's size 0 is infinite; robosuite's floor is 3 m).
const PLANE_HALF_M: f32 = 1.0;

/// One visible geom and the entity it is logged under.
#[derive(Debug, Clone)]
struct GeomEntity {
    id: usize,
    path: String,
}

/// The visible geoms of a compiled scene and a private `MjData` to pose them from recorded states.
pub struct SceneLogger {
    model: Arc<MjModel>,
    data: MjData<Arc<MjModel>>,
    geoms: Vec<GeomEntity>,
    root: String,
    /// Objects fixed in the world that episodes place differently (pegs): `(object name, mocap
    /// index)`. Recorded states do not hold their poses; episodes' object poses do.
    fixed: Vec<(String, usize)>,
}

impl std::fmt::Debug for SceneLogger {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneLogger").field("root", &self.root).field("geoms", &self.geoms.len()).finish_non_exhaustive()
    }
}

fn sanitize(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' { c } else { '_' }).collect()
}

fn is_collision(model: &MjModel, g: usize) -> bool {
    model.geom_contype()[g] != 0 || model.geom_conaffinity()[g] != 0
}

/// The colour MuJoCo's renderer would use (material colour unless the geom's own rgba is set).
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

#[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // colours are in [0, 1]
fn color(rgba: [f32; 4]) -> rerun::Color {
    let c = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    rerun::Color::from_unmultiplied_rgba(c(rgba[0]), c(rgba[1]), c(rgba[2]), c(rgba[3]))
}

#[allow(clippy::cast_possible_truncation)] // Rerun draws in f32
fn f32s<const N: usize>(v: [f64; N]) -> [f32; N] {
    v.map(|x| x as f32)
}

/// `[x, y, z, w]` of MuJoCo's row-major rotation matrix.
#[must_use]
#[allow(clippy::cast_possible_truncation)]
pub fn xyzw_from_xmat(xmat: &[f64; 9]) -> [f32; 4] {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_row_slice(xmat)));
    let c = q.coords;
    [c.x as f32, c.y as f32, c.z as f32, c.w as f32]
}

impl SceneLogger {
    /// Picks the geoms a person would see: groups 0-2, not fully transparent, and for a body that
    /// has visual-only geoms, only those (robosuite doubles every part as visual + collision).
    #[must_use]
    pub fn new(model: Arc<MjModel>, root: &str) -> Self {
        let ngeom = model.geom_type().len();
        let body_has_visual: Vec<bool> = {
            let nbody = model.body_parentid().len();
            let mut v = vec![false; nbody];
            for g in 0..ngeom {
                if !is_collision(&model, g)
                    && model.geom_group()[g] < FIRST_HIDDEN_GROUP
                    && let Some(slot) = usize::try_from(model.geom_bodyid()[g]).ok().and_then(|b| v.get_mut(b))
                {
                    *slot = true;
                }
            }
            v
        };
        let mut geoms = Vec::new();
        for g in 0..ngeom {
            let body = usize::try_from(model.geom_bodyid()[g]).unwrap_or_default();
            let name = model.id_to_name(MjtObjBase::mjOBJ_GEOM, g).map_or_else(String::new, sanitize);
            // robosuite's arena walls would hide the robot from every outside viewpoint.
            let hidden = name.starts_with("wall")
                || model.geom_group()[g] >= FIRST_HIDDEN_GROUP
                || geom_rgba(&model, g)[3] <= 0.0
                || (is_collision(&model, g) && body_has_visual.get(body).copied().unwrap_or(false));
            let supported = matches!(
                model.geom_type()[g],
                MjtGeomBase::mjGEOM_PLANE
                    | MjtGeomBase::mjGEOM_SPHERE
                    | MjtGeomBase::mjGEOM_CAPSULE
                    | MjtGeomBase::mjGEOM_ELLIPSOID
                    | MjtGeomBase::mjGEOM_CYLINDER
                    | MjtGeomBase::mjGEOM_BOX
                    | MjtGeomBase::mjGEOM_MESH
            );
            if hidden || !supported {
                continue;
            }
            let path = if name.is_empty() { format!("{root}/geom_{g:03}") } else { format!("{root}/{g:03}_{name}") };
            geoms.push(GeomEntity { id: g, path });
        }
        let data = MjData::new(Arc::clone(&model));
        Self { model, data, geoms, root: root.to_owned(), fixed: Vec::new() }
    }

    /// Number of geoms logged.
    #[must_use]
    pub fn len(&self) -> usize {
        self.geoms.len()
    }

    /// True when the scene has no visible geom.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.geoms.is_empty()
    }

    /// Logs every geom's shape once (static), in its own frame.
    ///
    /// # Errors
    /// [`VizError::Rerun`] if the stream rejects the data.
    pub fn log_static(&self, rec: &RecordingStream) -> Result<(), VizError> {
        let m = &self.model;
        for geom in &self.geoms {
            let g = geom.id;
            let size = f32s(m.geom_size()[g]);
            let rgba = color(geom_rgba(m, g));
            let result = match m.geom_type()[g] {
                MjtGeomBase::mjGEOM_PLANE => {
                    let half = |s: f32| if s > 0.0 { s.min(PLANE_HALF_M) } else { PLANE_HALF_M };
                    rec.log_static(
                        geom.path.as_str(),
                        &rerun::Boxes3D::from_half_sizes([[half(size[0]), half(size[1]), 0.001]])
                            .with_colors([rgba])
                            .with_fill_mode(rerun::FillMode::Solid),
                    )
                }
                MjtGeomBase::mjGEOM_SPHERE => rec.log_static(
                    geom.path.as_str(),
                    &rerun::Ellipsoids3D::from_radii([size[0]]).with_colors([rgba]).with_fill_mode(rerun::FillMode::Solid),
                ),
                MjtGeomBase::mjGEOM_ELLIPSOID => rec.log_static(
                    geom.path.as_str(),
                    &rerun::Ellipsoids3D::from_half_sizes([size]).with_colors([rgba]).with_fill_mode(rerun::FillMode::Solid),
                ),
                MjtGeomBase::mjGEOM_CAPSULE => rec.log_static(
                    geom.path.as_str(),
                    // Rerun's capsule runs from the origin along +z; MuJoCo's is centred.
                    &rerun::Capsules3D::from_lengths_and_radii([2.0 * size[1]], [size[0]])
                        .with_translations([[0.0, 0.0, -size[1]]])
                        .with_colors([rgba]),
                ),
                MjtGeomBase::mjGEOM_CYLINDER => rec.log_static(
                    geom.path.as_str(),
                    &rerun::Cylinders3D::from_lengths_and_radii([2.0 * size[1]], [size[0]])
                        .with_colors([rgba])
                        .with_fill_mode(rerun::FillMode::Solid),
                ),
                MjtGeomBase::mjGEOM_BOX => rec.log_static(
                    geom.path.as_str(),
                    &rerun::Boxes3D::from_half_sizes([size]).with_colors([rgba]).with_fill_mode(rerun::FillMode::Solid),
                ),
                MjtGeomBase::mjGEOM_MESH => self.log_mesh(rec, geom, rgba),
                _ => Ok(()),
            };
            result.map_err(|e| VizError::rerun(&geom.path, &e))?;
        }
        Ok(())
    }

    fn log_mesh(&self, rec: &RecordingStream, geom: &GeomEntity, rgba: rerun::Color) -> rerun::RecordingStreamResult<()> {
        let m = &self.model;
        let Ok(mesh) = usize::try_from(m.geom_dataid()[geom.id]) else { return Ok(()) };
        let as_usize = |v: i32| usize::try_from(v).unwrap_or_default();
        let (vadr, vnum) = (as_usize(m.mesh_vertadr()[mesh]), as_usize(m.mesh_vertnum()[mesh]));
        let (fadr, fnum) = (as_usize(m.mesh_faceadr()[mesh]), as_usize(m.mesh_facenum()[mesh]));
        let vertices = m.mesh_vert().get(vadr..vadr + vnum).unwrap_or_default();
        let faces: Vec<[u32; 3]> = m
            .mesh_face()
            .get(fadr..fadr + fnum)
            .unwrap_or_default()
            .iter()
            .map(|f| f.map(|i| u32::try_from(i).unwrap_or_default()))
            .collect();
        rec.log_static(
            geom.path.as_str(),
            &rerun::Mesh3D::new(vertices.iter().copied()).with_triangle_indices(faces).with_albedo_factor(rgba.0),
        )
    }

    /// Poses the private data at a recorded state (`[time, qpos, ...]`, long enough).
    fn pose(&mut self, state: &[f64]) {
        let nq = self.data.qpos().len();
        self.data.qpos_mut().copy_from_slice(&state[1..=nq]);
        self.data.kinematics();
    }

    /// Every logged geom's entity path and world position at the recorded state `state`.
    ///
    /// # Errors
    /// [`VizError::Sim`] for a state shorter than `1 + nq`.
    pub fn geom_positions(&mut self, state: &[f64]) -> Result<Vec<(String, [f64; 3])>, VizError> {
        if state.len() <= self.data.qpos().len() {
            return Err(VizError::Sim { what: self.root.clone(), reason: format!("a state of {} values is too short", state.len()) });
        }
        self.pose(state);
        Ok(self.geoms.iter().map(|g| (g.path.clone(), self.data.geom_xpos()[g.id])).collect())
    }

    /// Declares the objects fixed in the world that episodes may place differently (a peg):
    /// `(object name, mocap index)` pairs.
    pub fn set_fixed_objects(&mut self, fixed: Vec<(String, usize)>) {
        self.fixed = fixed;
    }

    /// Puts the fixed objects where `world_from_objects` (an episode's initial object poses, by
    /// name) has them.
    pub fn place_fixed_objects(&mut self, world_from_objects: &std::collections::BTreeMap<String, mimicgen_engine::Pose>) {
        for (name, mocap) in &self.fixed {
            if let Some(pose) = world_from_objects.get(name) {
                mimicgen_sim::env::set_mocap_pose(&mut self.data, *mocap, pose);
            }
        }
    }

    /// Logs every geom's world pose for the recorded simulator states `states` (robosuite's
    /// `[time, qpos, qvel]`), every `stride`-th step, as one column per geom. `index` gives each
    /// timeline's value for every row of `states` (e.g. `step`, `attempt`, `frame`).
    ///
    /// # Errors
    /// [`VizError::Sim`] for a state of the wrong length, [`VizError::Rerun`] from the stream.
    pub fn log_states(
        &mut self,
        rec: &RecordingStream,
        states: &Rows,
        stride: usize,
        index: &[(&'static str, Vec<i64>)],
    ) -> Result<(), VizError> {
        let nq = self.data.qpos().len();
        if states.width() < 1 + nq {
            return Err(VizError::Sim {
                what: self.root.clone(),
                reason: format!("states have {} values per step, the scene needs at least {}", states.width(), 1 + nq),
            });
        }
        let rows: Vec<usize> = (0..states.len()).step_by(stride.max(1)).collect();
        let mut translations: Vec<Vec<[f32; 3]>> = vec![Vec::with_capacity(rows.len()); self.geoms.len()];
        let mut quaternions: Vec<Vec<rerun::Quaternion>> = vec![Vec::with_capacity(rows.len()); self.geoms.len()];
        for &t in &rows {
            self.pose(states.row(t));
            let (xpos, xmat) = (self.data.geom_xpos(), self.data.geom_xmat());
            for (i, geom) in self.geoms.iter().enumerate() {
                translations[i].push(f32s(xpos[geom.id]));
                quaternions[i].push(rerun::Quaternion::from_xyzw(xyzw_from_xmat(&xmat[geom.id])));
            }
        }
        let times: Vec<TimeColumn> = index
            .iter()
            .map(|(name, values)| TimeColumn::new_sequence(*name, rows.iter().map(|&t| values.get(t).copied().unwrap_or_default())))
            .collect();
        for ((geom, trans), quats) in self.geoms.iter().zip(translations).zip(quaternions) {
            let columns = rerun::Transform3D::update_fields()
                .with_many_translation(trans)
                .with_many_quaternion(quats)
                .columns_of_unit_batches()
                .map_err(|e| VizError::rerun(&geom.path, &e))?;
            rec.send_columns(geom.path.as_str(), times.clone(), columns).map_err(|e| VizError::rerun(&geom.path, &e))?;
        }
        Ok(())
    }
}
