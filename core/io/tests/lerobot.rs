//! LeRobot export: the parquet frames, episode table, task table and info LeRobot's loader reads,
//! the camera streams as videos that decode back to the dataset's images, and bad input refused
//! with the field named.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used, clippy::float_cmp)] // tests fail loudly by design; exact equality is the point

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use arrow_array::RecordBatch;
use arrow_array::cast::AsArray as _;
use arrow_array::types::{Float32Type, Int64Type};
use mimicgen_engine::Rows;
use mimicgen_engine::image::{ImageStream, Pixels};
use mimicgen_io::lerobot::{LeRobotOptions, SubtaskLabel, export_lerobot};
use mimicgen_io::{DatagenInfo, DatasetWriter, DemoData, DemoReader, ReadOptions, WriterOptions};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

const H: usize = 16;
const W: usize = 24;

/// A demo of `steps` steps whose values (and images) depend on `seed`.
#[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation, clippy::cast_sign_loss)]
fn demo(steps: usize, seed: usize) -> DemoData {
    let value = |t: usize, i: usize| ((t * 7 + i * 3 + seed * 11) % 97) as f64 / 97.0 - 0.5;
    let rows = |w: usize| (0..steps).flat_map(|t| (0..w).map(move |i| value(t, i))).collect::<Vec<f64>>();
    // A picture that moves: a bright square at a position set by the step, on a gradient.
    let image: Vec<u8> = (0..steps)
        .flat_map(|t| {
            (0..H * W * 3).map(move |p| {
                let (y, x, c) = (p / (W * 3), (p / 3) % W, p % 3);
                let inside = (y / 4 == (t + seed) % 4) && (x / 6 == (t / 2) % 4);
                if inside { 240 } else { (40 + 5 * x + 3 * y + 30 * c) as u8 }
            })
        })
        .collect();
    DemoData {
        actions: Rows::from_vec(7, rows(7), "actions").unwrap(),
        rewards: Some((0..steps).map(|t| f64::from(u8::from(t + 1 == steps))).collect()),
        dones: Some((0..steps).map(|t| i64::from(t + 1 == steps)).collect()),
        obs: BTreeMap::from([
            ("robot0_eef_pos".to_owned(), (vec![3], rows(3))),
            ("robot0_eef_quat".to_owned(), (vec![4], rows(4))),
            ("robot0_gripper_qpos".to_owned(), (vec![2], rows(2))),
            ("object".to_owned(), (vec![5], rows(5))),
        ]),
        images: BTreeMap::from([("agentview_image".to_owned(), ImageStream { shape: [H, W, 3], pixels: Pixels::Rgb(image) })]),
        ..DemoData::default()
    }
}

fn write(path: &Path, demos: &[DemoData]) {
    let mut w =
        DatasetWriter::create(path, WriterOptions { env_args: Some(r#"{"env_name": "Stack_D0"}"#.into()), ..WriterOptions::default() })
            .unwrap();
    for d in demos {
        w.append(d).unwrap();
    }
    w.finish().unwrap();
}

fn options() -> LeRobotOptions {
    LeRobotOptions {
        state_keys: ["robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object"].map(str::to_owned).to_vec(),
        fps: 20,
        task: "stack the red cube on top of the green cube".into(),
        robot_type: "panda".into(),
        ffmpeg: LeRobotOptions::default_ffmpeg(),
        overwrite: false,
        subtasks: Vec::new(),
        card: None,
    }
}

fn read_parquet(path: &Path) -> RecordBatch {
    let file = std::fs::File::open(path).unwrap();
    let reader = ParquetRecordBatchReaderBuilder::try_new(file).unwrap().build().unwrap();
    let batches: Vec<RecordBatch> = reader.map(Result::unwrap).collect();
    arrow_select::concat::concat_batches(&batches[0].schema(), &batches).unwrap()
}

fn floats(batch: &RecordBatch, column: &str, row: usize) -> Vec<f32> {
    let list = batch.column_by_name(column).unwrap().as_fixed_size_list();
    list.value(row).as_primitive::<Float32Type>().values().to_vec()
}

fn ints(batch: &RecordBatch, column: &str) -> Vec<i64> {
    batch.column_by_name(column).unwrap().as_primitive::<Int64Type>().values().to_vec()
}

#[test]
fn an_export_holds_every_frame_episode_and_camera_as_lerobot_lays_them_out() {
    let dir = tempfile::tempdir().unwrap();
    let h5 = dir.path().join("demos.hdf5");
    let lengths = [12, 7, 9];
    let demos: Vec<DemoData> = lengths.iter().enumerate().map(|(i, &n)| demo(n, i)).collect();
    write(&h5, &demos);
    let out = dir.path().join("lerobot");
    let reader = DemoReader::open_with(&h5, ReadOptions::default()).unwrap();
    let mut progress = Vec::new();
    let summary = export_lerobot(&reader, &out, &options(), |done, total| progress.push((done, total))).unwrap();
    assert_eq!((summary.episodes, summary.frames), (3, 28));
    assert_eq!(progress, [(1, 3), (2, 3), (3, 3)]);
    assert_eq!(summary.videos, ["observation.images.agentview"]);
    assert!(!Path::new(&format!("{}.partial", out.display())).exists());

    // Frames: state = eef_pos + eef_quat + gripper_qpos + object, actions as float32.
    let frames = read_parquet(&out.join("data/chunk-000/file-000.parquet"));
    assert_eq!(frames.num_rows(), 28);
    assert_eq!(ints(&frames, "index"), (0..28).collect::<Vec<i64>>());
    let episode_index = ints(&frames, "episode_index");
    let frame_index = ints(&frames, "frame_index");
    let mut start = 0;
    for (e, (&n, d)) in lengths.iter().zip(&demos).enumerate() {
        assert!(episode_index[start..start + n].iter().all(|&i| i == e as i64));
        assert_eq!(frame_index[start..start + n], (0..n as i64).collect::<Vec<_>>());
        for t in [0, n - 1] {
            let action: Vec<f32> = d.actions.row(t).iter().map(|&v| v as f32).collect();
            assert_eq!(floats(&frames, "action", start + t), action, "episode {e} action {t}");
            let state = floats(&frames, "observation.state", start + t);
            assert_eq!(state.len(), 14);
            assert_eq!(state[..3], d.obs["robot0_eef_pos"].1[t * 3..t * 3 + 3].iter().map(|&v| v as f32).collect::<Vec<_>>()[..]);
            assert_eq!(state[9..], d.obs["object"].1[t * 5..t * 5 + 5].iter().map(|&v| v as f32).collect::<Vec<_>>()[..]);
        }
        let ts = frames.column_by_name("timestamp").unwrap().as_primitive::<Float32Type>();
        assert_eq!(ts.value(start + 1), 0.05);
        start += n;
    }

    // Episodes: boundaries, task, and where each episode's video starts.
    let episodes = read_parquet(&out.join("meta/episodes/chunk-000/file-000.parquet"));
    assert_eq!(ints(&episodes, "dataset_from_index"), [0, 12, 19]);
    assert_eq!(ints(&episodes, "dataset_to_index"), [12, 19, 28]);
    assert_eq!(ints(&episodes, "length"), [12, 7, 9]);
    let from_ts = episodes.column_by_name("videos/observation.images.agentview/from_timestamp").unwrap();
    assert_eq!(from_ts.as_primitive::<arrow_array::types::Float64Type>().values().to_vec(), [0.0, 0.6, 0.95]);
    let tasks = episodes.column_by_name("tasks").unwrap().as_list::<i32>();
    assert_eq!(tasks.value(2).as_string::<i32>().value(0), "stack the red cube on top of the green cube");
    // Tasks: the string is pandas' index (LeRobot looks the task up by it).
    let task_table = read_parquet(&out.join("meta/tasks.parquet"));
    assert_eq!(task_table.column_by_name("__index_level_0__").unwrap().as_string::<i32>().value(0), options().task);
    let file = std::fs::File::open(out.join("meta/tasks.parquet")).unwrap();
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).unwrap();
    let pandas: serde_json::Value = serde_json::from_str(&builder.schema().metadata()["pandas"]).unwrap();
    assert_eq!(pandas["index_columns"], serde_json::json!(["__index_level_0__"]));

    let info: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("meta/info.json")).unwrap()).unwrap();
    assert_eq!(
        (info["codebase_version"].as_str(), info["total_frames"].as_u64(), info["total_episodes"].as_u64()),
        (Some("v3.0"), Some(28), Some(3))
    );
    assert_eq!(info["features"]["observation.state"]["shape"], serde_json::json!([14]));
    assert_eq!(info["features"]["observation.images.agentview"]["shape"], serde_json::json!([H, W, 3]));
    let stats: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("meta/stats.json")).unwrap()).unwrap();
    assert_eq!(stats["action"]["count"], serde_json::json!([28]));
    assert_eq!(stats["observation.images.agentview"]["mean"].as_array().unwrap().len(), 3);

    // The video decodes back to the dataset's frames, episodes one after another.
    let video = out.join("videos/observation.images.agentview/chunk-000/file-000.mp4");
    let decoded = Command::new(options().ffmpeg)
        .args(["-v", "error", "-i"])
        .arg(&video)
        .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
        .output()
        .unwrap();
    assert!(decoded.status.success(), "{}", String::from_utf8_lossy(&decoded.stderr));
    let ours: Vec<u8> = demos
        .iter()
        .flat_map(|d| match &d.images["agentview_image"].pixels {
            Pixels::Rgb(p) => p.clone(),
            Pixels::Depth(_) => Vec::new(),
        })
        .collect();
    assert_eq!(decoded.stdout.len(), ours.len(), "frame count");
    let mae = decoded.stdout.iter().zip(&ours).map(|(a, b)| f64::from(a.abs_diff(*b))).sum::<f64>() / ours.len() as f64;
    assert!(mae < 6.0, "decoded frames differ by {mae:.2} / 255 on average");

    // An existing export is not replaced without overwrite.
    let err = export_lerobot(&reader, &out, &options(), |_, _| ()).unwrap_err();
    assert!(matches!(err, mimicgen_io::IoError::Exists { .. }) && err.is_user_error(), "{err}");
    export_lerobot(&reader, &out, &LeRobotOptions { overwrite: true, ..options() }, |_, _| ()).unwrap();
}

#[test]
fn bad_input_names_the_demo_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let h5 = dir.path().join("demos.hdf5");
    let mut broken = demo(5, 1);
    broken.actions = Rows::from_vec(7, (0..35).map(|i| if i == 12 { f64::NAN } else { 0.0 }).collect(), "actions").unwrap();
    write(&h5, &[demo(6, 0), broken]);
    let reader = DemoReader::open_with(&h5, ReadOptions::default()).unwrap();
    let out = dir.path().join("lr");
    let no_key = LeRobotOptions { state_keys: vec!["robot0_eef_pos".into(), "cube_pos".into()], ..options() };
    let err = export_lerobot(&reader, &out, &no_key, |_, _| ()).unwrap_err().to_string();
    assert!(err.contains("obs/cube_pos") && err.contains("data/demo_0") && err.contains("robot0_gripper_qpos"), "{err}");
    let err = export_lerobot(&reader, &out, &options(), |_, _| ()).unwrap_err().to_string();
    assert!(err.contains("data/demo_1") && err.contains("actions") && err.contains("NaN"), "{err}");
    assert!(!out.exists(), "a failed export must not look complete");
    let no_ffmpeg = LeRobotOptions { ffmpeg: dir.path().join("no-such-ffmpeg"), ..options() };
    let err = export_lerobot(&reader, &out, &no_ffmpeg, |_, _| ()).unwrap_err().to_string();
    assert!(err.contains("no-such-ffmpeg") && err.contains("setup.sh"), "{err}");
}

#[test]
fn frames_carry_their_subtask_and_the_card_is_the_readme() {
    let dir = tempfile::tempdir().unwrap();
    let h5 = dir.path().join("demos.hdf5");
    // Demo 0 grasps at step 3 (subtask 0 ends one step later), demo 1 never does.
    let with_signal = |steps: usize, seed: usize, grasp: Option<usize>| DemoData {
        datagen_info: Some(DatagenInfo {
            subtask_term_signals: BTreeMap::from([(
                "grasp".to_owned(),
                (0..steps).map(|t| i64::from(grasp.is_some_and(|g| t >= g))).collect(),
            )]),
            eef_poses: vec![mimicgen_engine::pose::Pose::identity(); steps],
            target_poses: vec![mimicgen_engine::pose::Pose::identity(); steps],
            gripper_actions: Rows::from_vec(1, vec![0.0; steps], "gripper").unwrap(),
            ..DatagenInfo::default()
        }),
        images: BTreeMap::new(),
        ..demo(steps, seed)
    };
    write(&h5, &[with_signal(6, 0, Some(3)), with_signal(4, 1, None)]);
    let reader = DemoReader::open_with(&h5, ReadOptions::default()).unwrap();
    let out = dir.path().join("lerobot");
    let subtasks = vec![
        SubtaskLabel { name: "cubeA until grasp".into(), end_signal: Some("grasp".into()) },
        SubtaskLabel { name: "cubeB until the task succeeds".into(), end_signal: None },
    ];
    let card = "---\ntags:\n- LeRobot\n---\n# A card\n".to_owned();
    let options = LeRobotOptions { subtasks: subtasks.clone(), card: Some(card.clone()), ..options() };
    let summary = export_lerobot(&reader, &out, &options, |_, _| ()).unwrap();
    assert_eq!(summary.subtasks, ["cubeA until grasp", "cubeB until the task succeeds"]);

    let frames = read_parquet(&out.join("data/chunk-000/file-000.parquet"));
    assert_eq!(ints(&frames, "subtask_index"), [0, 0, 0, 0, 1, 1, 0, 0, 0, 0]);
    let table = read_parquet(&out.join("meta/subtasks.parquet"));
    assert_eq!(ints(&table, "subtask_index"), [0, 1]);
    let names = table.column_by_name("__index_level_0__").unwrap().as_string::<i32>();
    assert_eq!((names.value(0), names.value(1)), ("cubeA until grasp", "cubeB until the task succeeds"));
    let info: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("meta/info.json")).unwrap()).unwrap();
    assert_eq!(info["features"]["subtask_index"]["dtype"], "int64");
    assert_eq!(std::fs::read_to_string(out.join("README.md")).unwrap(), card);

    // A demo without the signal is named.
    let bare = dir.path().join("bare.hdf5");
    write(&bare, &[DemoData { images: BTreeMap::new(), ..demo(5, 0) }]);
    let reader = DemoReader::open_with(&bare, ReadOptions::default()).unwrap();
    let err = export_lerobot(&reader, &dir.path().join("bare"), &options, |_, _| ()).unwrap_err().to_string();
    assert!(err.contains("data/demo_0") && err.contains("datagen_info/subtask_term_signals/grasp"), "{err}");
}
