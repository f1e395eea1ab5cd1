//! Composing task scenes: our base MJCF (table arena, Panda, gripper, mount; see
//! `viewer_assets/scenes/`) plus the task's objects, written as robosuite writes them.

use std::fmt::Write as _;
use std::path::Path;

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
    /// A mug from primitive geoms, its frame at the centre of its base: a bottom disc, a wall of
    /// 16 boxes and a handle of two arms and a bar along +x. Written as a free
    /// [`ObjectModel::Compound`] (geoms `<name>_g<i>`); varied, it is the paper's set of mugs
    /// for object transfer.
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
        /// Colour.
        rgba: [f64; 4],
        /// Density (kg/m^3).
        density: f64,
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
    /// Its geoms, relative to the hinge, as they sit when closed.
    pub geoms: Vec<Part>,
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
    /// MuJoCo geom type: `box`, `cylinder`, `capsule` or `sphere`.
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
    /// Turn about the x axis (deg), applied before the yaw: 90 lays a cylinder along y.
    #[serde(default)]
    pub roll_deg: f64,
    /// Colour; the object's when absent.
    #[serde(default)]
    pub rgba: Option<[f64; 4]>,
    /// Density (kg/m^3); MuJoCo's default (water) when absent.
    #[serde(default)]
    pub density: Option<f64>,
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
        let Self::Mug { radius_m: r, height_m: h, wall_m: w, handle_m: [reach, low, high], density, .. } = *self else {
            return Vec::new();
        };
        let part = |size: Vec<f64>, pos: [f64; 3], yaw_deg: f64, kind: &str| Part {
            kind: kind.to_owned(),
            size,
            pos,
            yaw_deg,
            roll_deg: 0.0,
            rgba: None,
            density: Some(density),
        };
        let middle = r - w / 2.0;
        let step = std::f64::consts::TAU / f64::from(WALL_BOXES);
        // Each box a little wider than its share of the circle, so the wall has no gaps.
        let half_width = middle * (step / 2.0).tan() * 1.06;
        let mut parts = vec![part(vec![middle, BOTTOM_M / 2.0], [0.0, 0.0, BOTTOM_M / 2.0], 0.0, "cylinder")];
        for k in 0..WALL_BOXES {
            let angle = step * f64::from(k);
            let pos = [middle * angle.cos(), middle * angle.sin(), (h + BOTTOM_M / 2.0) / 2.0];
            parts.push(part(vec![w / 2.0, half_width, (h - BOTTOM_M / 2.0) / 2.0], pos, angle.to_degrees(), "box"));
        }
        let (arm, bar) = ([reach / 2.0, 0.005, 0.004], 0.004);
        for z in [high, low] {
            parts.push(part(arm.to_vec(), [r + reach / 2.0, 0.0, z], 0.0, "box"));
        }
        parts.push(part(vec![bar, 0.005, (high - low) / 2.0 + bar], [r + reach - bar, 0.0, (high + low) / 2.0], 0.0, "box"));
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
            Self::Compound { .. } | Self::Mug { .. } => {}
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
    write_parts(out, &format!("{name}_g"), geoms, rgba, "      ");
    if let Some(h) = hinge {
        let (pos, axis) = (words(&h.pos), words(&h.axis));
        let open = h.open_deg.to_radians();
        let range = match h.range_deg {
            Some([low, high]) => format!("{} {}", low.to_radians(), high.to_radians()),
            None if open < 0.0 => format!("0 {}", -open),
            None => format!("{} 0", -open),
        };
        let _ = writeln!(out, r#"      <body name="{name}_lid" pos="{pos}" axisangle="{axis} {open}">"#);
        let _ = writeln!(out, r#"        <joint name="{name}_hinge" type="hinge" axis="{axis}" range="{range}" damping="0.01"/>"#);
        write_parts(out, &format!("{name}_lid_g"), &h.geoms, rgba, "        ");
        let _ = writeln!(out, "      </body>");
    }
    if let Some(s) = slide {
        let (axis, travel, damping) = (words(&s.axis), s.travel_m, s.damping);
        let _ = writeln!(out, r#"      <body name="{name}_drawer" pos="0 0 0">"#);
        let _ = writeln!(
            out,
            r#"        <joint name="{name}_slide" type="slide" axis="{axis}" range="0 {travel}" limited="true" damping="{damping}" armature="0.1"/>"#
        );
        write_parts(out, &format!("{name}_drawer_g"), &s.geoms, rgba, "        ");
        let _ = writeln!(out, "      </body>");
    }
    let _ = writeln!(out, r#"      <site name="{name}_default_site" pos="0 0 0" size="0.002" rgba="1 0 0 -1"/>"#);
    let _ = writeln!(out, "    </body>");
}

/// Numbers as MJCF writes a vector: `0.1 0 -2`.
/// `xml` with `section` added as the last element of `<mujoco>`.
#[must_use]
pub fn with_section(xml: &str, section: &str) -> String {
    match xml.rfind("</mujoco>") {
        Some(end) => format!("{}{section}{}", &xml[..end], &xml[end..]),
        None => xml.to_owned(),
    }
}

pub(crate) fn words(v: &[f64]) -> String {
    v.iter().map(f64::to_string).collect::<Vec<_>>().join(" ")
}

/// Collision geoms `<prefix><i>` and their visual copies.
fn write_parts(out: &mut String, prefix: &str, geoms: &[Part], rgba: [f64; 4], indent: &str) {
    for (i, part) in geoms.iter().enumerate() {
        let [r, g, b, a] = part.rgba.unwrap_or(rgba);
        let turn = if part.yaw_deg == 0.0 && part.roll_deg == 0.0 {
            String::new()
        } else {
            format!(r#" euler="{} 0 {}""#, part.roll_deg.to_radians(), part.yaw_deg.to_radians())
        };
        let (kind, size, pos) = (&part.kind, words(&part.size), words(&part.pos));
        let density = part.density.map_or_else(String::new, |d| format!(r#" density="{d}""#));
        let _ = writeln!(
            out,
            r#"{indent}<geom name="{prefix}{i}" type="{kind}" size="{size}" pos="{pos}"{turn}{density} friction="0.95 0.3 0.1" condim="4" solimp="0.998 0.998 0.001" solref="0.02 1" group="0" rgba="{r} {g} {b} {a}"/>"#
        );
        let _ = writeln!(
            out,
            r#"{indent}<geom name="{prefix}{i}_vis" type="{kind}" size="{size}" pos="{pos}"{turn} contype="0" conaffinity="0" group="1" mass="0" rgba="{r} {g} {b} {a}"/>"#
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
    compose_scene_with(&crate::robot::PANDA, assets_dir, objects, table_top_z)
}

/// [`compose_scene`] with another arm's base scene.
#[must_use]
pub fn compose_scene_with(robot: &crate::robot::RobotModel, assets_dir: &Path, objects: &[ObjectModel], table_top_z: f64) -> String {
    let (mut assets, mut bodies) = (String::new(), String::new());
    for object in objects {
        object.write_assets(&mut assets);
        object.write_body(&mut bodies);
    }
    with_table_top(robot.base_xml, table_top_z)
        .replace("    <!-- OBJECT ASSETS -->\n", &assets)
        .replace("    <!-- OBJECT BODIES -->\n", &bodies)
        .replace("{ASSETS}", assets_dir.display().to_string().trim_end_matches('/'))
}

/// One start tag's attributes, parsed from `<tag a="1" b="2">`.
fn parse_attrs(tag: &str) -> Option<Vec<(String, String)>> {
    let mut attrs = Vec::new();
    let mut rest = tag.trim_start_matches('<').split_once(char::is_whitespace).map_or("", |(_, r)| r);
    loop {
        rest = rest.trim_start();
        if rest.is_empty() || rest.starts_with('>') || rest.starts_with("/>") {
            return Some(attrs);
        }
        let (key, after) = rest.split_once('=')?;
        let after = after.trim_start().strip_prefix('"')?;
        let (value, after) = after.split_once('"')?;
        attrs.push((key.trim().to_owned(), value.to_owned()));
        rest = after;
    }
}

/// `xml` with the start tag of body `name` given `set` attributes (replacing any of the same
/// key) and without the `remove` ones. `None` if the XML has no such body.
#[must_use]
pub fn edit_body(xml: &str, name: &str, set: &[(&str, String)], remove: &[&str]) -> Option<String> {
    edit_element(xml, "body", name, set, remove)
}

/// `xml` with the start tag of the `element` named `name` (`body`, `joint`, ...) given `set`
/// attributes (replacing any of the same key) and without the `remove` ones. `None` if the XML
/// has no such element.
#[must_use]
pub fn edit_element(xml: &str, element: &str, name: &str, set: &[(&str, String)], remove: &[&str]) -> Option<String> {
    let open = format!("<{element}");
    let mut from = 0;
    while let Some(i) = xml[from..].find(&open).map(|i| i + from) {
        let end = xml[i..].find('>').map(|e| i + e + 1)?;
        let tag = &xml[i..end];
        let attrs = parse_attrs(tag)?;
        if tag[open.len()..].starts_with(char::is_whitespace) && attrs.iter().any(|(k, v)| k == "name" && v == name) {
            let mut kept: Vec<(String, String)> =
                attrs.into_iter().filter(|(k, _)| !remove.contains(&k.as_str()) && !set.iter().any(|(s, _)| s == k)).collect();
            kept.extend(set.iter().map(|(k, v)| ((*k).to_owned(), v.clone())));
            let attrs: String = kept.iter().map(|(k, v)| format!(" {k}=\"{v}\"")).collect();
            let close = if tag.ends_with("/>") { "/>" } else { ">" };
            return Some(format!("{}{open}{attrs}{close}{}", &xml[..i], &xml[end..]));
        }
        from = end;
    }
    None
}

/// `xml` with body `name` at `world_from_body` (position and `wxyz` quaternion; a body in the
/// world frame, as robosuite's pegs are). `None` if the XML has no such body.
#[must_use]
pub fn place_body(xml: &str, name: &str, world_from_body: &mimicgen_engine::pose::Pose) -> Option<String> {
    let t = world_from_body.translation.vector;
    let [w, x, y, z] = mimicgen_engine::pose::quat_to_wxyz(&world_from_body.rotation);
    edit_body(
        xml,
        name,
        &[("pos", format!("{} {} {}", t.x, t.y, t.z)), ("quat", format!("{w} {x} {y} {z}"))],
        &["euler", "axisangle", "xyaxes", "zaxis"],
    )
}

/// `xml` with every texture made a tiny flat one: physics never reads textures, and robosuite's
/// image textures (a 1450 px wood image on six cube faces, a 1181 px ceramic one, and others)
/// decode to tens of MB that a simulator would hold for nothing. Materials keep their names.
#[must_use]
pub fn without_image_textures(xml: &str) -> String {
    let mut out = String::with_capacity(xml.len());
    let mut rest = xml;
    while let Some(start) = rest.find("<texture") {
        out.push_str(&rest[..start]);
        let tag_len = rest[start..].find('>').map_or(rest.len() - start, |e| e + 1);
        let tag = &rest[start..start + tag_len];
        let mut kept = String::from("<texture");
        for (name, value) in attributes(tag) {
            if !matches!(
                name,
                "file"
                    | "fileright"
                    | "fileleft"
                    | "fileup"
                    | "filedown"
                    | "filefront"
                    | "fileback"
                    | "builtin"
                    | "width"
                    | "height"
                    | "gridsize"
                    | "gridlayout"
                    | "rgb1"
                    | "rgb2"
                    | "mark"
                    | "markrgb"
                    | "random"
            ) {
                kept.push_str(&format!(" {name}=\"{value}\""));
            }
        }
        kept.push_str(r#" builtin="flat" width="8" height="8" rgb1="0.5 0.5 0.5" rgb2="0.5 0.5 0.5""#);
        kept.push_str(if tag.ends_with("/>") { "/>" } else { ">" });
        out.push_str(&kept);
        rest = &rest[start + tag_len..];
    }
    out.push_str(rest);
    out
}

/// `xml` with robosuite's `<size njmax=".." nconmax=".."/>` replaced by an arena of
/// `memory` (MuJoCo's syntax, `"32M"`): MuJoCo 3 turns njmax/nconmax 5000 into a 1.3 GB arena per
/// `MjData`, of which resetting touches hundreds of MB. Our scenes make a few dozen contacts; the
/// arena's size does not change the physics, only where MuJoCo would run out of room.
#[must_use]
pub fn with_arena(xml: &str, memory: &str) -> String {
    let Some(start) = xml.find("<size") else { return xml.to_owned() };
    let Some(len) = xml[start..].find('>') else { return xml.to_owned() };
    let tag = &xml[start..=start + len];
    let mut kept = String::from("<size");
    for (name, value) in attributes(tag) {
        if !matches!(name, "njmax" | "nconmax" | "memory" | "nstack") {
            kept.push_str(&format!(" {name}=\"{value}\""));
        }
    }
    kept.push_str(&format!(" memory=\"{memory}\""));
    kept.push_str(if tag.ends_with("/>") { "/>" } else { ">" });
    format!("{}{kept}{}", &xml[..start], &xml[start + len + 1..])
}

/// The `name="value"` pairs of one XML tag, in order.
fn attributes(tag: &str) -> Vec<(&str, &str)> {
    let mut out = Vec::new();
    let mut rest = tag;
    while let Some(eq) = rest.find("=\"") {
        let name = rest[..eq].rsplit(|c: char| c.is_whitespace()).next().unwrap_or("");
        let after = &rest[eq + 2..];
        let Some(end) = after.find('"') else { break };
        out.push((name, &after[..end]));
        rest = &after[end + 1..];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_textures_become_tiny_flat_ones() {
        let xml = r#"<asset><texture type="cube" name="tex" file="/a/red-wood.png"/><texture type="skybox" builtin="gradient" rgb1="1 1 1" width="256" height="1536"/><material name="m" texture="tex"/></asset>"#;
        let out = without_image_textures(xml);
        assert!(!out.contains("file=") && !out.contains("1536") && !out.contains("gradient"), "{out}");
        assert!(out.contains(r#"<texture type="cube" name="tex" builtin="flat" width="8" height="8""#), "{out}");
        assert!(out.contains(r#"<material name="m" texture="tex"/>"#), "{out}");
    }

    #[test]
    fn robosuite_contact_limits_become_an_arena() {
        let xml = r#"<mujoco><size njmax="5000" nconmax="5000" nkey="2"/><worldbody/></mujoco>"#;
        assert_eq!(with_arena(xml, "32M"), r#"<mujoco><size nkey="2" memory="32M"/><worldbody/></mujoco>"#);
        assert_eq!(with_arena("<mujoco/>", "32M"), "<mujoco/>");
    }
    use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};

    #[test]
    fn bodies_are_edited_by_name_only() {
        let xml =
            r#"<worldbody><body name="peg10" pos="1 1 1"/><body pos="0.23 0.1 0.85" name="peg1" euler="0 0 1"><geom/></body></worldbody>"#;
        let pose = pose_from_parts(Vec3::new(0.1, -0.2, 0.85), Rot::from_axis_angle(&Vec3::z_axis(), std::f64::consts::PI));
        let out = place_body(xml, "peg1", &pose).unwrap_or_default();
        assert!(out.contains(r#"<body name="peg10" pos="1 1 1"/>"#), "{out}");
        let start = out.find(r#"<body name="peg1""#).unwrap_or_default();
        let attrs = parse_attrs(&out[start..]).unwrap_or_default();
        assert_eq!(attrs[1], ("pos".to_owned(), "0.1 -0.2 0.85".to_owned()));
        let quat: Vec<f64> = attrs[2].1.split(' ').filter_map(|v| v.parse().ok()).collect();
        assert!(quat[0].abs() < 1e-12 && (quat[3].abs() - 1.0).abs() < 1e-12, "{quat:?}");
        assert!(out.contains("><geom/></body>"), "{out}");
        assert!(!out.contains("euler"), "{out}");
        let mocap = edit_body(&out, "peg1", &[("mocap", "true".to_owned())], &[]).unwrap_or_default();
        assert!(mocap.contains(r#" mocap="true"><geom/>"#), "{mocap}");
        assert!(edit_body(xml, "peg2", &[], &[]).is_none());
        assert!(edit_body("<body name=\"peg1\" pos=\"1 2>", "peg1", &[], &[]).is_none());
        // Another element by name: a tendon's `<joint joint=..>` and a longer tag name are skipped.
        let joints = r#"<jointx name="j"/><fixed><joint joint="j" coef="1"/></fixed><joint name="j" range="0 1"/>"#;
        let edited = edit_element(joints, "joint", "j", &[("limited", "false".to_owned())], &[]).unwrap_or_default();
        assert!(
            edited.ends_with(r#"<joint name="j" range="0 1" limited="false"/>"#) && edited.starts_with(r#"<jointx name="j"/>"#),
            "{edited}"
        );
    }

    #[test]
    fn the_table_moves_with_its_legs() {
        let xml = with_table_top(PANDA_TABLE_XML, 0.82);
        assert!(xml.contains(r#"<body name="table" pos="0 0 0.795""#));
        assert_eq!(xml.matches("0.3975").count(), 8, "four legs, each a size and a position");
        assert!(!xml.contains("0.3875"));
        assert_eq!(with_table_top(PANDA_TABLE_XML, BASE_TABLE_TOP_Z), PANDA_TABLE_XML);
    }
}
