//! A small run logged to a `.rrd` file, read back with the Rerun viewer's CLI (`rerun rrd print`
//! and `rerun rrd stats`), the way a user's viewer will read it.

use std::path::Path;
use std::process::Command;
use std::sync::Arc;

use mimicgen_engine::spec::SourceSelection;
use mimicgen_engine::{Generator, TaskSpec};
use mimicgen_sim::{Scene, SimEnv, registry};
use mimicgen_viz::{LogConfig, RunLogger, SceneLevel, Sink, viewer_path};

fn rerun_cli(args: &[&str]) -> String {
    let bin = viewer_path();
    assert!(bin.is_file(), "no Rerun viewer at {} (run scripts/setup.sh or set MIMICGEN_RERUN)", bin.display());
    let _ = Command::new(&bin).args(["analytics", "disable"]).output();
    let out = Command::new(&bin).args(args).output().expect("run rerun");
    assert!(out.status.success(), "rerun {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr)
}

#[test]
fn three_attempts_read_back_with_the_viewer_cli() {
    let task = registry::task("stack", "D0").expect("task");
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/sim/data/stack_D0_source.hdf5");
    let mut spec = TaskSpec::from_toml_str(registry::default_spec_toml("stack").expect("spec"), "stack").expect("parse spec");
    spec.generation.num_trials = 3;
    // The place is reached by a planned transit: drawn in a colour of its own.
    spec.subtasks[1].transit = mimicgen_engine::spec::Transit::Plan;
    let mut sources = mimicgen_io::read_source_dataset(&source, &SourceSelection::default()).expect("sources");
    sources.demos.truncate(2);
    let xml = sources.demos[0].sim.model_xml.clone().expect("model_file");
    let scene = Arc::new(Scene::from_model_file(&xml, "stack_D0_source.hdf5", task.as_ref()).expect("scene"));
    let generator = Generator::new(spec, sources).expect("generator");
    let dir = tempfile::tempdir().expect("tempdir");
    let rrd = dir.path().join("run.rrd");
    let rec = Sink::Save(rrd.clone()).open("mimicgen").expect("open recording");
    let config = LogConfig { scene: SceneLevel::All, scene_stride: 2 };
    let mut logger = RunLogger::new(rec, &scene, config).expect("logger");
    let num_geoms = mimicgen_viz::SceneLogger::new(&scene, "world/scene").len();
    assert!(num_geoms > 20, "only {num_geoms} visible geoms: robot, gripper, table and cubes expected");
    logger.log_demos(generator.dataset().demos.iter().enumerate()).expect("log sources");
    let mut envs = vec![SimEnv::new(Arc::clone(&scene), Arc::clone(&task))];
    let mut logged = 0;
    let stats = mimicgen_engine::run(&generator, &mut envs, |attempt, stats| {
        logger.log_attempt(&attempt, stats).expect("log attempt");
        logged += 1;
        std::ops::ControlFlow::Continue(())
    })
    .expect("run");
    assert_eq!((stats.attempts, logged), (3, 3));
    logger.finish().expect("flush");

    let print = rerun_cli(&["rrd", "print", "-vv", rrd.to_str().expect("utf-8 path")]);
    for entity in [
        "/world/scene/",
        "/world/demo/eef_path/subtask_0",
        "/world/demo/subtask_ends",
        "/world/demo/object_frames_at_ends",
        "/plots/signals/grasp",
        "/plots/gripper",
        "/world/attempt/objects",
        "/world/attempt/subtask_0/source_segment",
        "/world/attempt/subtask_0/transformed_segment",
        "/world/attempt/subtask_0/interpolation_segment",
        "/world/attempt/subtask_1/transit_segment",
        "/world/attempt/subtask_1/object_frames",
        "/world/attempt/executed_path",
        "/world/attempt/eef",
        "/world/history/attempt_00002",
        "/outcome",
        "/stats/attempts",
        "/stats/successes",
        "/stats/generation_rate",
        "/stats/per_source_demo/demo_0/attempts",
    ] {
        assert!(print.contains(entity), "entity {entity} missing from `rerun rrd print`:\n{}", &print[..print.len().min(4000)]);
    }
    for timeline in ["attempt", "step", "frame", "demo", "log_time"] {
        assert!(print.contains(&format!("index_name: {timeline}")), "timeline {timeline} missing from `rerun rrd print -vv`");
    }
    assert!(print.contains("Mesh3D"), "no Mesh3D (robot links) in the recording");
    let stats_out = rerun_cli(&["rrd", "stats", rrd.to_str().expect("utf-8 path")]);
    assert!(stats_out.contains("num_entity_paths"), "unexpected `rerun rrd stats` output:\n{stats_out}");
    // Rows per entity, summed over chunks (the SDK batches log calls into chunks as it likes).
    let summary = rerun_cli(&["rrd", "print", "-v", rrd.to_str().expect("utf-8 path")]);
    let rows = |entity: &str| -> usize {
        summary
            .lines()
            .filter(|l| l.contains(&format!(" - {entity} - ")))
            .filter_map(|l| l.split(" with ").nth(1)?.split(' ').next()?.parse::<usize>().ok())
            .sum()
    };
    assert_eq!(rows("/outcome"), 3, "one outcome per attempt:\n{summary}");
    assert_eq!(rows("/stats/generation_rate"), 3, "statistics after every attempt");
    assert_eq!(rows("/world/attempt/objects"), 3, "object frames per attempt");
    assert!(print.matches("/world/history/attempt_").count() >= 3, "every attempt's path is kept");
}

#[test]
fn pegs_are_drawn_where_each_episode_had_them() {
    use mimicgen_engine::Environment as _;
    use rand::SeedableRng as _;
    let task = registry::task("square", "D2").expect("task");
    let scene = Arc::new(Scene::for_task(task.as_ref()).expect("scene"));
    let mut env = SimEnv::new(Arc::clone(&scene), Arc::clone(&task));
    env.reset(&mut rand_chacha::ChaCha8Rng::seed_from_u64(7)).expect("reset");
    let peg = env.physics().object_pose(1);
    let state = env.state();
    let mut logger = mimicgen_viz::SceneLogger::new(&scene, "world/scene");
    let peg_geom = |positions: Vec<(String, [f64; 3])>| {
        positions.into_iter().find(|(path, _)| path.ends_with("peg1_vis")).map(|(_, p)| p).expect("peg drawn")
    };
    // Without being told, the logger draws the peg where the scene file has it ...
    let default = peg_geom(logger.geom_positions(&state).expect("pose"));
    assert!((default[0] - 0.23).abs() < 1e-9 && (default[1] - 0.1).abs() < 1e-9, "{default:?}");
    // ... and where the episode's object poses have it once it knows the peg is placed per episode.
    logger.place_fixed_objects(&std::collections::BTreeMap::from([("square_peg".to_owned(), peg)]));
    let placed = peg_geom(logger.geom_positions(&state).expect("pose"));
    let t = peg.translation.vector;
    assert!((placed[0] - t.x).abs() < 1e-9 && (placed[1] - t.y).abs() < 1e-9, "{placed:?} vs {t:?}");
    assert!((t.x - 0.23).abs() + (t.y - 0.1).abs() > 1e-3, "seed 7 should move the peg");
}

#[test]
fn camera_images_go_on_the_demo_timeline() {
    use mimicgen_engine::image::{ImageStream, Pixels};
    let task = registry::task("stack", "D0").expect("task");
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/sim/data/stack_D0_source.hdf5");
    let mut sources = mimicgen_io::read_source_dataset(&source, &SourceSelection::default()).expect("sources");
    sources.demos.truncate(1);
    let demo = &sources.demos[0];
    let scene =
        Scene::from_model_file(demo.sim.model_xml.as_deref().expect("model_file"), "stack_D0_source.hdf5", task.as_ref()).expect("scene");
    let dir = tempfile::tempdir().expect("tempdir");
    let rrd = dir.path().join("cams.rrd");
    let rec = Sink::Save(rrd.clone()).open("mimicgen").expect("open recording");
    let mut logger = RunLogger::new(rec, &scene, LogConfig { scene: SceneLevel::None, scene_stride: 1 }).expect("logger");
    logger.log_demos([(0, demo)]).expect("log demo");
    let n = demo.len();
    let stream = |v: u8| ImageStream { shape: [4, 6, 3], pixels: Pixels::Rgb(vec![v; n * 4 * 6 * 3]) };
    let images = std::collections::BTreeMap::from([
        ("agentview_image".to_owned(), stream(10)),
        ("robot0_eye_in_hand_image".to_owned(), stream(200)),
        ("agentview_depth".to_owned(), ImageStream { shape: [4, 6, 1], pixels: Pixels::Depth(vec![0.5; n * 24]) }),
    ]);
    let cameras = logger.log_demo_images(0, &images).expect("log images");
    assert_eq!(cameras, ["agentview", "robot0_eye_in_hand"]);
    mimicgen_viz::send_blueprint(logger.stream(), mimicgen_viz::blueprint_with_cameras(&cameras)).expect("blueprint");
    logger.finish().expect("finish");
    // One image per step and camera: the rows of each camera's chunks add up to the demo's steps.
    let print = rerun_cli(&["rrd", "print", "--verbose", rrd.to_str().expect("utf-8 path")]);
    for camera in ["agentview", "robot0_eye_in_hand"] {
        let rows: usize = print
            .lines()
            .filter(|l| l.contains(&format!("- /cameras/{camera} - data columns")) && l.contains("Image:buffer"))
            .filter_map(|l| l.split(" with ").nth(1)?.split(' ').next()?.parse::<usize>().ok())
            .sum();
        assert_eq!(rows, n, "{camera}: {rows} images for {n} steps");
    }
}

/// A two-arm run in Rerun: each arm's segments, path and hand under `world/attempt/<arm>`, its
/// gripper, subtask and holding plots, and the ties: coordinated pairs as bands and lines between
/// the hands, the sequential release as an arrow and a text line.
#[test]
fn two_arm_attempts_show_each_arm_and_the_ties() {
    use mimicgen_engine::demo::SourceDataset;
    use mimicgen_engine::demonstrator::Style;
    use mimicgen_engine::two_arm::{TwoArmEnvironment as _, TwoArmGenerator, TwoArmHandoverScript};
    use mimicgen_sim::two_arm::{TwoArmSimEnv, TwoArmTask};
    use rand::SeedableRng as _;

    let task = TwoArmTask::Handover;
    let scene = Arc::new(task.scene().expect("scene"));
    let mut env = TwoArmSimEnv::new(Arc::clone(&scene), task, "D0").expect("env");
    let spec = task.spec().expect("spec");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut views: Vec<Vec<_>> = vec![Vec::new(), Vec::new()];
    while views[0].len() < 2 {
        env.reset(&mut rng).expect("reset");
        let demo = TwoArmHandoverScript::hammer().record(&mut env, Style::Careful, &mut rng).expect("record");
        let arm_views = demo.arm_views(&format!("demo_{}", views[0].len()));
        let one = arm_views.iter().map(|d| SourceDataset { demos: vec![d.clone()], env_args: None }).collect();
        if demo.success && TwoArmGenerator::new(spec.clone(), one).is_ok() {
            for (arm, view) in arm_views.into_iter().enumerate() {
                views[arm].push(view);
            }
        }
    }
    let generator = TwoArmGenerator::new(spec.clone(), views.into_iter().map(|demos| SourceDataset { demos, env_args: None }).collect())
        .expect("generator");
    let dir = tempfile::tempdir().expect("tempdir");
    let rrd = dir.path().join("two_arm.rrd");
    let rec = Sink::Save(rrd.clone()).open("mimicgen").expect("open recording");
    let mut logger = RunLogger::new(rec, &scene, LogConfig { scene: SceneLevel::All, scene_stride: 4 }).expect("logger");
    logger.set_source_names(vec!["demo_0".to_owned(), "demo_1".to_owned()]);
    let (mut successes, mut released) = (0, false);
    for index in 0..2 {
        let attempt = generator.attempt(&mut env, index).expect("attempt");
        successes += usize::from(attempt.success);
        released |= attempt.arms[0].plans.len() == 4;
        logger.log_two_arm_attempt(&attempt, &spec, (usize::try_from(index).expect("index") + 1, successes)).expect("log");
    }
    logger.finish().expect("flush");
    assert!(released, "no attempt got to arm 0's release: the sequential tie is not drawn");
    let print = rerun_cli(&["rrd", "print", "-vv", rrd.to_str().expect("utf-8 path")]);
    for entity in [
        "/world/scene/",
        "/world/attempt/robot0/subtask_0/transformed_segment",
        "/world/attempt/robot1/subtask_1/transformed_segment",
        "/world/attempt/robot0/executed_path",
        "/world/attempt/robot1/eef",
        "/plots/robot0/gripper",
        "/plots/robot1/holding",
        "/plots/ties/coordination_0",
        "/world/attempt/ties/coordination_1",
        "/world/attempt/ties/sequential_1_1_0_3",
        "/ties",
        "/plots/signals/handle_grasp",
        "/outcome",
        "/stats/successes",
    ] {
        assert!(print.contains(entity), "entity {entity} missing from `rerun rrd print`:\n{}", &print[..print.len().min(4000)]);
    }
}
