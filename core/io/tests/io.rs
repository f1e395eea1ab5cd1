//! Reading, writing and round-tripping robomimic / MimicGen datasets, including malformed files.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used, clippy::float_cmp)] // tests fail loudly by design; exact equality is the point

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::Command;

use mimicgen_engine::spec::SourceSelection;
use mimicgen_engine::{Generator, TaskSpec, kinematic};
use mimicgen_io::tree::{Dataset, Group, Node, Values};
use mimicgen_io::{DatasetWriter, IoError, ReadOptions, RobomimicDataset, WriterOptions, read_source_dataset, write_tree};

/// HDF5 opens files without close-on-exec and locks them: a Python child spawned while another
/// test holds a file would keep that file locked. Tests that spawn take this lock exclusively.
static SPAWN_LOCK: std::sync::RwLock<()> = std::sync::RwLock::new(());

fn shared() -> std::sync::RwLockReadGuard<'static, ()> {
    SPAWN_LOCK.read().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn exclusive() -> std::sync::RwLockWriteGuard<'static, ()> {
    SPAWN_LOCK.write().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

const SOURCE: &str = "source_D0_prepared.hdf5";

fn stack_spec() -> TaskSpec {
    TaskSpec::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../engine/tests/data/config_D0.json")).unwrap()
}

fn python() -> PathBuf {
    let py = std::env::var_os("MIMICGEN_PYTHON")
        .map_or_else(|| PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache/mimicgen/venv/bin/python"), PathBuf::from);
    assert!(py.exists(), "Python interpreter {} not found: run scripts/setup.sh (or set MIMICGEN_PYTHON)", py.display());
    py
}

fn run_python(script: &str, args: &[&Path]) {
    let out = Command::new(python()).arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join(script)).args(args).output().unwrap();
    assert!(out.status.success(), "{script} failed:\n{}\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
}

fn dataset_mut<'a>(root: &'a mut Group, path: &str) -> &'a mut Dataset {
    let mut g = root;
    let parts: Vec<&str> = path.split('/').collect();
    for part in &parts[..parts.len() - 1] {
        g = match g.members.get_mut(*part) {
            Some(Node::Group(sub)) => sub,
            _ => panic!("no group {part} in {path}"),
        };
    }
    match g.members.get_mut(parts[parts.len() - 1]) {
        Some(Node::Dataset(d)) => d,
        _ => panic!("no dataset {path}"),
    }
}

fn f64s(d: &mut Dataset) -> &mut Vec<f64> {
    match &mut d.array.values {
        Values::F64(v) => v,
        other => panic!("not f64: {other:?}"),
    }
}

/// Writes the source fixture with `edit` applied into `dir/name` and returns its path.
fn edited_source(dir: &Path, name: &str, edit: impl FnOnce(&mut Group)) -> PathBuf {
    let mut ds = RobomimicDataset::open(data(SOURCE)).unwrap();
    edit(&mut ds.root);
    let path = dir.join(name);
    write_tree(&path, &ds.root).unwrap();
    path
}

#[test]
fn source_fixture_reads_into_engine_types_in_robomimic_order() {
    let _hdf5 = shared();
    let ds = read_source_dataset(data(SOURCE), &SourceSelection::default()).unwrap();
    assert_eq!(ds.demos.len(), 10);
    let names: Vec<&str> = ds.demos.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, (0..10).map(|i| format!("demo_{i}")).collect::<Vec<_>>());
    assert_eq!(ds.object_names(), ["cubeA", "cubeB"]);
    assert_eq!(ds.signal_names(), ["grasp"]);
    assert!(ds.env_args.as_deref().unwrap().contains("Stack_D0"));
    let d0 = &ds.demos[0];
    assert_eq!(d0.len(), 93);
    assert_eq!((d0.sim.actions.width(), d0.sim.states.width(), d0.gripper_actions.width()), (7, 45, 1));
    assert!(d0.sim.model_xml.as_deref().unwrap().starts_with("<mujoco"));
    // The engine accepts it: segmentation on the grasp signal works for every demo.
    Generator::new(stack_spec(), ds).unwrap();
}

#[test]
fn selection_applies_start_and_n_after_numeric_sorting() {
    let _hdf5 = shared();
    let sel = SourceSelection { start: Some(8), n: Some(5), ..SourceSelection::default() };
    let ds = read_source_dataset(data(SOURCE), &sel).unwrap();
    assert_eq!(ds.demos.iter().map(|d| d.name.clone()).collect::<Vec<_>>(), ["demo_8", "demo_9"]);
    let names = mimicgen_io::dataset::sort_demo_names(vec!["demo_10".into(), "demo_2".into(), "demo_1".into()]);
    assert_eq!(names, ["demo_1", "demo_2", "demo_10"]);
}

#[test]
fn source_fixture_round_trips_bit_for_bit() {
    let _hdf5 = exclusive();
    let dir = tempfile::tempdir().unwrap();
    for name in [SOURCE, "generated_D0_first3.hdf5"] {
        let original = RobomimicDataset::open(data(name)).unwrap();
        let copy = dir.path().join(name);
        original.write(&copy).unwrap();
        let back = RobomimicDataset::open(&copy).unwrap();
        assert_eq!(back.root, original.root, "{name}");
        run_python("compare_hdf5.py", &[&data(name), &copy]);
    }
}

#[test]
fn a_reference_generated_file_with_many_demos_reads_in_order() {
    let _hdf5 = shared();
    // The first 20 demos of the reference's generated Stack D0 dataset (see core/sim/tests/data).
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim/tests/data/generated_D0_replay.hdf5");
    let ds = RobomimicDataset::open(&path).unwrap();
    assert_eq!(ds.demo_names().len(), 20);
    // Numeric order, not the file's lexical order (demo_10 sorts before demo_2 as text).
    assert_eq!(ds.demo_names()[2], "demo_2");
    assert_eq!(ds.demo_names()[10], "demo_10");
    for name in ds.demo_names() {
        let demo = ds.demo(name).unwrap();
        let rows = |field: &str| demo.dataset_at(field).unwrap().array.shape[0];
        assert_eq!(rows("actions"), ds.demo_len(name));
        assert_eq!(rows("states"), ds.demo_len(name));
        assert_eq!(rows("datagen_info/eef_pose"), ds.demo_len(name));
    }
}

/// Generated attempts from the engine's kinematic environment, written with synthetic observations.
fn write_generated(path: &Path, attempts: usize, valid_fraction: Option<f64>) -> Vec<mimicgen_engine::Attempt> {
    let generator = Generator::new(kinematic::pick_place_spec(attempts, 3), kinematic::scripted_dataset(3, 1).unwrap()).unwrap();
    let mut kept = Vec::new();
    let mut envs = vec![kinematic::PickPlace::new(0.1)];
    mimicgen_engine::run(&generator, &mut envs, |a, _| {
        kept.push(a);
        ControlFlow::Continue(())
    })
    .unwrap();
    kept.sort_by_key(|a| a.index);
    let options = WriterOptions {
        env_args: Some(r#"{"env_name": "PickPlace", "type": 1, "env_kwargs": {"controller_configs": {"type": "OSC_POSE"}}}"#.into()),
        compress_obs: true,
        valid_fraction,
        split_seed: 7,
    };
    let mut writer = DatasetWriter::create(path, options).unwrap();
    for a in &kept {
        let n = a.trajectory.len();
        let eef: Vec<f64> = a.trajectory.eef_poses.iter().flat_map(|p| p.translation.vector.iter().copied().collect::<Vec<_>>()).collect();
        let obs = BTreeMap::from([("robot0_eef_pos".to_owned(), (vec![3], eef)), ("object".to_owned(), (vec![2, 2], vec![0.5; n * 4]))]);
        writer.append_attempt(a, obs, Some("<mujoco/>".into())).unwrap();
    }
    assert_eq!(writer.finish().unwrap(), path);
    kept
}

#[test]
fn written_dataset_reads_back_as_the_attempts_and_loads_like_robomimic() {
    let _hdf5 = exclusive();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("generated.hdf5");
    let attempts = write_generated(&path, 6, Some(0.34));
    assert!(!DatasetWriter::partial_path(&path).exists());
    let file = RobomimicDataset::open(&path).unwrap();
    let masks = file.masks().unwrap();
    assert_eq!(masks["valid"].len() + masks["train"].len(), 6);
    assert_eq!(masks["valid"].len(), 2);
    let back = file.to_source_dataset(&SourceSelection::default()).unwrap();
    for (a, d) in attempts.iter().zip(&back.demos) {
        assert_eq!(d.sim.actions, a.trajectory.actions);
        assert_eq!(d.sim.states, a.trajectory.states);
        assert_eq!(d.subtask_term_signals, a.trajectory.subtask_term_signals);
        for (p, q) in d.eef_poses.iter().zip(&a.trajectory.eef_poses) {
            assert!((p.to_homogeneous() - q.to_homogeneous()).abs().max() < 1e-12);
        }
    }
    let valid = file.to_source_dataset(&SourceSelection { filter_key: Some("valid".into()), ..SourceSelection::default() }).unwrap();
    assert_eq!(valid.demos.iter().map(|d| d.name.clone()).collect::<Vec<_>>(), masks["valid"]);
    run_python("check_robomimic_layout.py", &[&path]);
}

#[test]
fn an_unfinished_file_is_refused_unless_recovering() {
    let _hdf5 = shared();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.hdf5");
    let generator = Generator::new(kinematic::pick_place_spec(2, 3), kinematic::scripted_dataset(2, 1).unwrap()).unwrap();
    let mut env = kinematic::PickPlace::new(0.1);
    let mut writer = DatasetWriter::create(&out, WriterOptions::default()).unwrap();
    for i in 0..2 {
        writer.append_attempt(&generator.attempt(&mut env, i).unwrap(), BTreeMap::new(), None).unwrap();
    }
    drop(writer); // interrupted: never finished
    assert!(!out.exists());
    let partial = DatasetWriter::partial_path(&out);
    let err = RobomimicDataset::open(&partial).unwrap_err();
    assert!(matches!(err, IoError::Incomplete { complete_demos: 2, .. }), "{err}");
    assert!(err.to_string().contains("out.hdf5.partial"), "{err}");
    let recovered = RobomimicDataset::open_with(&partial, ReadOptions { recover: true }).unwrap();
    assert_eq!(recovered.demo_names(), ["demo_0", "demo_1"]);
}

#[test]
fn a_demo_without_num_samples_is_dropped_on_recovery() {
    let _hdf5 = shared();
    // What a crash between a demo's datasets and its closing `num_samples` attribute leaves.
    let dir = tempfile::tempdir().unwrap();
    let path = edited_source(dir.path(), "crashed.hdf5", |root| {
        root.attrs.insert(mimicgen_io::dataset::COMPLETE_ATTR.into(), mimicgen_io::tree::Array::int(0));
        if let Some(Node::Group(data)) = root.members.get_mut("data")
            && let Some(Node::Group(d9)) = data.members.get_mut("demo_9")
        {
            d9.attrs.remove("num_samples");
        }
    });
    let err = RobomimicDataset::open(&path).unwrap_err();
    assert!(matches!(err, IoError::Incomplete { complete_demos: 9, .. }), "{err}");
    let ok = RobomimicDataset::open_with(&path, ReadOptions { recover: true }).unwrap();
    assert_eq!(ok.demo_names().len(), 9);
}

#[test]
fn plain_robomimic_dataset_reports_what_mimicgen_needs() {
    let _hdf5 = shared();
    let dir = tempfile::tempdir().unwrap();
    let path = edited_source(dir.path(), "plain.hdf5", |root| {
        if let Some(Node::Group(data)) = root.members.get_mut("data") {
            for demo in data.members.values_mut() {
                if let Node::Group(d) = demo {
                    d.members.remove("datagen_info");
                }
            }
        }
    });
    let file = RobomimicDataset::open(&path).unwrap();
    let report = file.report();
    assert!(!report.is_mimicgen_source());
    assert_eq!(report.missing.len(), 5);
    assert!(report.present.contains(&"rewards".to_owned()));
    let err = file.to_source_dataset(&SourceSelection::default()).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("plain.hdf5")
            && msg.contains("`datagen_info/eef_pose` missing in 10 of 10 demos")
            && msg.contains("prepare_src_dataset"),
        "{msg}"
    );
}

mod malformed {
    use super::*;

    fn open_err(path: &Path) -> IoError {
        match RobomimicDataset::open(path).and_then(|d| d.to_source_dataset(&SourceSelection::default())) {
            Ok(_) => panic!("{} was accepted", path.display()),
            Err(e) => e,
        }
    }

    fn assert_names(err: &IoError, parts: &[&str]) {
        let msg = err.to_string();
        for p in parts {
            assert!(msg.contains(p), "`{msg}` does not mention `{p}`");
        }
    }

    #[test]
    fn truncated_file() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let bytes = std::fs::read(data(SOURCE)).unwrap();
        let path = dir.path().join("truncated.hdf5");
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let err = open_err(&path);
        assert!(matches!(err, IoError::Hdf5 { .. }), "{err}");
        assert_names(&err, &["truncated.hdf5"]);
    }

    #[test]
    fn a_file_that_cannot_be_opened_says_why_in_a_users_words() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let text = dir.path().join("notes.hdf5");
        std::fs::write(&text, "not a dataset\n").unwrap();
        let empty = dir.path().join("empty.hdf5");
        std::fs::write(&empty, "").unwrap();
        for (path, reason) in [
            (dir.path().join("nope.hdf5"), "no such file"),
            (dir.path().to_path_buf(), "is a directory"),
            (text, "not an HDF5 file"),
            (empty, "is empty"),
        ] {
            let err = open_err(&path);
            assert!(matches!(err, IoError::Open { .. }) && err.is_user_error(), "{err}");
            assert_names(&err, &[&path.display().to_string(), reason]);
            assert!(!err.to_string().contains("H5F"), "HDF5's own words leaked: {err}");
        }
    }

    #[test]
    fn missing_data_group() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let path = edited_source(dir.path(), "nodata.hdf5", |root| {
            let data = root.members.remove("data").unwrap();
            root.members.insert("demos".into(), data);
        });
        let err = open_err(&path);
        assert!(matches!(err, IoError::Missing { .. }), "{err}");
        assert_names(&err, &["nodata.hdf5", "group `/`", "`data`"]);
    }

    #[test]
    fn demo_without_actions() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let path = edited_source(dir.path(), "noactions.hdf5", |root| {
            if let Some(Node::Group(data)) = root.members.get_mut("data")
                && let Some(Node::Group(d)) = data.members.get_mut("demo_3")
            {
                d.members.remove("actions");
            }
        });
        assert_names(&open_err(&path), &["noactions.hdf5", "data/demo_3", "`actions`"]);
    }

    #[test]
    fn shape_mismatch_within_a_demo() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let path = edited_source(dir.path(), "shape.hdf5", |root| {
            let d = dataset_mut(root, "data/demo_2/states");
            d.array.shape[0] -= 1;
            let width = d.array.shape[1];
            let keep = d.array.shape[0] * width;
            f64s(d).truncate(keep);
        });
        let err = open_err(&path);
        assert!(matches!(err, IoError::Shape { .. }), "{err}");
        assert_names(&err, &["shape.hdf5", "data/demo_2", "`states`"]);
    }

    #[test]
    fn nan_pose() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let path = edited_source(dir.path(), "nan.hdf5", |root| {
            f64s(dataset_mut(root, "data/demo_1/datagen_info/eef_pose"))[5 * 16 + 3] = f64::NAN;
        });
        let err = open_err(&path);
        assert!(matches!(err, IoError::Invalid { .. }), "{err}");
        assert_names(&err, &["nan.hdf5", "data/demo_1/datagen_info", "`eef_pose`", "step 5", "NaN"]);
    }

    #[test]
    fn non_rigid_matrix() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let path = edited_source(dir.path(), "scaled.hdf5", |root| {
            let v = f64s(dataset_mut(root, "data/demo_0/datagen_info/object_poses/cubeB"));
            for i in [0, 5, 10] {
                v[7 * 16 + i] *= 2.0;
            }
        });
        assert_names(&open_err(&path), &["scaled.hdf5", "data/demo_0/datagen_info/object_poses", "`cubeB`", "step 7", "orthonormal"]);
    }

    #[test]
    fn signal_that_never_turns_on() {
        let _hdf5 = shared();
        let dir = tempfile::tempdir().unwrap();
        let path = edited_source(dir.path(), "nosignal.hdf5", |root| {
            match &mut dataset_mut(root, "data/demo_4/datagen_info/subtask_term_signals/grasp").array.values {
                Values::I64(v) => v.iter_mut().for_each(|x| *x = 0),
                other => panic!("{other:?}"),
            }
        });
        let sources = read_source_dataset(&path, &SourceSelection::default()).unwrap();
        let err = Generator::new(stack_spec(), sources).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("demo_4") && msg.contains("subtask 0"), "{msg}");
    }

    #[test]
    fn unknown_object_in_task_spec() {
        let _hdf5 = shared();
        let sources = read_source_dataset(data(SOURCE), &SourceSelection::default()).unwrap();
        let mut spec = stack_spec();
        spec.subtasks[0].object_ref = Some("cubeZ".into());
        let msg = Generator::new(spec, sources).unwrap_err().to_string();
        assert!(msg.contains("cubeZ") && msg.contains("cubeA"), "{msg}");
    }

    #[test]
    fn unknown_filter_key() {
        let _hdf5 = shared();
        let err = RobomimicDataset::open(data(SOURCE))
            .unwrap()
            .to_source_dataset(&SourceSelection { filter_key: Some("train".into()), ..SourceSelection::default() })
            .unwrap_err();
        assert_names(&err, &[SOURCE, "group `mask`", "`train`"]);
    }
}

#[test]
fn mcap_export_reads_back_in_rust_and_python() {
    let _hdf5 = exclusive();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("g3.mcap");
    let ds = RobomimicDataset::open(data("generated_D0_first3.hdf5")).unwrap();
    let steps: usize = ds.demo_names().iter().map(|n| ds.demo_len(n)).sum();
    let summary = mimicgen_io::mcap_export::export(&ds, &out).unwrap();
    assert_eq!(summary.steps, steps as u64);
    let bytes = std::fs::read(&out).unwrap();
    let mut per_topic: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    let mut first_eef = None;
    for msg in mcap::MessageStream::new(&bytes).unwrap() {
        let msg = msg.unwrap();
        let schema = msg.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "jsonschema");
        let value: serde_json::Value = serde_json::from_slice(&msg.data).unwrap();
        if msg.channel.topic == "/eef_pose" {
            assert_eq!(schema.name, "foxglove.PoseInFrame");
            first_eef.get_or_insert(value);
        }
        per_topic.entry(msg.channel.topic.clone()).or_default().push(msg.log_time);
    }
    assert_eq!(
        per_topic.keys().collect::<Vec<_>>(),
        ["/actions", "/eef_pose", "/gripper", "/objects/cubeA", "/objects/cubeB", "/source_demo", "/subtask", "/success", "/target_pose"]
    );
    let times = &per_topic["/eef_pose"];
    assert_eq!(times.len(), steps);
    assert!(times.windows(2).all(|w| w[1] - w[0] == mimicgen_io::mcap_export::STEP_NANOS));
    // The first message carries demo_0's first eef pose.
    let eef = &first_eef.unwrap()["pose"]["position"];
    let m = match &ds.demo("demo_0").unwrap().dataset_at("datagen_info/eef_pose").unwrap().array.values {
        Values::F64(v) => v[..16].to_vec(),
        other => panic!("{other:?}"),
    };
    // serde_json's default float parser may be 1 ulp off; the writer prints shortest round-trip form.
    for (key, want) in [("x", m[3]), ("y", m[7]), ("z", m[11])] {
        assert!((eef[key].as_f64().unwrap() - want).abs() < 1e-15, "{key}");
    }
    run_python("check_mcap.py", &[&out]);
}

#[test]
fn demo_reader_streams_the_same_dataset() {
    let _hdf5 = shared();
    use mimicgen_io::DemoSource as _;
    for name in [SOURCE, "generated_D0_first3.hdf5"] {
        let whole = RobomimicDataset::open(data(name)).unwrap();
        let reader = mimicgen_io::DemoReader::open_with(data(name), ReadOptions::default()).unwrap();
        assert_eq!(reader.demo_names(), whole.demo_names());
        for demo in whole.demo_names() {
            assert_eq!(&*reader.load_demo(demo).unwrap(), whole.demo(demo).unwrap());
        }
        assert_eq!(mimicgen_io::info::DatasetInfo::of(&reader).unwrap(), mimicgen_io::info::DatasetInfo::of(&whole).unwrap());
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.hdf5");
    let mut writer = DatasetWriter::create(&out, WriterOptions::default()).unwrap();
    let generator = Generator::new(kinematic::pick_place_spec(1, 3), kinematic::scripted_dataset(2, 1).unwrap()).unwrap();
    writer.append_attempt(&generator.attempt(&mut kinematic::PickPlace::new(0.1), 0).unwrap(), BTreeMap::new(), None).unwrap();
    drop(writer);
    let partial = DatasetWriter::partial_path(&out);
    let err = mimicgen_io::DemoReader::open_with(&partial, ReadOptions::default()).unwrap_err();
    assert!(matches!(err, IoError::Incomplete { complete_demos: 1, .. }), "{err}");
    let reader = mimicgen_io::DemoReader::open_with(&partial, ReadOptions { recover: true }).unwrap();
    assert_eq!(reader.demo_names(), ["demo_0"]);
}

#[test]
fn h5py_masks_select_demos_and_round_trip() {
    let _hdf5 = exclusive();
    let dir = tempfile::tempdir().unwrap();
    let masked = dir.path().join("masked.hdf5");
    std::fs::copy(data(SOURCE), &masked).unwrap();
    let mut perms = std::fs::metadata(&masked).unwrap().permissions();
    #[allow(clippy::permissions_set_readonly_false)] // a private temp copy
    perms.set_readonly(false);
    std::fs::set_permissions(&masked, perms).unwrap();
    // robomimic's split_train_val_from_hdf5 writes masks as numpy byte strings (`S6`).
    let script = "import sys, h5py, numpy as np\n\
                  f = h5py.File(sys.argv[1], 'a')\n\
                  f.create_dataset('mask/train', data=np.array(['demo_%d' % i for i in (0, 2, 4, 6, 8, 10)][:5], dtype='S'))\n\
                  f.create_dataset('mask/valid', data=np.array(['demo_9', 'demo_1'], dtype='S'))\n";
    let out = Command::new(python()).args(["-c", script]).arg(&masked).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let file = RobomimicDataset::open(&masked).unwrap();
    let valid = file.select(&SourceSelection { filter_key: Some("valid".into()), ..SourceSelection::default() }).unwrap();
    assert_eq!(valid, ["demo_1", "demo_9"]);
    let train = file
        .select(&SourceSelection { filter_key: Some("train".into()), start: Some(1), n: Some(2), ..SourceSelection::default() })
        .unwrap();
    assert_eq!(train, ["demo_2", "demo_4"]);
    let copy = dir.path().join("copy.hdf5");
    file.write(&copy).unwrap();
    run_python("compare_hdf5.py", &[&masked, &copy]);
}

/// A two-arm demo written with each arm's end effector under `datagen_info/<field>/<arm>` reads
/// back as one view per arm: the arm's own poses and gripper, the objects and signals shared; a
/// missing arm is refused naming its field.
#[test]
fn a_two_arm_demo_reads_back_as_one_view_per_arm() {
    use mimicgen_engine::Pose;
    use mimicgen_engine::demo::Rows;
    use mimicgen_io::{ArmInfo, DatagenInfo, DemoData};
    let _guard = shared();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two.hdf5");
    let steps = 6;
    let poses = |x: f64| (0..steps).map(|t| Pose::translation(x, 0.01 * t as f64, 1.0)).collect::<Vec<_>>();
    let gripper = |v: f64| Rows::from_vec(1, vec![v; steps], "gripper").unwrap();
    let arm = |name: &str, x: f64, g: f64| ArmInfo {
        name: name.to_owned(),
        eef_poses: poses(x),
        target_poses: poses(x + 0.001),
        gripper_actions: gripper(g),
    };
    let demo = DemoData {
        actions: Rows::from_vec(14, vec![0.0; 14 * steps], "actions").unwrap(),
        states: Rows::from_vec(3, vec![0.0; 3 * steps], "states").unwrap(),
        datagen_info: Some(DatagenInfo {
            object_poses: BTreeMap::from([("pot".to_owned(), poses(0.5))]),
            subtask_term_signals: BTreeMap::from([("grasp0".to_owned(), vec![0, 0, 1, 1, 1, 1])]),
            arms: vec![arm("robot0", -0.3, -1.0), arm("robot1", 0.3, 1.0)],
            ..DatagenInfo::default()
        }),
        ..DemoData::default()
    };
    let mut writer = DatasetWriter::create(&path, WriterOptions::default()).unwrap();
    writer.append(&demo).unwrap();
    writer.finish().unwrap();
    let file = RobomimicDataset::open(&path).unwrap();
    let views = file.to_arm_source_datasets(&SourceSelection::default(), &["robot0", "robot1"]).unwrap();
    assert_eq!(views.len(), 2);
    for (view, (x, g)) in views.iter().zip([(-0.3, -1.0), (0.3, 1.0)]) {
        let d = &view.demos[0];
        assert_eq!(d.eef_poses, poses(x));
        assert_eq!(d.target_poses, poses(x + 0.001));
        assert_eq!(d.gripper_actions.row(0), &[g]);
        assert_eq!(d.object_poses["pot"], poses(0.5));
        assert_eq!(d.subtask_term_signals["grasp0"], vec![0, 0, 1, 1, 1, 1]);
    }
    let err = file.to_arm_source_datasets(&SourceSelection::default(), &["robot0", "robot2"]).unwrap_err().to_string();
    assert!(err.contains("two.hdf5") && err.contains("datagen_info/eef_pose") && err.contains("robot2"), "{err}");
    // Read as a one-arm source, the file says it is a two-arm one.
    let err = file.to_source_dataset(&SourceSelection::default()).unwrap_err().to_string();
    assert!(err.contains("two.hdf5") && err.contains("two-arm demo") && err.contains("robot0, robot1"), "{err}");
}
