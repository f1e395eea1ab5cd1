//! Camera observations: robosuite's cameras render offscreen (EGL), upright, follow the state, and
//! bad requests name what is wrong.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::collections::BTreeMap;
use std::sync::Arc;

use mimicgen_engine::Environment as _;
use mimicgen_sim::camera::{CameraConfig, Cameras, ImageStream, Pixels};
use mimicgen_sim::{Scene, SimEnv, registry};
use rand::SeedableRng as _;

fn stack_env() -> (Arc<Scene>, SimEnv) {
    let task = registry::task("stack", "D0").unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    let mut env = SimEnv::new(Arc::clone(&scene), task);
    env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(5)).unwrap();
    (scene, env)
}

fn capture(cameras: &Cameras, env: &SimEnv) -> BTreeMap<String, ImageStream> {
    let mut streams = cameras.streams(1);
    cameras.capture(env.physics().data(), &mut streams).unwrap();
    streams
}

fn rgb(streams: &BTreeMap<String, ImageStream>, key: &str) -> Vec<u8> {
    streams[key].rgb_frame(0).unwrap().to_vec()
}

/// Mean brightness of rows `rows` of an `h x w` RGB image.
fn mean_rows(pixels: &[u8], w: usize, rows: std::ops::Range<usize>) -> f64 {
    let band = &pixels[rows.start * w * 3..rows.end * w * 3];
    band.iter().map(|&v| f64::from(v)).sum::<f64>() / band.len() as f64
}

#[test]
fn robosuite_cameras_render_upright_and_follow_the_state() {
    let (scene, mut env) = stack_env();
    let config = CameraConfig { height: 48, width: 64, depth: true, ..CameraConfig::default() };
    let cameras = Cameras::new(&scene, config).unwrap();
    assert_eq!(cameras.keys(), ["agentview_image", "agentview_depth", "robot0_eye_in_hand_image", "robot0_eye_in_hand_depth"]);
    let first = capture(&cameras, &env);
    assert_eq!(first["agentview_image"].shape, [48, 64, 3]);
    assert_eq!(first["agentview_depth"].shape, [48, 64, 1]);
    assert!(first.values().all(|s| s.steps() == 1));
    // Upright, as robomimic stores robosuite's frames: the white table fills agentview's bottom,
    // the wall and the robot its top.
    let agentview = rgb(&first, "agentview_image");
    let (top, bottom) = (mean_rows(&agentview, 64, 0..8), mean_rows(&agentview, 64, 40..48));
    assert!(bottom > top + 40.0, "bottom rows {bottom:.0}, top rows {top:.0}: is the image upside down?");
    // Depth is robosuite's normalized buffer: in (0, 1), the table's front nearer than the wall.
    let Pixels::Depth(depth) = &first["agentview_depth"].pixels else { panic!("depth is not float") };
    assert!(depth.iter().all(|&d| d > 0.0 && d < 1.0));
    assert!(depth[47 * 64 + 32] < depth[32]);
    // The same state renders the same pixels; another state others.
    assert_eq!(capture(&cameras, &env), first);
    for _ in 0..10 {
        env.step(&[0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
    }
    let moved = capture(&cameras, &env);
    let changed = |key: &str| rgb(&first, key).iter().zip(rgb(&moved, key)).filter(|(a, b)| a.abs_diff(*b) > 16).count();
    assert!(changed("robot0_eye_in_hand_image") > 48 * 64 / 10, "the wrist camera did not move with the arm");
    assert!(changed("agentview_image") > 0);
}

#[test]
fn bad_camera_requests_name_what_is_wrong() {
    let (scene, _) = stack_env();
    let named = |names: &[&str]| CameraConfig { names: names.iter().map(|&n| n.to_owned()).collect(), ..CameraConfig::default() };
    let err = Cameras::new(&scene, named(&["agentview", "topview"])).unwrap_err().to_string();
    assert!(err.contains("\"topview\"") && err.contains("agentview") && err.contains("frontview"), "{err}");
    let err = Cameras::new(&scene, named(&[])).unwrap_err().to_string();
    assert!(err.contains("no camera named"), "{err}");
    let err = Cameras::new(&scene, CameraConfig { height: 5000, ..CameraConfig::default() }).unwrap_err().to_string();
    assert!(err.contains("5000x84") && err.contains("4096x4096"), "{err}");
    assert!(Cameras::new(&scene, CameraConfig { height: 0, ..CameraConfig::default() }).is_err());
}

/// Every state of a stretch of arm motion, drawn the three ways `RenderOptions` allows: MuJoCo's
/// own (a camera per render and read-back, every geom), the cameras side by side in one buffer, and
/// that with the geoms a camera cannot see left out; and the default, without the floor's reflection.
#[test]
fn drawing_side_by_side_and_culled_keeps_the_pixels() {
    use mimicgen_sim::camera::RenderOptions;
    let (scene, mut env) = stack_env();
    let config =
        CameraConfig { names: vec!["agentview".into(), "robot0_eye_in_hand".into(), "frontview".into()], ..CameraConfig::default() };
    let way = |tile: bool, cull: bool| {
        Cameras::new(&scene, config.clone()).unwrap().with_render_options(RenderOptions { tile, cull, reflection: true })
    };
    let (mujoco, tiled, culled) = (way(false, false), way(true, false), way(true, true));
    // The default: no floor reflection (a deliberate difference from robosuite, BENCHMARKS.md).
    let default = Cameras::new(&scene, config.clone()).unwrap();
    let mut frames: [BTreeMap<String, Vec<u8>>; 4] = Default::default();
    for step in 0..24 {
        // Down, sideways and turning: the wrist camera sweeps the table, the arm crosses frames.
        let a = (f64::from(step) * 0.4).sin();
        env.step(&[0.3 * a, -0.6, -0.5, 0.0, 0.0, 0.4 * a, if step < 12 { -1.0 } else { 1.0 }]).unwrap();
        for (rig, out) in [&mujoco, &tiled, &culled, &default].into_iter().zip(frames.iter_mut()) {
            let streams = capture(rig, &env);
            for key in rig.keys() {
                out.entry(key.clone()).or_default().extend(rgb(&streams, &key));
            }
        }
    }
    let all = |i: usize| -> Vec<u8> { frames[i].values().flatten().copied().collect() };
    // Leaving out what a camera cannot see changes nothing, to the bit.
    assert!(frames[1] == frames[2], "culling changed {} values", all(1).iter().zip(&all(2)).filter(|(a, b)| a != b).count());
    // Side by side, a few edge samples round differently (the buffer is wider): at most a few
    // levels, on a few values in ten thousand.
    let (mujoco_all, tiled_all) = (all(0), all(1));
    let differ: Vec<u8> = mujoco_all.iter().zip(&tiled_all).map(|(a, b)| a.abs_diff(*b)).filter(|&d| d > 0).collect();
    let max = differ.iter().copied().max().unwrap_or(0);
    assert!(max <= 8 && differ.len() * 1000 < mujoco_all.len(), "{} of {} values differ, by up to {max}", differ.len(), mujoco_all.len());
    // Without the floor's 1 % reflection only the floor differs: by a few levels in robomimic's
    // two cameras (frontview, low over the floor, sees more of it and differs more).
    for key in ["agentview_image", "robot0_eye_in_hand_image"] {
        let (with, without) = (&frames[0][key], &frames[3][key]);
        let mse = with.iter().zip(without).map(|(a, b)| (f64::from(*a) - f64::from(*b)).powi(2)).sum::<f64>() / with.len() as f64;
        let max = with.iter().zip(without).map(|(a, b)| a.abs_diff(*b)).max().unwrap_or(0);
        let psnr = 10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10();
        assert!(psnr > 40.0 && max <= 24, "{key} without the reflection: {psnr:.1} dB, up to {max} levels");
    }
    assert!(frames[0]["frontview_image"] != frames[3]["frontview_image"], "the default drew the reflection");
}
