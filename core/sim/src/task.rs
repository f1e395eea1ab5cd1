//! Tasks: which objects a scene has, how scenes are sampled, subtask-end signals and success.

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use mimicgen_engine::EnvError;
use mimicgen_engine::coverage::{Coordinate, Dimension};
use mimicgen_engine::demonstrator::PickPlaceScript;
use mimicgen_engine::pose::{Pose, Rot, Vec3, pose_from_parts};
use rand::{Rng, RngCore};

use crate::compose::{BASE_TABLE_TOP_Z, ObjectModel, SQUARE_NUT_HANDLE};
use crate::env::SimEnv;

/// What a task adds to a robosuite scene.
pub trait Task: Send + Sync {
    /// Task name (`stack`).
    fn name(&self) -> &str;
    /// `(object name, body name)` of every object, in order.
    fn objects(&self) -> Vec<(&'static str, &'static str)>;
    /// The object models our composed scene adds to the base scene, in the same order.
    fn object_models(&self) -> Vec<ObjectModel>;
    /// Initial `world_from_object` of every object, in order.
    ///
    /// # Errors
    /// [`EnvError::Fatal`] if no valid placement is found.
    fn sample_scene(&self, rng: &mut dyn RngCore) -> Result<Vec<Pose>, EnvError>;
    /// Subtask-end signals in the current state.
    fn signals(&self, env: &SimEnv) -> BTreeMap<String, i64>;
    /// Whether the task is achieved in the current state.
    fn is_success(&self, env: &SimEnv) -> bool;
    /// robosuite's `object` observation for this task in the current state.
    fn object_obs(&self, env: &SimEnv) -> Vec<f64>;
    /// The scripted demonstrator's pick-and-places, in order (empty if the task has none).
    fn scripts(&self) -> Vec<PickPlaceScript>;
    /// The reset distribution as coverage dimensions: each object's x, y and yaw over its range.
    fn coverage_dimensions(&self) -> Vec<Dimension>;
    /// Height of the table top (m), robosuite's `table_offset` z.
    fn table_top_z(&self) -> f64 {
        TABLE_TOP_Z
    }
}

/// Coverage dimensions of objects sampled in `regions` around the table centre (world x, y; yaw
/// over the full circle when the region's yaw range is).
fn region_dimensions(objects: &[&str], regions: &[PlacementRegion]) -> Vec<Dimension> {
    let mut dims = Vec::with_capacity(objects.len() * 3);
    for (object, r) in objects.iter().zip(regions) {
        let yaw = if r.yaw.1 - r.yaw.0 >= TAU - 1e-9 { (-std::f64::consts::PI, std::f64::consts::PI) } else { r.yaw };
        for (coordinate, (low, high)) in [(Coordinate::X, r.x), (Coordinate::Y, r.y), (Coordinate::Yaw, yaw)] {
            dims.push(Dimension { object: (*object).to_owned(), coordinate, low, high });
        }
    }
    dims
}

/// A textured cube as robosuite's `BoxObject`.
fn cube(name: &str, half: f64, tex: &str, file: &str) -> ObjectModel {
    ObjectModel::Box {
        name: name.to_owned(),
        half_size: [half; 3],
        rgba: [0.5, 0.0, 0.0, 1.0],
        texture: (tex.to_owned(), format!("textures/{file}")),
    }
}

/// Whether object `upper` rests on `lower`: lifted above the table by `lift_m` and touching it.
fn stacked(env: &SimEnv, upper: usize, lower: usize, lift_m: f64) -> bool {
    let objects = &env.scene().objects;
    env.object_pose(upper).translation.z > TABLE_TOP_Z + lift_m && env.in_contact(&objects[upper].geoms, &objects[lower].geoms)
}

/// robosuite's per-object observables: each object's position and `xyzw` quaternion, then
/// `object - eef` for each object.
fn pose_and_gripper_obs(env: &SimEnv) -> Vec<f64> {
    use mimicgen_engine::Environment as _;
    let eef = env.eef_pose().translation.vector;
    let poses: Vec<Pose> = (0..env.scene().objects.len()).map(|i| env.object_pose(i)).collect();
    let mut obs = Vec::with_capacity(poses.len() * 10);
    for (i, p) in poses.iter().enumerate() {
        obs.extend(p.translation.vector.iter());
        // MuJoCo's own quaternion (not one rebuilt from the rotation), so the sign matches robosuite.
        let [w, x, y, z] = env.data().xquat()[env.scene().objects[i].body];
        obs.extend([x, y, z, w]);
    }
    for p in &poses {
        obs.extend((p.translation.vector - eef).iter());
    }
    obs
}

/// Height of robosuite's table top (m): `table_offset` z (Stack, Stack Three).
pub const TABLE_TOP_Z: f64 = BASE_TABLE_TOP_Z;

/// A region of the table to place an object in, robosuite's `UniformRandomSampler` style.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacementRegion {
    /// x range (m, relative to the table centre).
    pub x: (f64, f64),
    /// y range.
    pub y: (f64, f64),
    /// yaw range (rad).
    pub yaw: (f64, f64),
}

impl PlacementRegion {
    /// A square of side `side_m` centred on the table, any yaw.
    #[must_use]
    pub fn square(side_m: f64) -> Self {
        Self { x: (-side_m / 2.0, side_m / 2.0), y: (-side_m / 2.0, side_m / 2.0), yaw: (0.0, TAU) }
    }
}

fn uniform(rng: &mut dyn RngCore, (lo, hi): (f64, f64)) -> f64 {
    if hi > lo { rng.random_range(lo..hi) } else { lo }
}

/// Places boxes one by one in their regions, rejecting overlaps of their bounding circles, as
/// robosuite's sampler does (10 000 tries each). `half_sizes` are the boxes' half extents.
///
/// # Errors
/// [`EnvError::Fatal`] if a box cannot be placed.
pub fn place_boxes(
    rng: &mut dyn RngCore,
    regions: &[PlacementRegion],
    half_sizes: &[[f64; 3]],
    z_offset: f64,
) -> Result<Vec<Pose>, EnvError> {
    let mut placed: Vec<(f64, f64, f64)> = Vec::new();
    let mut poses = Vec::with_capacity(regions.len());
    for (region, half) in regions.iter().zip(half_sizes) {
        let radius = half[0].hypot(half[1]);
        let mut found = None;
        for _ in 0..10_000 {
            let (x, y) = (uniform(rng, region.x), uniform(rng, region.y));
            if placed.iter().all(|(px, py, pr)| (px - x).hypot(py - y) > pr + radius) {
                found = Some((x, y));
                break;
            }
        }
        let (x, y) = found
            .ok_or_else(|| EnvError::Fatal { reason: format!("cannot place object {} without overlap in {region:?}", poses.len()) })?;
        let yaw = uniform(rng, region.yaw);
        placed.push((x, y, radius));
        poses.push(pose_from_parts(Vec3::new(x, y, TABLE_TOP_Z + z_offset + half[2]), Rot::from_axis_angle(&Vec3::z_axis(), yaw)));
    }
    Ok(poses)
}

/// The square region (side in m) of `variant` among `sides`, for tasks whose variants differ only
/// in the size of the square every object is sampled in.
fn square_variant(task: &str, variant: &str, sides: &[(&str, f64)]) -> Result<PlacementRegion, String> {
    let wanted = variant.to_ascii_uppercase();
    sides.iter().find(|(name, _)| *name == wanted).map(|(_, side)| PlacementRegion::square(*side)).ok_or_else(|| {
        format!("{task} has variants {}, not {variant:?}", sides.iter().map(|(name, _)| *name).collect::<Vec<_>>().join(" and "))
    })
}

/// robosuite's Stack: put the red cube (`cubeA`, 4 cm) on the green one (`cubeB`, 5 cm).
#[derive(Debug, Clone, PartialEq)]
pub struct Stack {
    /// Where both cubes are sampled.
    pub region: PlacementRegion,
}

impl Stack {
    /// MimicGen's variants: D0 both cubes in a 0.16 m square, D1 in a 0.40 m square; random yaw.
    ///
    /// # Errors
    /// A message listing the variants when `variant` is not one of them.
    pub fn variant(variant: &str) -> Result<Self, String> {
        Ok(Self { region: square_variant("stack", variant, &[("D0", 0.16), ("D1", 0.40)])? })
    }
}

impl Stack {
    /// The scripted demonstrator's settings: grasp near the red cube's centre, release it 6 mm
    /// above resting on the green one; the gripper takes about four control steps to close.
    #[must_use]
    pub fn script() -> PickPlaceScript {
        PickPlaceScript {
            pick: "cubeA".to_owned(),
            place_on: "cubeB".to_owned(),
            grasp_point_m: [0.0; 3],
            grasp_height_m: -0.002,
            grasp_symmetry_rad: std::f64::consts::FRAC_PI_2,
            grasp_yaw_offset_rad: 0.0,
            release_height_m: 0.02 + 0.025 + 0.006,
            close_steps: (6, 9),
            open_steps: (3, 5),
            grasp_offset_m: 0.003,
            approach_height_m: (0.06, 0.12),
            lift_height_m: (0.12, 0.18),
            preplace_height_m: (0.03, 0.08),
            retreat_height_m: 0.08,
            place_yaw_symmetry_rad: None,
            settle_steps: 0,
            wait_for_arm: true,
        }
    }
}

impl Task for Stack {
    fn name(&self) -> &str {
        "stack"
    }

    fn objects(&self) -> Vec<(&'static str, &'static str)> {
        vec![("cubeA", "cubeA_main"), ("cubeB", "cubeB_main")]
    }

    fn object_models(&self) -> Vec<ObjectModel> {
        vec![cube("cubeA", 0.02, "redwood", "red-wood.png"), cube("cubeB", 0.025, "greenwood", "green-wood.png")]
    }

    fn scripts(&self) -> Vec<PickPlaceScript> {
        vec![Self::script()]
    }

    fn coverage_dimensions(&self) -> Vec<Dimension> {
        region_dimensions(&["cubeA", "cubeB"], &[self.region; 2])
    }

    fn sample_scene(&self, rng: &mut dyn RngCore) -> Result<Vec<Pose>, EnvError> {
        place_boxes(rng, &[self.region, self.region], &[[0.02; 3], [0.025; 3]], 0.01)
    }

    fn signals(&self, env: &SimEnv) -> BTreeMap<String, i64> {
        BTreeMap::from([("grasp".to_owned(), i64::from(env.is_grasping(0)))])
    }

    fn object_obs(&self, env: &SimEnv) -> Vec<f64> {
        let mut obs = pose_and_gripper_obs(env);
        let (a, b) = (env.object_pose(0).translation.vector, env.object_pose(1).translation.vector);
        obs.extend((b - a).iter());
        obs
    }

    fn is_success(&self, env: &SimEnv) -> bool {
        // robosuite's Stack: cubeA lifted above the table, touching cubeB, and not held.
        stacked(env, 0, 1, 0.04) && !env.is_grasping(0)
    }
}

/// robosuite's Lift: pick the red cube (`cube`, 2 to 2.2 cm half size) up off the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Lift {
    /// Where the cube is sampled.
    pub region: PlacementRegion,
}

impl Lift {
    /// D0: robosuite's own reset (cube in a 0.06 m square, any yaw); D1: a 0.30 m square.
    ///
    /// # Errors
    /// A message listing the variants when `variant` is not one of them.
    pub fn variant(variant: &str) -> Result<Self, String> {
        Ok(Self { region: square_variant("lift", variant, &[("D0", 0.06), ("D1", 0.30)])? })
    }
}

impl Task for Lift {
    fn name(&self) -> &str {
        "lift"
    }

    fn objects(&self) -> Vec<(&'static str, &'static str)> {
        vec![("cube", "cube_main")]
    }

    fn object_models(&self) -> Vec<ObjectModel> {
        vec![cube("cube", 0.021, "redwood", "red-wood.png")]
    }

    fn scripts(&self) -> Vec<PickPlaceScript> {
        // Its bundled demos are robosuite's human ones (`mimicgen prepare` of the file in its wheel).
        Vec::new()
    }

    fn coverage_dimensions(&self) -> Vec<Dimension> {
        region_dimensions(&["cube"], &[self.region])
    }

    fn sample_scene(&self, rng: &mut dyn RngCore) -> Result<Vec<Pose>, EnvError> {
        place_boxes(rng, &[self.region], &[[0.021; 3]], 0.01)
    }

    fn signals(&self, env: &SimEnv) -> BTreeMap<String, i64> {
        BTreeMap::from([("grasp".to_owned(), i64::from(env.is_grasping(0)))])
    }

    fn object_obs(&self, env: &SimEnv) -> Vec<f64> {
        // robosuite's Lift: cube_pos, cube_quat (xyzw), then gripper_to_cube_pos = eef - cube.
        use mimicgen_engine::Environment as _;
        let mut obs = pose_and_gripper_obs(env);
        let eef = env.eef_pose().translation.vector;
        let cube = env.object_pose(0).translation.vector;
        obs.truncate(7);
        obs.extend((eef - cube).iter());
        obs
    }

    fn is_success(&self, env: &SimEnv) -> bool {
        // robosuite's Lift: the cube's centre more than 4 cm above the table top.
        env.object_pose(0).translation.z > TABLE_TOP_Z + 0.04
    }
}

/// robosuite's nut sensors for object `i`: position, `xyzw` quaternion, then the nut's pose in the
/// gripper frame (grip site position, hand orientation).
fn nut_obs(env: &SimEnv, i: usize) -> Vec<f64> {
    use mimicgen_engine::Environment as _;
    let body = env.scene().objects[i].body;
    let [w, x, y, z] = env.data().xquat()[body];
    let nut = env.object_pose(i);
    let hand = env.data().xquat()[env.scene().robot.hand_body];
    let world_from_gripper = pose_from_parts(
        env.eef_pose().translation.vector,
        Rot::from_quaternion(nalgebra::Quaternion::new(hand[0], hand[1], hand[2], hand[3])),
    );
    let gripper_from_nut = world_from_gripper.inverse() * nut;
    let q = gripper_from_nut.rotation.quaternion();
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    let mut obs = Vec::with_capacity(17);
    obs.extend(nut.translation.vector.iter());
    obs.extend([x, y, z, w]);
    obs.extend(gripper_from_nut.translation.vector.iter());
    obs.extend([sign * q.i, sign * q.j, sign * q.k, sign * q.w]);
    obs
}

/// robosuite's `on_peg`: the nut's centre within 3 cm of the peg's axis and low on it.
fn nut_on_peg(env: &SimEnv, nut: usize, peg: usize) -> bool {
    let (n, p) = (env.object_pose(nut).translation.vector, env.object_pose(peg).translation.vector);
    (n.x - p.x).abs() < 0.03 && (n.y - p.y).abs() < 0.03 && n.z < NUT_TABLE_TOP_Z + 0.05
}

/// robosuite's Nut Assembly (MimicGen's D0): the square nut onto the square peg, then the round
/// nut onto the round peg; both pegs at robosuite's fixed places.
#[derive(Debug, Clone, PartialEq)]
pub struct NutAssembly {
    /// Where the square nut is sampled.
    pub square_nut: PlacementRegion,
    /// Where the round nut is sampled.
    pub round_nut: PlacementRegion,
}

/// robosuite's round peg (`peg2`): radius and half height, and where the arena has it.
const ROUND_PEG: [f64; 2] = [0.02, 0.1];
const ROUND_PEG_POS: [f64; 3] = [0.23, -0.1, 0.85];

impl NutAssembly {
    /// D0: robosuite's reset: each nut in a 0.005 x 0.115 m strip in front of its peg, any yaw.
    /// D1 (ours; the paper has D0 only): both nuts anywhere in a 0.25 x 0.5 m region in front of
    /// the pegs, any yaw, clear of each other.
    ///
    /// # Errors
    /// A message when `variant` is not D0 or D1.
    pub fn variant(variant: &str) -> Result<Self, String> {
        let any = (0.0, TAU);
        match variant.to_ascii_uppercase().as_str() {
            "D0" => Ok(Self {
                square_nut: PlacementRegion { x: (-0.115, -0.11), y: (0.11, 0.225), yaw: any },
                round_nut: PlacementRegion { x: (-0.115, -0.11), y: (-0.225, -0.11), yaw: any },
            }),
            "D1" => {
                let wide = PlacementRegion { x: (-0.2, 0.05), y: (-0.25, 0.25), yaw: any };
                Ok(Self { square_nut: wide, round_nut: wide })
            }
            _ => Err(format!("nut_assembly has variants D0 and D1, not {variant:?}")),
        }
    }

    /// The round nut's demonstrator: Square's, gripping the round nut's handle, with any yaw over
    /// the (round) peg.
    #[must_use]
    pub fn round_script() -> PickPlaceScript {
        PickPlaceScript {
            pick: "round_nut".to_owned(),
            place_on: "round_peg".to_owned(),
            grasp_point_m: crate::compose::ROUND_NUT_HANDLE,
            place_yaw_symmetry_rad: None,
            ..Square::script()
        }
    }
}

impl Task for NutAssembly {
    fn name(&self) -> &str {
        "nut_assembly"
    }

    fn objects(&self) -> Vec<(&'static str, &'static str)> {
        vec![("square_nut", "SquareNut_main"), ("round_nut", "RoundNut_main"), ("square_peg", "peg1"), ("round_peg", "peg2")]
    }

    fn object_models(&self) -> Vec<ObjectModel> {
        vec![
            ObjectModel::SquareNut { name: "SquareNut".to_owned() },
            ObjectModel::RoundNut { name: "RoundNut".to_owned() },
            ObjectModel::FixedBox { body: "peg1".to_owned(), half_size: PEG_HALF_SIZE, pos: PEG_DEFAULT_POS },
            ObjectModel::FixedCylinder { body: "peg2".to_owned(), radius_half_height: ROUND_PEG, pos: ROUND_PEG_POS },
        ]
    }

    fn table_top_z(&self) -> f64 {
        NUT_TABLE_TOP_Z
    }

    fn sample_scene(&self, rng: &mut dyn RngCore) -> Result<Vec<Pose>, EnvError> {
        // As robosuite: each nut's bottom site (5 cm below its centre) 2 cm above the table.
        let z = NUT_TABLE_TOP_Z + 0.02 + 0.05;
        let mut nut = |r: &PlacementRegion| {
            pose_from_parts(Vec3::new(uniform(rng, r.x), uniform(rng, r.y), z), Rot::from_axis_angle(&Vec3::z_axis(), uniform(rng, r.yaw)))
        };
        let square = nut(&self.square_nut);
        // The round nut clear of the square one (handles included), as robosuite's sampler keeps
        // objects apart (D0's strips are apart already).
        let mut round = nut(&self.round_nut);
        let mut tries = 0;
        while (round.translation.vector - square.translation.vector).xy().norm() < 2.0 * NUT_HORIZONTAL_RADIUS {
            tries += 1;
            if tries > 10_000 {
                return Err(EnvError::Fatal {
                    reason: format!("cannot place the round nut in {:?} clear of the square nut", self.round_nut),
                });
            }
            round = nut(&self.round_nut);
        }
        let peg = |[x, y, z]: [f64; 3]| pose_from_parts(Vec3::new(x, y, z), Rot::identity());
        Ok(vec![square, round, peg(PEG_DEFAULT_POS), peg(ROUND_PEG_POS)])
    }

    fn signals(&self, env: &SimEnv) -> BTreeMap<String, i64> {
        BTreeMap::from([
            ("grasp_square_nut".to_owned(), i64::from(env.is_grasping(0))),
            ("insert_square_nut".to_owned(), i64::from(nut_on_peg(env, 0, 2))),
            ("grasp_round_nut".to_owned(), i64::from(env.is_grasping(1))),
        ])
    }

    fn is_success(&self, env: &SimEnv) -> bool {
        // robosuite's NutAssembly: every nut on its peg.
        nut_on_peg(env, 0, 2) && nut_on_peg(env, 1, 3)
    }

    fn object_obs(&self, env: &SimEnv) -> Vec<f64> {
        let mut obs = nut_obs(env, 0);
        obs.extend(nut_obs(env, 1));
        obs
    }

    fn scripts(&self) -> Vec<PickPlaceScript> {
        vec![Square::script(), Self::round_script()]
    }

    fn coverage_dimensions(&self) -> Vec<Dimension> {
        region_dimensions(&["square_nut", "round_nut"], &[self.square_nut, self.round_nut])
    }
}

/// MimicGen's Stack Three: red (`cubeA`) onto green (`cubeB`), then blue (`cubeC`) onto red.
#[derive(Debug, Clone, PartialEq)]
pub struct StackThree {
    /// Where the three cubes are sampled.
    pub region: PlacementRegion,
}

impl StackThree {
    /// D0: cubes in a 0.20 m square; D1: 0.40 m; random yaw.
    ///
    /// # Errors
    /// A message listing the variants when `variant` is not one of them.
    pub fn variant(variant: &str) -> Result<Self, String> {
        Ok(Self { region: square_variant("stack_three", variant, &[("D0", 0.20), ("D1", 0.40)])? })
    }
}

impl Task for StackThree {
    fn name(&self) -> &str {
        "stack_three"
    }

    fn objects(&self) -> Vec<(&'static str, &'static str)> {
        vec![("cubeA", "cubeA_main"), ("cubeB", "cubeB_main"), ("cubeC", "cubeC_main")]
    }

    fn object_models(&self) -> Vec<ObjectModel> {
        vec![
            cube("cubeA", 0.02, "redwood", "red-wood.png"),
            cube("cubeB", 0.025, "greenwood", "green-wood.png"),
            cube("cubeC", 0.02, "bluewood", "blue-wood.png"),
        ]
    }

    fn sample_scene(&self, rng: &mut dyn RngCore) -> Result<Vec<Pose>, EnvError> {
        place_boxes(rng, &[self.region; 3], &[[0.02; 3], [0.025; 3], [0.02; 3]], 0.01)
    }

    fn signals(&self, env: &SimEnv) -> BTreeMap<String, i64> {
        BTreeMap::from([
            ("grasp_1".to_owned(), i64::from(env.is_grasping(0))),
            ("stack_1".to_owned(), i64::from(stacked(env, 0, 1, 0.04))),
            ("grasp_2".to_owned(), i64::from(env.is_grasping(2))),
        ])
    }

    fn is_success(&self, env: &SimEnv) -> bool {
        stacked(env, 0, 1, 0.04) && stacked(env, 2, 0, 0.08) && !env.is_grasping(2)
    }

    fn object_obs(&self, env: &SimEnv) -> Vec<f64> {
        let mut obs = pose_and_gripper_obs(env);
        let [a, b, c] = [0, 1, 2].map(|i| env.object_pose(i).translation.vector);
        obs.extend((b - a).iter());
        obs.extend((c - a).iter());
        obs.extend((c - b).iter());
        obs
    }

    fn scripts(&self) -> Vec<PickPlaceScript> {
        let first = Stack::script();
        // Lift well clear of the new stack before carrying on, and approach the blue cube from
        // above the stack's height, as a careful operator would.
        let first = PickPlaceScript { retreat_height_m: 0.15, ..first };
        let second = PickPlaceScript {
            pick: "cubeC".to_owned(),
            place_on: "cubeA".to_owned(),
            release_height_m: 0.02 + 0.02 + 0.006,
            approach_height_m: (0.13, 0.17),
            lift_height_m: (0.15, 0.2),
            ..first.clone()
        };
        vec![first, second]
    }

    fn coverage_dimensions(&self) -> Vec<Dimension> {
        region_dimensions(&["cubeA", "cubeB", "cubeC"], &[self.region; 3])
    }
}

/// robosuite's nut-assembly table height (`table_offset` z).
const NUT_TABLE_TOP_Z: f64 = 0.82;
/// robosuite's square peg (`peg1` of `arenas/pegs_arena.xml`): half extents and default position.
const PEG_HALF_SIZE: [f64; 3] = [0.016, 0.016, 0.1];
const PEG_DEFAULT_POS: [f64; 3] = [0.23, 0.1, 0.85];
/// The square nut's `horizontal_radius` (its `horizontal_radius_site`, 0.11 x 0.06 m).
const NUT_HORIZONTAL_RADIUS: f64 = 0.125_299_640_861_416_6;

/// MimicGen's Square (robosuite's `NutAssemblySquare`): put the square nut (`square_nut`) onto the
/// square peg (`square_peg`).
#[derive(Debug, Clone, PartialEq)]
pub struct Square {
    /// Where the nut is sampled (x, y around the table centre; any yaw).
    pub nut: PlacementRegion,
    /// Where the peg is sampled; `None` keeps it at robosuite's default (0.23, 0.1).
    pub peg: Option<PlacementRegion>,
}

impl Square {
    /// D0: peg fixed, nut in robosuite's 0.005 x 0.115 m region; D1: peg in a 0.4 x 0.4 m region
    /// (fixed yaw), nut in 0.23 x 0.51 m; D2: both in 0.5 x 0.5 m, peg yaw in [0, 90 deg].
    ///
    /// # Errors
    /// A message listing the variants when `variant` is not one of them.
    pub fn variant(variant: &str) -> Result<Self, String> {
        let any = (0.0, TAU);
        match variant.to_ascii_uppercase().as_str() {
            "D0" => Ok(Self { nut: PlacementRegion { x: (-0.115, -0.11), y: (0.11, 0.225), yaw: any }, peg: None }),
            "D1" => Ok(Self {
                nut: PlacementRegion { x: (-0.115, 0.115), y: (-0.255, 0.255), yaw: any },
                peg: Some(PlacementRegion { x: (-0.1, 0.3), y: (-0.2, 0.2), yaw: (0.0, 0.0) }),
            }),
            "D2" => Ok(Self {
                nut: PlacementRegion { x: (-0.25, 0.25), y: (-0.25, 0.25), yaw: any },
                peg: Some(PlacementRegion { x: (-0.25, 0.25), y: (-0.25, 0.25), yaw: (0.0, std::f64::consts::FRAC_PI_2) }),
            }),
            _ => Err(format!("square has variants D0, D1 and D2, not {variant:?}")),
        }
    }

    /// The scripted demonstrator: wait for the nut to land, grip the handle across its width,
    /// carry the nut high over the peg, turned to the peg's yaw (mod 90 deg) with the handle on the
    /// robot's side, push it down the peg to just above the table and let go.
    #[must_use]
    pub fn script() -> PickPlaceScript {
        PickPlaceScript {
            pick: "square_nut".to_owned(),
            place_on: "square_peg".to_owned(),
            grasp_point_m: SQUARE_NUT_HANDLE,
            grasp_height_m: -0.003,
            grasp_symmetry_rad: std::f64::consts::PI,
            grasp_yaw_offset_rad: std::f64::consts::FRAC_PI_2,
            release_height_m: -0.005,
            close_steps: (10, 13),
            open_steps: (3, 5),
            grasp_offset_m: 0.003,
            approach_height_m: (0.06, 0.12),
            lift_height_m: (0.15, 0.2),
            preplace_height_m: (0.14, 0.17),
            retreat_height_m: 0.08,
            place_yaw_symmetry_rad: Some(std::f64::consts::FRAC_PI_2),
            settle_steps: 6,
            wait_for_arm: true,
        }
    }
}

impl Task for Square {
    fn name(&self) -> &str {
        "square"
    }

    fn objects(&self) -> Vec<(&'static str, &'static str)> {
        vec![("square_nut", "SquareNut_main"), ("square_peg", "peg1")]
    }

    fn object_models(&self) -> Vec<ObjectModel> {
        vec![
            ObjectModel::SquareNut { name: "SquareNut".to_owned() },
            ObjectModel::FixedBox { body: "peg1".to_owned(), half_size: PEG_HALF_SIZE, pos: PEG_DEFAULT_POS },
        ]
    }

    fn table_top_z(&self) -> f64 {
        NUT_TABLE_TOP_Z
    }

    fn sample_scene(&self, rng: &mut dyn RngCore) -> Result<Vec<Pose>, EnvError> {
        let [px, py, pz] = PEG_DEFAULT_POS;
        let peg = match &self.peg {
            // MimicGen samples the peg around the table centre at the arena's peg height.
            Some(r) => pose_from_parts(
                Vec3::new(uniform(rng, r.x), uniform(rng, r.y), pz),
                Rot::from_axis_angle(&Vec3::z_axis(), uniform(rng, r.yaw)),
            ),
            None => pose_from_parts(Vec3::new(px, py, pz), Rot::identity()),
        };
        // Nut positions that would put it on the peg are rejected (MimicGen: 5000 tries). robosuite
        // puts the nut's `bottom_site` (5 cm below its centre) 2 cm above the table, so it drops.
        let peg_radius = PEG_HALF_SIZE[0].hypot(PEG_HALF_SIZE[1]);
        for _ in 0..5000 {
            let (x, y) = (uniform(rng, self.nut.x), uniform(rng, self.nut.y));
            let yaw = uniform(rng, self.nut.yaw);
            if (x - peg.translation.x).hypot(y - peg.translation.y) > peg_radius + NUT_HORIZONTAL_RADIUS {
                let nut = pose_from_parts(Vec3::new(x, y, NUT_TABLE_TOP_Z + 0.02 + 0.05), Rot::from_axis_angle(&Vec3::z_axis(), yaw));
                return Ok(vec![nut, peg]);
            }
        }
        Err(EnvError::Fatal { reason: format!("cannot place the square nut in {:?} clear of the peg", self.nut) })
    }

    fn signals(&self, env: &SimEnv) -> BTreeMap<String, i64> {
        BTreeMap::from([("grasp".to_owned(), i64::from(env.is_grasping(0)))])
    }

    fn is_success(&self, env: &SimEnv) -> bool {
        use mimicgen_engine::Environment as _;
        // robosuite's `on_peg` and its reach check: the nut round the peg, low on it, and the
        // gripper not at the nut's centre (1 - tanh(10 d) < 0.6).
        let (nut, peg) = (env.object_pose(0).translation.vector, env.object_pose(1).translation.vector);
        let on_peg = (nut.x - peg.x).abs() < 0.03 && (nut.y - peg.y).abs() < 0.03 && nut.z < NUT_TABLE_TOP_Z + 0.05;
        let reach = 1.0 - (10.0 * (env.eef_pose().translation.vector - nut).norm()).tanh();
        on_peg && reach < 0.6
    }

    fn object_obs(&self, env: &SimEnv) -> Vec<f64> {
        // MimicGen's D1/D2 add the peg.
        let mut obs = nut_obs(env, 0);
        if self.peg.is_some() {
            obs.extend(env.object_pose(1).translation.vector.iter());
        }
        obs
    }

    fn scripts(&self) -> Vec<PickPlaceScript> {
        vec![Self::script()]
    }

    fn coverage_dimensions(&self) -> Vec<Dimension> {
        let fixed =
            PlacementRegion { x: (PEG_DEFAULT_POS[0], PEG_DEFAULT_POS[0]), y: (PEG_DEFAULT_POS[1], PEG_DEFAULT_POS[1]), yaw: (0.0, 0.0) };
        region_dimensions(&["square_nut", "square_peg"], &[self.nut, self.peg.unwrap_or(fixed)])
    }
}
