//! The MuJoCo scene as Rerun primitives: every visible geom logged once, then its pose per step,
//! under `<root>/<part>/` (`robot`, `gripper`, `objects`, `table`, `arena`) so a view can show
//! the workspace without the arm and the room.

use mimicgen_engine::Rows;
use mimicgen_sim::{GeomPoser, Scene, Shape, VisibleGeom};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use rerun::{RecordingStream, TimeColumn};

use crate::VizError;

/// Largest half extent drawn for a plane (MuJoCo's size 0 is infinite; robosuite's floor is 3 m).
const PLANE_HALF_M: f32 = 1.0;

/// One visible geom and the entity it is logged under.
#[derive(Debug, Clone)]
struct GeomEntity {
    geom: VisibleGeom,
    path: String,
}

/// The visible geoms of a compiled scene and a poser (with its own simulator state) to place
/// them at recorded states.
pub struct SceneLogger {
    poser: GeomPoser,
    geoms: Vec<GeomEntity>,
    root: String,
}

impl std::fmt::Debug for SceneLogger {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneLogger").field("root", &self.root).field("geoms", &self.geoms.len()).finish_non_exhaustive()
    }
}

fn sanitize(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' { c } else { '_' }).collect()
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
    /// Logs the geoms a person would see ([`Scene::visible_geoms`]) under `root`.
    #[must_use]
    pub fn new(scene: &Scene, root: &str) -> Self {
        let geoms: Vec<GeomEntity> = scene
            .visible_geoms()
            .into_iter()
            .map(|geom| {
                let g = geom.id;
                let part = geom.part.name();
                let path = if geom.name.is_empty() {
                    format!("{root}/{part}/geom_{g:03}")
                } else {
                    format!("{root}/{part}/{g:03}_{}", sanitize(&geom.name))
                };
                GeomEntity { geom, path }
            })
            .collect();
        let poser = GeomPoser::new(scene, geoms.iter().map(|g| g.geom.id).collect());
        Self { poser, geoms, root: root.to_owned() }
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
        for entity in &self.geoms {
            let rgba = color(entity.geom.rgba);
            let path = entity.path.as_str();
            #[allow(clippy::cast_possible_truncation)] // Rerun draws in f32
            let f = |v: f64| v as f32;
            let result = match &entity.geom.shape {
                Shape::Plane { half_m } => {
                    let half = |s: f64| if s > 0.0 { f(s).min(PLANE_HALF_M) } else { PLANE_HALF_M };
                    rec.log_static(
                        path,
                        &rerun::Boxes3D::from_half_sizes([[half(half_m[0]), half(half_m[1]), 0.001]])
                            .with_colors([rgba])
                            .with_fill_mode(rerun::FillMode::Solid),
                    )
                }
                Shape::Sphere { radius_m } => rec.log_static(
                    path,
                    &rerun::Ellipsoids3D::from_radii([f(*radius_m)]).with_colors([rgba]).with_fill_mode(rerun::FillMode::Solid),
                ),
                Shape::Ellipsoid { half_m } => rec.log_static(
                    path,
                    &rerun::Ellipsoids3D::from_half_sizes([f32s(*half_m)]).with_colors([rgba]).with_fill_mode(rerun::FillMode::Solid),
                ),
                Shape::Capsule { radius_m, half_length_m } => rec.log_static(
                    path,
                    // Rerun's capsule runs from the origin along +z; MuJoCo's is centred.
                    &rerun::Capsules3D::from_lengths_and_radii([2.0 * f(*half_length_m)], [f(*radius_m)])
                        .with_translations([[0.0, 0.0, -f(*half_length_m)]])
                        .with_colors([rgba]),
                ),
                Shape::Cylinder { radius_m, half_length_m } => rec.log_static(
                    path,
                    &rerun::Cylinders3D::from_lengths_and_radii([2.0 * f(*half_length_m)], [f(*radius_m)])
                        .with_colors([rgba])
                        .with_fill_mode(rerun::FillMode::Solid),
                ),
                Shape::Box { half_m } => rec.log_static(
                    path,
                    &rerun::Boxes3D::from_half_sizes([f32s(*half_m)]).with_colors([rgba]).with_fill_mode(rerun::FillMode::Solid),
                ),
                Shape::Mesh { vertices, triangles } => rec.log_static(
                    path,
                    &rerun::Mesh3D::new(vertices.iter().copied())
                        .with_triangle_indices(triangles.iter().copied())
                        .with_albedo_factor(rgba.0),
                ),
            };
            result.map_err(|e| VizError::rerun(path, &e))?;
        }
        Ok(())
    }

    /// Every logged geom's entity path and world position at the recorded state `state`.
    ///
    /// # Errors
    /// [`VizError::Sim`] for a state shorter than `1 + nq`.
    pub fn geom_positions(&mut self, state: &[f64]) -> Result<Vec<(String, [f64; 3])>, VizError> {
        let poses = self.poser.poses(state).map_err(|e| VizError::Sim { what: self.root.clone(), reason: e.to_string() })?;
        Ok(self.geoms.iter().zip(poses).map(|(g, (xpos, _))| (g.path.clone(), xpos)).collect())
    }

    /// Puts the scene's fixed objects (pegs) where `world_from_objects` (an episode's initial
    /// object poses, by name) has them.
    pub fn place_fixed_objects(&mut self, world_from_objects: &std::collections::BTreeMap<String, mimicgen_engine::Pose>) {
        self.poser.place_fixed_objects(world_from_objects);
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
        let need = self.poser.min_state_len();
        if states.width() < need {
            return Err(VizError::Sim {
                what: self.root.clone(),
                reason: format!("states have {} values per step, the scene needs at least {need}", states.width()),
            });
        }
        let rows: Vec<usize> = (0..states.len()).step_by(stride.max(1)).collect();
        let mut translations: Vec<Vec<[f32; 3]>> = vec![Vec::with_capacity(rows.len()); self.geoms.len()];
        let mut quaternions: Vec<Vec<rerun::Quaternion>> = vec![Vec::with_capacity(rows.len()); self.geoms.len()];
        for &t in &rows {
            let poses = self.poser.poses(states.row(t)).map_err(|e| VizError::Sim { what: self.root.clone(), reason: e.to_string() })?;
            for ((xpos, xmat), (translation, quaternion)) in poses.iter().zip(translations.iter_mut().zip(quaternions.iter_mut())) {
                translation.push(f32s(*xpos));
                quaternion.push(rerun::Quaternion::from_xyzw(xyzw_from_xmat(xmat)));
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
