//! Box-box contacts at MuJoCo 2.3's depth (`mimicgen_sim::legacy_contacts`): the same soft contact
//! met at twice the reported depth, so a box resting on a box sinks twice as deep as MuJoCo 3.17
//! alone lets it, and no other contact changes.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]

use mimicgen_sim::legacy_contacts::contact_section;
use mimicgen_sim::mjcf_edit::with_section;
use mimicgen_sim::scene::compile_mjcf;
use mujoco_rs::prelude::*;

/// A 4 cm cube dropped on a box table and a sphere dropped on the same table, with robosuite's
/// solver options.
const SCENE: &str = r#"<mujoco>
  <option impratio="20" cone="elliptic"/>
  <worldbody>
    <body name="table" pos="0 0 0.4"><geom name="table_top" type="box" size="0.4 0.4 0.4"/></body>
    <body name="cube" pos="0 0 0.83"><freejoint/><geom name="cube_g" type="box" size="0.02 0.02 0.02"/></body>
    <body name="ball" pos="0.2 0 0.83"><freejoint/><geom name="ball_g" type="sphere" size="0.02"/></body>
  </worldbody>
</mujoco>"#;

/// How far the cube's and the ball's bottoms sit below the table top after 1 s.
fn resting_depths(xml: &str) -> (f64, f64) {
    let model = compile_mjcf(xml).expect("the test scene compiles");
    let mut data = MjData::new(&model);
    for _ in 0..500 {
        data.step();
    }
    let qpos = data.qpos();
    (0.8 - (qpos[2] - 0.02), 0.8 - (qpos[9] - 0.02))
}

#[test]
fn a_box_on_a_box_sinks_as_deep_as_in_mujoco_2_3_and_a_sphere_as_before() {
    let model = compile_mjcf(SCENE).expect("the test scene compiles");
    let section = contact_section(&model).expect("a cube on a box table is a box-box pair");
    assert!(section.contains(r#"<exclude body1="table" body2="cube"/>"#), "{section}");
    assert!(!section.contains("ball"), "only box-box body pairs change: {section}");
    let (cube_true, ball_true) = resting_depths(SCENE);
    let (cube_legacy, ball_legacy) = resting_depths(&with_section(SCENE, &section));
    assert!(cube_true > 0.0 && cube_legacy > 0.0, "both rest in (soft) contact: {cube_true} {cube_legacy}");
    let ratio = cube_legacy / cube_true;
    assert!((ratio - 2.0).abs() < 0.2, "the cube rests {cube_legacy:.6} m deep against {cube_true:.6} m: ratio {ratio:.3}, not 2");
    assert!((ball_legacy - ball_true).abs() < 1e-9, "the sphere's contact is untouched: {ball_legacy} against {ball_true}");
}

#[test]
fn a_model_without_two_boxes_that_touch_is_left_alone() {
    let xml = r#"<mujoco><worldbody>
        <geom name="floor" type="plane" size="1 1 0.1"/>
        <body pos="0 0 0.1"><freejoint/><geom name="b" type="box" size="0.02 0.02 0.02"/></body>
        <body pos="0 0 0.3"><freejoint/><geom name="s" type="box" size="0.02 0.02 0.02" contype="0" conaffinity="0"/></body>
      </worldbody></mujoco>"#;
    let model = compile_mjcf(xml).expect("compiles");
    assert_eq!(contact_section(&model), None);
}
