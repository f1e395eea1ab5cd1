//! Composing task scenes: our base MJCF (table arena, Panda, gripper, mount; see
//! `viewer_assets/scenes/`) plus the task's objects, written as robosuite writes them.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use mimicgen_engine::pose::{Rot, Vec3, quat_to_wxyz};

use crate::mjcf_edit::words;

/// The base scene: robosuite's table arena with a Panda on its mount, asset paths as `{ASSETS}/`.
pub const PANDA_TABLE_XML: &str = crate::robot::PANDA.base_xml;

/// An object model to add to a scene: a task file's `model`, tagged by `kind` (`box`,
/// `square_nut`, `round_nut`, `fixed_box`, `fixed_cylinder`, `compound`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ObjectModel {
    /// A box with a free joint, as robosuite's `BoxObject`: a collision geom and a textured visual
    /// geom, body `<name>_main`, joint `<name>_joint0`, geom `<name>_g0`.
    Box {
        /// Object name (`cubeA`).
        name: String,
        /// Half extents (m).
        half_size: [f64; 3],
        /// Colour of the collision geom.
        rgba: [f64; 4],
        /// Texture for the visual geom: `(texture name, file under the assets directory)`.
        texture: (String, String),
    },
    /// robosuite's `SquareNutObject` (`objects/square-nut.xml`): four bars round a square hole
    /// and a handle along +x, body `<name>_main` with a free joint, geoms in `<name>_object`.
    SquareNut {
        /// Object name (`SquareNut`).
        name: String,
    },
    /// robosuite's `RoundNutObject` (`objects/round-nut.xml`): eight bars round a round hole and a
    /// handle along +x, body `<name>_main` with a free joint.
    RoundNut {
        /// Object name (`RoundNut`).
        name: String,
    },
    /// A cylinder fixed in the world, as robosuite's round peg (`peg2`): a mocap body.
    FixedCylinder {
        /// Body name (`peg2`).
        body: String,
        /// Radius and half height (m).
        radius_half_height: [f64; 2],
        /// Default position (m).
        pos: [f64; 3],
    },
    /// A box fixed in the world that the task may move between episodes, as robosuite's pegs:
    /// a mocap body (it never moves during an episode; resets set its pose).
    FixedBox {
        /// Body name (`peg1`).
        body: String,
        /// Half extents (m).
        half_size: [f64; 3],
        /// Default position (m), the one a scene has before any reset.
        pos: [f64; 3],
    },
    /// An object from a mesh in robosuite's assets, as robosuite's `MilkObject` and the like: body
    /// `<name>_main` with a free joint, the mesh as collision geom `<name>_g0` and, textured, as
    /// visual geom.
    Mesh {
        /// Object name (`milk`).
        name: String,
        /// The mesh file under the assets directory (`objects/meshes/milk.msh`).
        mesh: String,
        /// The mesh's scale.
        #[serde(default = "unit_scale")]
        scale: [f64; 3],
        /// The texture file under the assets directory (`textures/ceramic.png`).
        texture: String,
        /// Density (kg/m^3).
        density: f64,
    },
    /// A mug from primitive geoms: a bottom disc, a wall of 16 boxes and a handle of two arms
    /// and a bar. Its frame is wherever `base_m` and `handle_yaw_deg` put it (by default at the
    /// centre of its base, the handle along +x; the reference's ShapeNet mugs have theirs at the
    /// mesh's origin, the handle along +y). Written as a free [`ObjectModel::Compound`] (geoms
    /// `<name>_g<i>`); varied, it is the paper's set of mugs for object transfer.
    Mug {
        /// Object name (`mug`).
        name: String,
        /// Outer radius (m).
        radius_m: f64,
        /// Height, base to rim (m).
        height_m: f64,
        /// Wall thickness (m).
        wall_m: f64,
        /// The handle: how far it reaches out from the wall, and the heights of its lower and
        /// upper arms (m).
        handle_m: [f64; 3],
        /// The centre of its base in its frame (m).
        #[serde(default)]
        base_m: [f64; 3],
        /// The direction of its handle in its frame (deg about z from +x).
        #[serde(default)]
        handle_yaw_deg: f64,
        /// Colour.
        rgba: [f64; 4],
        /// Density (kg/m^3).
        density: f64,
        /// MuJoCo friction of every geom (sliding, torsional, rolling); robosuite's 0.95, 0.3,
        /// 0.1 when absent. The reference's ShapeNet mugs have (1, 1, 1).
        #[serde(default)]
        friction: Option<[f64; 3]>,
        /// MuJoCo solref of every geom (time constant, damping ratio); (0.02, 1) when absent.
        /// The reference's ShapeNet mugs have (0.001, 1).
        #[serde(default)]
        solref: Option<[f64; 2]>,
        /// MuJoCo margin of every geom (m): contacts count from this far apart; 0 when absent.
        /// The reference's ShapeNet mugs have 0.001.
        #[serde(default)]
        margin: Option<f64>,
    },
    /// An object built from primitive geoms (ours, for the tasks whose objects robosuite does not
    /// ship): body `<name>_main`, with a free joint, or fixed in the world (a mocap body the task
    /// may move between episodes); collision geoms `<name>_g<i>` and coloured visual copies.
    Compound {
        /// Object name (`needle`).
        name: String,
        /// Its geoms, in the object frame.
        geoms: Vec<Part>,
        /// Fixed in the world rather than free.
        #[serde(default)]
        fixed: bool,
        /// Colour of every geom without its own.
        rgba: [f64; 4],
        /// A hinged part (a lid), if it has one.
        #[serde(default)]
        hinge: Option<Hinge>,
        /// A sliding part (a drawer), if it has one.
        #[serde(default)]
        slide: Option<Slide>,
    },
}

/// A hinged part of a [`ObjectModel::Compound`]: body `<name>_lid` on joint `<name>_hinge`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Hinge {
    /// The hinge's position in the object frame (m).
    pub pos: [f64; 3],
    /// Its axis in the object frame.
    pub axis: [f64; 3],
    /// The part's turn about the axis from closed to open at reset (deg): the joint reads 0 open
    /// and `-open_deg` closed.
    pub open_deg: f64,
    /// The joint's range (deg) in place of the one `open_deg` implies: for a part that starts
    /// closed (`open_deg = 0`) and opens by turning, a lid opened to `[-100, 0]`.
    #[serde(default)]
    pub range_deg: Option<[f64; 2]>,
    /// What the joint reads at reset (deg; MJCF's `ref`): 0 unless the part's own zero is
    /// elsewhere (a switch that rests at -17.2 deg, off, and is on from 0 up).
    #[serde(default)]
    pub start_deg: f64,
    /// Viscous damping of the joint (N m s/rad).
    #[serde(default = "hinge_damping")]
    pub damping: f64,
    /// Dry friction of the joint (N m): a part it holds wherever it is pushed to.
    #[serde(default)]
    pub frictionloss: f64,
    /// The part's mass and inertia in place of its geoms' (a part whose maker gave them).
    #[serde(default)]
    pub inertial: Option<Box<Inertial>>,
    /// Its geoms, relative to the hinge, as they sit when closed.
    pub geoms: Vec<Part>,
}

fn hinge_damping() -> f64 {
    0.01
}

/// A body's mass and inertia, as MJCF's `<inertial>` gives them (relative to its hinge).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inertial {
    /// Centre of mass (m).
    pub pos: [f64; 3],
    /// Orientation of the principal axes (w, x, y, z).
    pub quat: [f64; 4],
    /// Mass (kg).
    pub mass: f64,
    /// Principal moments of inertia (kg m^2).
    pub diaginertia: [f64; 3],
}

/// A sliding part of a [`ObjectModel::Compound`]: body `<name>_drawer` on joint `<name>_slide`,
/// closed at reset. The joint reads how far it is pulled out along `axis` (m): 0 closed.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Slide {
    /// The direction it pulls out, in the object frame.
    pub axis: [f64; 3],
    /// How far it can be pulled out (m).
    pub travel_m: f64,
    /// Viscous damping of the slide (N s/m): how hard it is to move quickly.
    #[serde(default = "drawer_damping")]
    pub damping: f64,
    /// The moving part's mass and inertia in place of its geoms' (a drawer whose maker gave them).
    #[serde(default)]
    pub inertial: Option<Box<Inertial>>,
    /// Its geoms, in the object frame, as they sit when closed.
    pub geoms: Vec<Part>,
}

fn drawer_damping() -> f64 {
    10.0
}

fn unit_scale() -> [f64; 3] {
    [1.0; 3]
}

/// One primitive geom of a [`ObjectModel::Compound`].
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part {
    /// MuJoCo geom type: `box`, `cylinder`, `capsule` or `sphere`; or `convex_box`, a box that
    /// collides as a convex mesh (MuJoCo's general convex collider, one contact per geom pair at
    /// the true depth), as the reference's mesh objects do: a stand-in for a mesh's hull.
    #[serde(rename = "type")]
    pub kind: String,
    /// MuJoCo `size` (half extents for a box; radius and half length for a cylinder).
    pub size: Vec<f64>,
    /// Position in the object frame (m).
    #[serde(default)]
    pub pos: [f64; 3],
    /// Turn about the object frame's z axis (deg).
    #[serde(default)]
    pub yaw_deg: f64,
    /// Turn about the object frame's x axis (deg), applied before the yaw: 90 lays a cylinder
    /// along y, and a yaw of 90 after it turns that cylinder to lie along x.
    #[serde(default)]
    pub roll_deg: f64,
    /// Colour; the object's when absent.
    #[serde(default)]
    pub rgba: Option<[f64; 4]>,
    /// Density (kg/m^3); MuJoCo's default (water) when absent.
    #[serde(default)]
    pub density: Option<f64>,
    /// Seen but never touched: no collision geom, only the coloured copy (a burner's plate, a
    /// serving region painted on the table).
    #[serde(default)]
    pub visual: bool,
    /// MuJoCo friction (sliding, torsional, rolling); robosuite's 0.95, 0.3, 0.1 when absent.
    #[serde(default)]
    pub friction: Option<[f64; 3]>,
    /// MuJoCo solref (time constant, damping ratio); (0.02, 1) when absent.
    #[serde(default)]
    pub solref: Option<[f64; 2]>,
    /// MuJoCo margin (m): contacts count from this far apart; 0 when absent.
    #[serde(default)]
    pub margin: Option<f64>,
    /// A name predicates can touch it by (`contact = ["mug", "coffee_machine.base"]`): its geom is
    /// `<object>_<name>_g<k>`, the k-th of the object's parts so named, as the reference names
    /// Coffee Preparation's base plate `coffee_machine_base_g0`.
    #[serde(default)]
    pub name: Option<String>,
}

/// robosuite's square nut: `(position, half extents)` of its five box geoms, in the nut frame.
const SQUARE_NUT_GEOMS: [([f64; 3], [f64; 3]); 5] = [
    ([-0.03325, 0.0, 0.0], [0.0105, 0.04375, 0.01]),
    ([0.0, 0.03325, 0.0], [0.03125, 0.0105, 0.01]),
    ([0.0, -0.03325, 0.0], [0.03125, 0.0105, 0.01]),
    ([0.03325, 0.0, 0.0], [0.0105, 0.04375, 0.01]),
    ([0.054, 0.0, 0.0], [0.02525, 0.015875, 0.01]),
];

/// robosuite's round nut: `(position, half extents, yaw)` of its nine box geoms, in the nut frame.
const ROUND_NUT_GEOMS: [([f64; 3], [f64; 3], f64); 9] = [
    ([-0.04245, 0.0, 0.0], [0.01125, 0.0225, 0.01], 0.0),
    ([0.04245, 0.0, 0.0], [0.01125, 0.0225, 0.01], 0.0),
    ([0.0, -0.04245, 0.0], [0.0225, 0.01125, 0.01], 0.0),
    ([0.0, 0.04245, 0.0], [0.0225, 0.01125, 0.01], 0.0),
    ([-0.03, -0.03, 0.0], [0.01125, 0.0225, 0.01], std::f64::consts::FRAC_PI_4),
    ([0.03, 0.03, 0.0], [0.01125, 0.0225, 0.01], std::f64::consts::FRAC_PI_4),
    ([0.03, -0.03, 0.0], [0.0225, 0.01125, 0.01], std::f64::consts::FRAC_PI_4),
    ([-0.03, 0.03, 0.0], [0.0225, 0.01125, 0.01], std::f64::consts::FRAC_PI_4),
    ([0.06, 0.0, 0.0], [0.02525, 0.015875, 0.01], 0.0),
];

/// Where robosuite's round nut handle is, in the nut frame (m): its `handle_site`.
const ROUND_NUT_HANDLE: [f64; 3] = [0.06, 0.0, 0.0];

/// Where robosuite's square nut handle is, in the nut frame (m): its `handle_site`.
const SQUARE_NUT_HANDLE: [f64; 3] = [0.054, 0.0, 0.0];

impl ObjectModel {
    /// How far its frame stands above the bottom it rests on (m): robosuite's `-bottom_offset`
    /// (a mug's frame at its mesh's origin); 0 for a model whose frame is at its bottom or whose
    /// task sets the height itself.
    #[must_use]
    pub fn origin_above_bottom_m(&self) -> f64 {
        match self {
            Self::Mug { base_m, .. } => -base_m[2],
            _ => 0.0,
        }
    }

    /// Contact pairs MuJoCo's parent filter would drop: a fixed cabinet's geoms against its
    /// drawer's. The reference's cabinet is welded to the world, so its drawer meets it (the
    /// back wall stops on the front posts 13.5 cm out); ours is a mocap body that resets move,
    /// and a mocap body's child is filtered against it unless the pairs are explicit.
    fn contact_pairs(&self) -> Vec<(String, String)> {
        let Self::Compound { name, geoms, fixed: true, slide: Some(slide), .. } = self else {
            return Vec::new();
        };
        (0..geoms.len())
            .flat_map(|i| (0..slide.geoms.len()).map(move |j| (format!("{name}_g{i}"), format!("{name}_drawer_g{j}"))))
            .collect()
    }

    /// Whether a [`ObjectModel::Compound`] has a part (its own, its hinged or its sliding part's)
    /// named `name`.
    #[must_use]
    pub fn has_part(&self, name: &str) -> bool {
        let Self::Compound { geoms, hinge, slide, .. } = self else {
            return false;
        };
        let hinged = hinge.iter().flat_map(|h| &h.geoms);
        let sliding = slide.iter().flat_map(|s| &s.geoms);
        geoms.iter().chain(hinged).chain(sliding).any(|p| p.name.as_deref() == Some(name))
    }

    /// The body whose frame is the object's pose.
    #[must_use]
    pub fn body_name(&self) -> String {
        match self {
            Self::Box { name, .. }
            | Self::SquareNut { name }
            | Self::RoundNut { name }
            | Self::Compound { name, .. }
            | Self::Mug { name, .. }
            | Self::Mesh { name, .. } => {
                format!("{name}_main")
            }
            Self::FixedBox { body, .. } | Self::FixedCylinder { body, .. } => body.clone(),
        }
    }

    /// A [`ObjectModel::Mug`]'s geoms (empty for any other model).
    fn mug_parts(&self) -> Vec<Part> {
        const WALL_BOXES: u32 = 16;
        const BOTTOM_M: f64 = 0.008;
        let Self::Mug {
            radius_m: r,
            height_m: h,
            wall_m: w,
            handle_m: [reach, low, high],
            base_m,
            handle_yaw_deg,
            density,
            friction,
            solref,
            margin,
            ..
        } = *self
        else {
            return Vec::new();
        };
        // Built with the base at the origin and the handle along +x, then turned and moved into
        // the mug's frame.
        let (sin, cos) = handle_yaw_deg.to_radians().sin_cos();
        let part = |size: Vec<f64>, [x, y, z]: [f64; 3], yaw_deg: f64, kind: &str| Part {
            kind: kind.to_owned(),
            size,
            pos: [base_m[0] + cos * x - sin * y, base_m[1] + sin * x + cos * y, base_m[2] + z],
            yaw_deg: yaw_deg + handle_yaw_deg,
            roll_deg: 0.0,
            rgba: None,
            density: Some(density),
            visual: false,
            friction,
            solref,
            margin,
            name: None,
        };
        let middle = r - w / 2.0;
        let step = std::f64::consts::TAU / f64::from(WALL_BOXES);
        // Each box a little wider than its share of the circle, so the wall has no gaps.
        let half_width = middle * (step / 2.0).tan() * 1.06;
        let mut parts = vec![part(vec![middle, BOTTOM_M / 2.0], [0.0, 0.0, BOTTOM_M / 2.0], 0.0, "cylinder")];
        for k in 0..WALL_BOXES {
            let angle = step * f64::from(k);
            let pos = [middle * angle.cos(), middle * angle.sin(), (h + BOTTOM_M / 2.0) / 2.0];
            parts.push(part(vec![w / 2.0, half_width, (h - BOTTOM_M / 2.0) / 2.0], pos, angle.to_degrees(), CONVEX_BOX));
        }
        let (arm, bar) = ([reach / 2.0, 0.005, 0.004], 0.004);
        for z in [high, low] {
            parts.push(part(arm.to_vec(), [r + reach / 2.0, 0.0, z], 0.0, CONVEX_BOX));
        }
        parts.push(part(vec![bar, 0.005, (high - low) / 2.0 + bar], [r + reach - bar, 0.0, (high + low) / 2.0], 0.0, CONVEX_BOX));
        parts
    }

    fn write_assets(&self, out: &mut String) {
        match self {
            Self::Box { name, texture: (tex, file), .. } => {
                let _ = writeln!(out, r#"    <texture type="cube" name="{name}_{tex}" file="{{ASSETS}}/{file}"/>"#);
                let _ = writeln!(out, r#"    <material name="{name}_{tex}_mat" texture="{name}_{tex}" specular="0.4" shininess="0.1"/>"#);
            }
            Self::SquareNut { name } | Self::RoundNut { name } => write_brass(out, name),
            Self::FixedBox { body, .. } | Self::FixedCylinder { body, .. } => write_brass(out, body),
            Self::Mug { name, .. } => write_hulls(out, name, &self.mug_parts()),
            Self::Compound { name, geoms, hinge, slide, .. } => {
                write_hulls(out, name, geoms);
                if let Some(h) = hinge {
                    write_hulls(out, &format!("{name}_lid"), &h.geoms);
                }
                if let Some(s) = slide {
                    write_hulls(out, &format!("{name}_drawer"), &s.geoms);
                }
            }
            Self::Mesh { name, mesh, scale: [sx, sy, sz], texture, .. } => {
                let _ = writeln!(out, r#"    <mesh name="{name}_mesh" file="{{ASSETS}}/{mesh}" scale="{sx} {sy} {sz}"/>"#);
                let _ = writeln!(out, r#"    <texture type="2d" name="{name}_tex" file="{{ASSETS}}/{texture}"/>"#);
                let _ = writeln!(
                    out,
                    r#"    <material name="{name}_mat" texture="{name}_tex" reflectance="0.5" texrepeat="1 1" texuniform="true"/>"#
                );
            }
        }
    }

    fn write_body(&self, out: &mut String) {
        match self {
            Self::Box { name, half_size: [x, y, z], rgba: [r, g, b, a], texture: (tex, _) } => {
                let _ = writeln!(out, r#"    <body name="{name}_main" pos="0 0 0" gravcomp="0">"#);
                let _ = writeln!(out, r#"      <joint name="{name}_joint0" type="free"/>"#);
                let _ = writeln!(out, r#"      <geom name="{name}_g0" size="{x} {y} {z}" type="box" rgba="{r} {g} {b} {a}"/>"#);
                let _ = writeln!(
                    out,
                    r#"      <geom name="{name}_g0_vis" size="{x} {y} {z}" type="box" contype="0" conaffinity="0" group="1" mass="0" material="{name}_{tex}_mat"/>"#
                );
                let _ = writeln!(out, r#"      <site name="{name}_default_site" pos="0 0 0" size="0.002" rgba="1 0 0 -1"/>"#);
                let _ = writeln!(out, "    </body>");
            }
            Self::SquareNut { name } => {
                let geoms = SQUARE_NUT_GEOMS.map(|(pos, size)| (pos, size, 0.0));
                write_nut(out, name, &geoms, SQUARE_NUT_HANDLE, 0.01, [0.11, 0.06]);
            }
            Self::RoundNut { name } => write_nut(out, name, &ROUND_NUT_GEOMS, ROUND_NUT_HANDLE, 0.025, [0.11, 0.05]),
            Self::FixedCylinder { body, radius_half_height: [r, h], pos: [px, py, pz] } => {
                let _ = writeln!(out, r#"    <body name="{body}" pos="{px} {py} {pz}" mocap="true">"#);
                let _ = writeln!(
                    out,
                    r#"      <geom name="{body}_g0" size="{r} {h}" type="cylinder" group="0" friction="1 0.005 0.0001" rgba="0.5 0 0 1"/>"#
                );
                let _ = writeln!(
                    out,
                    r#"      <geom name="{body}_vis" size="{r} {h}" type="cylinder" contype="0" conaffinity="0" group="1" material="{body}_bmetal"/>"#
                );
                let _ = writeln!(out, "    </body>");
            }
            Self::Mesh { name, density, .. } => {
                let _ = writeln!(out, r#"    <body name="{name}_main" pos="0 0 0" gravcomp="0">"#);
                let _ = writeln!(out, r#"      <joint name="{name}_joint0" type="free" damping="0.0005"/>"#);
                let _ = writeln!(
                    out,
                    r#"      <geom name="{name}_g0" type="mesh" mesh="{name}_mesh" solimp="0.998 0.998 0.001" solref="0.001 1" density="{density}" friction="0.95 0.3 0.1" condim="4" group="0" rgba="0.5 0 0 1"/>"#
                );
                let _ = writeln!(
                    out,
                    r#"      <geom name="{name}_vis" type="mesh" mesh="{name}_mesh" contype="0" conaffinity="0" group="1" mass="0" material="{name}_mat"/>"#
                );
                let _ = writeln!(out, r#"      <site name="{name}_default_site" pos="0 0 0" size="0.002" rgba="1 0 0 -1"/>"#);
                let _ = writeln!(out, "    </body>");
            }
            Self::Mug { name, rgba, .. } => write_compound(out, name, &self.mug_parts(), false, *rgba, None, None),
            Self::Compound { name, geoms, fixed, rgba, hinge, slide } => {
                write_compound(out, name, geoms, *fixed, *rgba, hinge.as_ref(), slide.as_ref());
            }
            Self::FixedBox { body, half_size: [x, y, z], pos: [px, py, pz] } => {
                let _ = writeln!(out, r#"    <body name="{body}" pos="{px} {py} {pz}" mocap="true">"#);
                let _ = writeln!(
                    out,
                    r#"      <geom name="{body}_g0" size="{x} {y} {z}" type="box" group="0" friction="1 0.005 0.0001" rgba="0.5 0 0 1"/>"#
                );
                let _ = writeln!(
                    out,
                    r#"      <geom name="{body}_vis" size="{x} {y} {z}" type="box" contype="0" conaffinity="0" group="1" material="{body}_bmetal"/>"#
                );
                let _ = writeln!(out, "    </body>");
            }
        }
    }
}

/// A [`ObjectModel::Compound`]: collision geoms (group 0) and visual copies (group 1), and its
/// hinged and sliding parts.
fn write_compound(out: &mut String, name: &str, geoms: &[Part], fixed: bool, rgba: [f64; 4], hinge: Option<&Hinge>, slide: Option<&Slide>) {
    let joint = if fixed { r#" mocap="true""# } else { r#" gravcomp="0""# };
    let _ = writeln!(out, r#"    <body name="{name}_main" pos="0 0 0"{joint}>"#);
    if !fixed {
        let _ = writeln!(out, r#"      <joint name="{name}_joint0" type="free" damping="0.0005"/>"#);
    }
    write_parts(out, name, geoms, rgba, "      ");
    if let Some(h) = hinge {
        let (pos, axis) = (words(&h.pos), words(&h.axis));
        let open = h.open_deg.to_radians();
        let range = match h.range_deg {
            Some([low, high]) => format!("{} {}", low.to_radians(), high.to_radians()),
            None if open < 0.0 => format!("0 {}", -open),
            None => format!("{} 0", -open),
        };
        let (start, damping, frictionloss) = (h.start_deg.to_radians(), h.damping, h.frictionloss);
        let _ = writeln!(out, r#"      <body name="{name}_lid" pos="{pos}" axisangle="{axis} {open}">"#);
        write_inertial(out, h.inertial.as_deref());
        let extra = if frictionloss > 0.0 { format!(r#" frictionloss="{frictionloss}""#) } else { String::new() };
        let reference = if start == 0.0 { String::new() } else { format!(r#" ref="{start}""#) };
        let _ = writeln!(
            out,
            r#"        <joint name="{name}_hinge" type="hinge" axis="{axis}" range="{range}"{reference} damping="{damping}"{extra}/>"#
        );
        write_parts(out, &format!("{name}_lid"), &h.geoms, rgba, "        ");
        let _ = writeln!(out, "      </body>");
    }
    if let Some(s) = slide {
        let (axis, travel, damping) = (words(&s.axis), s.travel_m, s.damping);
        let _ = writeln!(out, r#"      <body name="{name}_drawer" pos="0 0 0">"#);
        write_inertial(out, s.inertial.as_deref());
        let _ = writeln!(
            out,
            r#"        <joint name="{name}_slide" type="slide" axis="{axis}" range="0 {travel}" limited="true" damping="{damping}" armature="0.1"/>"#
        );
        write_parts(out, &format!("{name}_drawer"), &s.geoms, rgba, "        ");
        let _ = writeln!(out, "      </body>");
    }
    let _ = writeln!(out, r#"      <site name="{name}_default_site" pos="0 0 0" size="0.002" rgba="1 0 0 -1"/>"#);
    let _ = writeln!(out, "    </body>");
}

/// A hinged or sliding part's given mass and inertia, if it has them.
fn write_inertial(out: &mut String, inertial: Option<&Inertial>) {
    if let Some(i) = inertial {
        let (pos, quat, mass, diag) = (words(&i.pos), words(&i.quat), i.mass, words(&i.diaginertia));
        let _ = writeln!(out, r#"        <inertial pos="{pos}" quat="{quat}" mass="{mass}" diaginertia="{diag}"/>"#);
    }
}

/// The geom names of `owner`'s parts: `<owner>_g<i>` by their place in `geoms`, or
/// `<owner>_<name>_g<k>` for the k-th part named `name`.
fn part_geom_names(owner: &str, geoms: &[Part]) -> Vec<String> {
    let mut named: BTreeMap<&str, usize> = BTreeMap::new();
    geoms
        .iter()
        .enumerate()
        .map(|(i, part)| match &part.name {
            Some(name) => {
                let k = named.entry(name.as_str()).or_default();
                *k += 1;
                format!("{owner}_{name}_g{}", *k - 1)
            }
            None => format!("{owner}_g{i}"),
        })
        .collect()
}

/// The mesh assets of `owner`'s `convex_box` parts (`<geom>_hull`: the box's eight corners).
fn write_hulls(out: &mut String, owner: &str, geoms: &[Part]) {
    for (part, geom) in geoms.iter().zip(part_geom_names(owner, geoms)) {
        if part.kind == CONVEX_BOX {
            let [x, y, z] = [0, 1, 2].map(|k| part.size.get(k).copied().unwrap_or_default());
            let corners: Vec<f64> = (0..8)
                .flat_map(|c| [if c & 1 == 0 { -x } else { x }, if c & 2 == 0 { -y } else { y }, if c & 4 == 0 { -z } else { z }])
                .collect();
            let _ = writeln!(out, r#"    <mesh name="{geom}_hull" vertex="{}"/>"#, words(&corners));
        }
    }
}

/// The part kind of a box that collides as a convex mesh ([`Part::kind`]).
const CONVEX_BOX: &str = "convex_box";

/// `owner`'s collision geoms and their visual copies, named by [`part_geom_names`].
fn write_parts(out: &mut String, owner: &str, geoms: &[Part], rgba: [f64; 4], indent: &str) {
    for (part, geom) in geoms.iter().zip(part_geom_names(owner, geoms)) {
        let [r, g, b, a] = part.rgba.unwrap_or(rgba);
        let (roll, yaw) = (part.roll_deg.to_radians(), part.yaw_deg.to_radians());
        let turn = if yaw == 0.0 && roll == 0.0 {
            String::new()
        } else if yaw == 0.0 || roll == 0.0 {
            format!(r#" euler="{roll} 0 {yaw}""#)
        } else {
            // The roll about the object's x, then the yaw about its z: MJCF's euler turns about
            // axes that move with the part, so both together are written as one quaternion.
            let q = Rot::from_axis_angle(&Vec3::z_axis(), yaw) * Rot::from_axis_angle(&Vec3::x_axis(), roll);
            format!(r#" quat="{}""#, words(&quat_to_wxyz(&q)))
        };
        let (size, pos) = (words(&part.size), words(&part.pos));
        let (kind, shape) = if part.kind == CONVEX_BOX {
            ("box", format!(r#"type="mesh" mesh="{geom}_hull""#))
        } else {
            (part.kind.as_str(), format!(r#"type="{}" size="{size}""#, part.kind))
        };
        let density = part.density.map_or_else(String::new, |d| format!(r#" density="{d}""#));
        let friction = words(&part.friction.unwrap_or([0.95, 0.3, 0.1]));
        let solref = words(&part.solref.unwrap_or([0.02, 1.0]));
        let margin = part.margin.map_or_else(String::new, |m| format!(r#" margin="{m}""#));
        if !part.visual {
            let _ = writeln!(
                out,
                r#"{indent}<geom name="{geom}" {shape} pos="{pos}"{turn}{density} friction="{friction}" condim="4" solimp="0.998 0.998 0.001" solref="{solref}"{margin} group="0" rgba="{r} {g} {b} {a}"/>"#
            );
        }
        let _ = writeln!(
            out,
            r#"{indent}<geom name="{geom}_vis" type="{kind}" size="{size}" pos="{pos}"{turn} contype="0" conaffinity="0" group="1" mass="0" rgba="{r} {g} {b} {a}"/>"#
        );
    }
}

/// One of robosuite's nuts: box `geoms` (`(position, half extents, yaw)` in the nut frame) round a
/// hole, a free joint, and its handle, centre, bottom, top and horizontal-radius sites (the top at
/// `top_z`, the radius site at `radius_site` (x, y)).
fn write_nut(out: &mut String, name: &str, geoms: &[([f64; 3], [f64; 3], f64)], handle: [f64; 3], top_z: f64, radius_site: [f64; 2]) {
    let _ = writeln!(out, r#"    <body name="{name}_main" pos="0 0 0" gravcomp="0">"#);
    let _ = writeln!(out, r#"      <joint name="{name}_joint0" type="free" damping="0.0005"/>"#);
    let _ = writeln!(out, r#"      <body name="{name}_object" pos="0 0 0" gravcomp="0">"#);
    for (i, ([px, py, pz], [sx, sy, sz], yaw)) in geoms.iter().enumerate() {
        let (pos, size) = (format!("{px} {py} {pz}"), format!("{sx} {sy} {sz}"));
        // Only rotated bars carry an axisangle. Visual geoms are named as robosuite names them
        // (`_visual`), so robosuite loads the model_file.
        let turn = if *yaw == 0.0 { String::new() } else { format!(r#" axisangle="0 0 1 {yaw}""#) };
        let _ = writeln!(
            out,
            r#"        <geom name="{name}_g{i}" pos="{pos}" size="{size}"{turn} type="box" solimp="0.998 0.998 0.001" solref="0.02 1" density="100" friction="0.95 0.3 0.1" condim="4" group="0" rgba="0.5 0 0 1"/>"#
        );
        let _ = writeln!(
            out,
            r#"        <geom name="{name}_g{i}_visual" pos="{pos}" size="{size}"{turn} type="box" contype="0" conaffinity="0" group="1" mass="0" material="{name}_bmetal"/>"#
        );
    }
    let [hx, hy, hz] = handle;
    let [rx, ry] = radius_site;
    let _ = writeln!(out, r#"        <site name="{name}_handle_site" pos="{hx} {hy} {hz}" size="0.005" rgba="1 0 0 -1"/>"#);
    let _ = writeln!(out, r#"        <site name="{name}_center_site" pos="0 0 0" size="0.003" rgba="1 0 0 -1"/>"#);
    let _ = writeln!(out, "      </body>");
    let _ = writeln!(out, r#"      <site name="{name}_bottom_site" pos="0 0 -0.05" size="0.005" rgba="0 0 0 0"/>"#);
    let _ = writeln!(out, r#"      <site name="{name}_top_site" pos="0 0 {top_z}" size="0.005" rgba="0 0 0 0"/>"#);
    let _ = writeln!(out, r#"      <site name="{name}_horizontal_radius_site" pos="{rx} {ry} 0" size="0.005" rgba="0 0 0 0"/>"#);
    // robosuite's nut objects look this site up when they load a model_file.
    let _ = writeln!(out, r#"      <site name="{name}_default_site" pos="0 0 0" size="0.002" rgba="1 0 0 0"/>"#);
    let _ = writeln!(out, "    </body>");
}

/// robosuite's brushed-brass material (nuts and pegs), named after `owner`.
fn write_brass(out: &mut String, owner: &str) {
    let _ = writeln!(out, r#"    <texture type="cube" name="{owner}_brass" file="{{ASSETS}}/textures/brass-ambra.png"/>"#);
    let _ = writeln!(
        out,
        r#"    <material name="{owner}_bmetal" texture="{owner}_brass" reflectance="1.0" shininess="1.0" specular="1.0" texrepeat="1 1" texuniform="true"/>"#
    );
}

/// The table height of the base scene (m): robosuite's `table_offset` z for most tasks.
pub const BASE_TABLE_TOP_Z: f64 = 0.8;

/// The base scene's table with its top at `top_z` (robosuite's `table_offset` z; 0.82 for nut
/// assembly): the table body and its legs, as robosuite's `TableArena` sizes them.
fn with_table_top(xml: &str, top_z: f64) -> String {
    if (top_z - BASE_TABLE_TOP_Z).abs() < 1e-12 {
        return xml.to_owned();
    }
    // Rounded to the micrometre so the XML reads 0.795, not 0.7949999999999999.
    let body_z = ((top_z - 0.025) * 1e6).round() / 1e6;
    let leg_half = (body_z / 2.0 * 1e7).round() / 1e7;
    xml.replace(r#"<body name="table" pos="0 0 0.775""#, &format!(r#"<body name="table" pos="0 0 {body_z}""#))
        .replace(r#"size="0.025 0.3875""#, &format!(r#"size="0.025 {leg_half}""#))
        .replace(r#" -0.3875""#, &format!(r#" -{leg_half}""#))
}

/// The base scene with its table top at `table_top_z`, `objects` added and asset paths pointing
/// into `assets_dir`.
#[must_use]
pub fn compose_scene(assets_dir: &Path, objects: &[ObjectModel], table_top_z: f64) -> String {
    compose_scene_with(&crate::robot::PANDA, assets_dir, objects, table_top_z, [0.0; 2])
}

/// [`compose_scene`] with another arm's base scene, its robot and table moved by
/// `robot_offset_m` in x and y (a task whose world frame is another robosuite arena's).
#[must_use]
pub fn compose_scene_with(
    robot: &crate::robot::RobotModel,
    assets_dir: &Path,
    objects: &[ObjectModel],
    table_top_z: f64,
    robot_offset_m: [f64; 2],
) -> String {
    let (mut assets, mut bodies) = (String::new(), String::new());
    for object in objects {
        object.write_assets(&mut assets);
        object.write_body(&mut bodies);
    }
    let mut base = with_table_top(robot.base_xml, table_top_z);
    if robot_offset_m.iter().any(|v| *v != 0.0) {
        // Every base scene has both bodies (the tests below compose each arm's).
        for body in ["robot0_base", "table"] {
            base = crate::mjcf_edit::shift_body(&base, body, robot_offset_m).unwrap_or(base);
        }
    }
    let xml = base
        .replace("    <!-- OBJECT ASSETS -->\n", &assets)
        .replace("    <!-- OBJECT BODIES -->\n", &bodies)
        .replace("{ASSETS}", assets_dir.display().to_string().trim_end_matches('/'));
    let pairs: Vec<(String, String)> = objects.iter().flat_map(ObjectModel::contact_pairs).collect();
    if pairs.is_empty() {
        return xml;
    }
    // The parts' own contact parameters (write_parts), as MuJoCo would mix them.
    let mut section = String::from("  <contact>\n");
    for (a, b) in pairs {
        let _ = writeln!(
            section,
            r#"    <pair geom1="{a}" geom2="{b}" condim="4" friction="0.95 0.95 0.3 0.1 0.1" solref="0.02 1" solimp="0.998 0.998 0.001"/>"#
        );
    }
    section.push_str("  </contact>\n");
    crate::mjcf_edit::with_section(&xml, &section)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_moves_with_its_legs() {
        let xml = with_table_top(PANDA_TABLE_XML, 0.82);
        assert!(xml.contains(r#"<body name="table" pos="0 0 0.795""#));
        assert_eq!(xml.matches("0.3975").count(), 8, "four legs, each a size and a position");
        assert!(!xml.contains("0.3875"));
        assert_eq!(with_table_top(PANDA_TABLE_XML, BASE_TABLE_TOP_Z), PANDA_TABLE_XML);
    }

    #[test]
    fn an_offset_moves_every_arm_and_its_table_but_nothing_else() {
        for robot in crate::robot::ROBOTS {
            let still = compose_scene_with(robot, Path::new("/a"), &[], BASE_TABLE_TOP_Z, [0.0; 2]);
            let moved = compose_scene_with(robot, Path::new("/a"), &[], BASE_TABLE_TOP_Z, [0.06, -0.1]);
            let pos = |xml: &str, body: &str| -> Vec<f64> {
                let start = xml.find(&format!(r#"<body name="{body}""#)).unwrap_or_else(|| panic!("{}: no {body}", robot.robosuite_name));
                let tag = &xml[start..start + xml[start..].find('>').unwrap_or_default()];
                let value = tag.split(r#"pos=""#).nth(1).and_then(|v| v.split('"').next()).unwrap_or_default();
                value.split_whitespace().map(|w| w.parse().unwrap_or(f64::NAN)).collect()
            };
            for body in ["robot0_base", "table"] {
                let (a, b) = (pos(&still, body), pos(&moved, body));
                let d: Vec<f64> = b.iter().zip(&a).map(|(b, a)| ((b - a) * 1e9).round() / 1e9).collect();
                assert_eq!(d, [0.06, -0.1, 0.0], "{} {body}: {a:?} -> {b:?}", robot.robosuite_name);
            }
            assert_eq!(pos(&still, "mount0_base"), pos(&moved, "mount0_base"), "children keep their parent's frame");
            assert_eq!(still.lines().count(), moved.lines().count());
        }
    }

    #[test]
    fn a_part_rolled_then_turned_lies_along_x() {
        let bar = Part {
            kind: "capsule".to_owned(),
            size: vec![0.009, 0.05],
            pos: [0.0, -0.17, 0.121],
            yaw_deg: 90.0,
            roll_deg: 90.0,
            rgba: None,
            density: None,
            visual: false,
            friction: None,
            solref: None,
            margin: None,
            name: None,
        };
        let mut xml = String::new();
        write_parts(&mut xml, "drawer", &[bar], [1.0; 4], "");
        let quat = xml.split(r#"quat=""#).nth(1).and_then(|q| q.split('"').next()).unwrap_or_default();
        let q: Vec<f64> = quat.split_whitespace().map(|w| w.parse().unwrap_or(f64::NAN)).collect();
        let [w, x, y, z] = q[..] else { panic!("{xml}") };
        let axis = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)) * nalgebra::Vector3::z();
        assert!((axis.x.abs() - 1.0).abs() < 1e-9, "the capsule's axis {axis:?}, want along x");
    }

    #[test]
    fn a_convex_box_collides_as_a_mesh_of_its_corners_and_is_drawn_as_a_box() {
        let wall = Part {
            kind: CONVEX_BOX.to_owned(),
            size: vec![0.002, 0.01, 0.03],
            pos: [0.0, 0.02, 0.03],
            yaw_deg: 0.0,
            roll_deg: 0.0,
            rgba: None,
            density: None,
            visual: false,
            friction: None,
            solref: None,
            margin: Some(0.001),
            name: Some("wall".to_owned()),
        };
        let (mut assets, mut body) = (String::new(), String::new());
        write_hulls(&mut assets, "mug", std::slice::from_ref(&wall));
        write_parts(&mut body, "mug", &[wall], [1.0; 4], "");
        let vertex = assets.split(r#"vertex=""#).nth(1).and_then(|v| v.split('"').next()).unwrap_or_default();
        let corners: Vec<f64> = vertex.split_whitespace().map(|w| w.parse().unwrap_or(f64::NAN)).collect();
        assert!(assets.contains(r#"<mesh name="mug_wall_g0_hull""#) && corners.len() == 24, "{assets}");
        for corner in corners.chunks(3) {
            assert_eq!(corner.iter().map(|v| v.abs()).collect::<Vec<_>>(), [0.002, 0.01, 0.03], "{corner:?}");
        }
        let distinct: std::collections::BTreeSet<String> = corners.chunks(3).map(|c| format!("{c:?}")).collect();
        assert_eq!(distinct.len(), 8, "{assets}");
        let mut lines = body.lines();
        let collision = lines.next().unwrap_or_default();
        assert!(collision.contains(r#"type="mesh" mesh="mug_wall_g0_hull""#) && !collision.contains("size="), "{collision}");
        assert!(collision.contains(r#" margin="0.001""#), "{collision}");
        let visual = lines.next().unwrap_or_default();
        assert!(visual.contains(r#"type="box" size="0.002 0.01 0.03""#), "{visual}");
    }

    fn mug(base_m: [f64; 3], handle_yaw_deg: f64) -> ObjectModel {
        ObjectModel::Mug {
            name: "object".to_owned(),
            radius_m: 0.0283,
            height_m: 0.0644,
            wall_m: 0.004,
            handle_m: [0.025, 0.012, 0.056],
            base_m,
            handle_yaw_deg,
            rgba: [1.0; 4],
            density: 100.0,
            friction: None,
            solref: None,
            margin: None,
        }
    }

    #[test]
    fn a_mug_is_built_in_the_frame_its_base_and_handle_name() {
        let plain = mug([0.0; 3], 0.0);
        let shapenet = mug([0.0, -0.0181, -0.0309], 90.0);
        assert_eq!((plain.origin_above_bottom_m(), shapenet.origin_above_bottom_m()), (0.0, 0.0309));
        let (a, b) = (plain.mug_parts(), shapenet.mug_parts());
        assert_eq!(a.len(), b.len());
        for (a, b) in a.iter().zip(&b) {
            // Each part turned a quarter about z, then moved by the base.
            let want = [-a.pos[1], a.pos[0] - 0.0181, a.pos[2] - 0.0309];
            let err = b.pos.iter().zip(want).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
            assert!(err < 1e-12, "{:?} -> {:?}, want {want:?}", a.pos, b.pos);
            assert!((b.yaw_deg - a.yaw_deg - 90.0).abs() < 1e-12 && a.size == b.size);
        }
        // The handle's bar, the last part, reaches out along +y, past the cup.
        let bar = b.last().map(|p| p.pos).unwrap_or_default();
        assert!(bar[0].abs() < 1e-9 && bar[1] > -0.0181 + 0.0283, "{bar:?}");
        // The bottom disc's underside is the mug's bottom, 0.0309 below the frame.
        let disc = &b[0];
        assert!((disc.pos[2] - disc.size[1] + 0.0309).abs() < 1e-12);
    }
}
