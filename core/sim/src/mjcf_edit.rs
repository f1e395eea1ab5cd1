//! Textual edits of MJCF: a section added, one element's attributes set by name, a body placed,
//! textures made flat and robosuite's contact limits made an arena. What scene composition,
//! the arms' models and the simulator's scene preparation all do to XML, without parsing it.

use mimicgen_engine::pose::{Pose, quat_to_wxyz};

/// `xml` with `section` added as the last element of `<mujoco>`.
#[must_use]
pub fn with_section(xml: &str, section: &str) -> String {
    match xml.rfind("</mujoco>") {
        Some(end) => format!("{}{section}{}", &xml[..end], &xml[end..]),
        None => xml.to_owned(),
    }
}

/// Numbers as MJCF writes a vector: `0.1 0 -2`.
pub(crate) fn words(v: &[f64]) -> String {
    v.iter().map(f64::to_string).collect::<Vec<_>>().join(" ")
}

/// A start tag's attributes, `(key, value)` in order.
type Attrs = Vec<(String, String)>;

/// One start tag's attributes, parsed from `<tag a="1" b="2">`.
fn parse_attrs(tag: &str) -> Option<Attrs> {
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

/// The start tag of the `element` named `name`: where it starts and ends in `xml`, and its
/// attributes.
fn find_element(xml: &str, element: &str, name: &str) -> Option<(usize, usize, Attrs)> {
    let open = format!("<{element}");
    let mut from = 0;
    while let Some(i) = xml[from..].find(&open).map(|i| i + from) {
        let end = xml[i..].find('>').map(|e| i + e + 1)?;
        let tag = &xml[i..end];
        let attrs = parse_attrs(tag)?;
        if tag[open.len()..].starts_with(char::is_whitespace) && attrs.iter().any(|(k, v)| k == "name" && v == name) {
            return Some((i, end, attrs));
        }
        from = end;
    }
    None
}

/// `xml` with the start tag of the `element` named `name` (`body`, `joint`, ...) given `set`
/// attributes (replacing any of the same key) and without the `remove` ones. `None` if the XML
/// has no such element.
#[must_use]
pub fn edit_element(xml: &str, element: &str, name: &str, set: &[(&str, String)], remove: &[&str]) -> Option<String> {
    let (start, end, attrs) = find_element(xml, element, name)?;
    let mut kept: Vec<(String, String)> =
        attrs.into_iter().filter(|(k, _)| !remove.contains(&k.as_str()) && !set.iter().any(|(s, _)| s == k)).collect();
    kept.extend(set.iter().map(|(k, v)| ((*k).to_owned(), v.clone())));
    let attrs: String = kept.iter().map(|(k, v)| format!(" {k}=\"{v}\"")).collect();
    let close = if xml[start..end].ends_with("/>") { "/>" } else { ">" };
    Some(format!("{}<{element}{attrs}{close}{}", &xml[..start], &xml[end..]))
}

/// `xml` with body `name` at `world_from_body` (position and `wxyz` quaternion; a body in the
/// world frame, as robosuite's pegs are). `None` if the XML has no such body.
#[must_use]
pub fn place_body(xml: &str, name: &str, world_from_body: &Pose) -> Option<String> {
    let t = world_from_body.translation.vector;
    let [w, x, y, z] = quat_to_wxyz(&world_from_body.rotation);
    edit_body(
        xml,
        name,
        &[("pos", format!("{} {} {}", t.x, t.y, t.z)), ("quat", format!("{w} {x} {y} {z}"))],
        &["euler", "axisangle", "xyaxes", "zaxis"],
    )
}

/// `xml` with body `name` moved by `dx_dy` (m) in its parent's x and y. `None` if the XML has no
/// such body or its `pos` is not three numbers.
#[must_use]
pub fn shift_body(xml: &str, name: &str, [dx, dy]: [f64; 2]) -> Option<String> {
    let (_, _, attrs) = find_element(xml, "body", name)?;
    let pos = attrs.iter().find(|(k, _)| k == "pos").map_or("0 0 0", |(_, v)| v.as_str());
    let p: Vec<f64> = pos.split_whitespace().map(str::parse).collect::<Result<_, _>>().ok()?;
    let [x, y, z] = p[..] else { return None };
    edit_body(xml, name, &[("pos", words(&[x + dx, y + dy, z]))], &[])
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
    use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};

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
}
