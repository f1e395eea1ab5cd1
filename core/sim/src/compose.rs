//! Composing task scenes: our base MJCF (table arena, Panda, gripper, mount; see
//! `viewer_assets/scenes/`) plus the task's objects, written as robosuite writes them.

use std::fmt::Write as _;
use std::path::Path;

/// The base scene: robosuite's table arena with a Panda on its mount, asset paths as `{ASSETS}/`.
pub const PANDA_TABLE_XML: &str = include_str!("../../../viewer_assets/scenes/panda_table.xml");

/// An object model to add to a scene.
#[derive(Debug, Clone, PartialEq)]
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
}

impl ObjectModel {
    /// The body whose frame is the object's pose.
    #[must_use]
    pub fn body_name(&self) -> String {
        match self {
            Self::Box { name, .. } => format!("{name}_main"),
        }
    }

    fn write_assets(&self, out: &mut String) {
        match self {
            Self::Box { name, texture: (tex, file), .. } => {
                let _ = writeln!(out, r#"    <texture type="cube" name="{name}_{tex}" file="{{ASSETS}}/{file}"/>"#);
                let _ = writeln!(out, r#"    <material name="{name}_{tex}_mat" texture="{name}_{tex}" specular="0.4" shininess="0.1"/>"#);
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
        }
    }
}

/// The base scene with `objects` added and asset paths pointing into `assets_dir`.
#[must_use]
pub fn compose_scene(assets_dir: &Path, objects: &[ObjectModel]) -> String {
    let (mut assets, mut bodies) = (String::new(), String::new());
    for object in objects {
        object.write_assets(&mut assets);
        object.write_body(&mut bodies);
    }
    PANDA_TABLE_XML
        .replace("    <!-- OBJECT ASSETS -->\n", &assets)
        .replace("    <!-- OBJECT BODIES -->\n", &bodies)
        .replace("{ASSETS}", assets_dir.display().to_string().trim_end_matches('/'))
}
