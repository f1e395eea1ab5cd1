//! The `mimicgen` command line.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::process::Command;

use mimicgen_engine::TaskSpec;
use mimicgen_io::RobomimicDataset;

fn mimicgen() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mimicgen"))
}

#[test]
fn spec_convert_turns_a_mimicgen_config_into_equivalent_toml() {
    let json = repo_path("core/engine/tests/data/config_D0.json");
    let out = mimicgen().args(["spec", "convert"]).arg(&json).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let from_toml = TaskSpec::from_toml_str(&String::from_utf8(out.stdout).unwrap(), "stdout").unwrap();
    assert_eq!(from_toml, TaskSpec::load(&json).unwrap());
}

#[test]
fn spec_check_names_the_bad_field() {
    let dir = std::env::temp_dir().join(format!("mimicgen-flow-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[[subtask]]\nobject_ref = \"cubeA\"\nselection = { strategy = \"nearest_neighbor_object\", nn_k = 0 }\n")
        .unwrap();
    let out = mimicgen().args(["spec", "check"]).arg(&bad).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml") && err.contains("subtask[0].selection.nn_k"), "{err}");
    assert_eq!(err.matches("bad.toml").count(), 1, "the file is named once: {err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_spec_naming_an_unknown_object_is_blamed_once_by_file_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad_spec.toml");
    let stack = std::fs::read_to_string(repo_path("core/sim/tasks/stack.toml")).unwrap();
    let line = stack.lines().position(|l| l.trim() == "object_ref = \"cubeA\"").unwrap() + 1;
    std::fs::write(&bad, stack.replace("object_ref = \"cubeA\"", "object_ref = \"nope\"")).unwrap();
    let out = dir.path().join("out.hdf5");
    let generate = mimicgen()
        .args(["generate", "--num-demos", "1", "--workers", "1", "--config"])
        .arg(&bad)
        .arg("--out")
        .arg(&out)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .output()
        .unwrap();
    let check = mimicgen().args(["spec", "check"]).arg(&bad).output().unwrap();
    for (command, run) in [("generate", generate), ("spec check", check)] {
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{command}: {err}");
        assert!(err.contains(&format!("bad_spec.toml:{line}")), "{command} names the spec file and line: {err}");
        assert!(err.contains("subtask[0].object_ref") && err.contains("\"nope\""), "{command}: {err}");
        assert!(err.contains("\"cubeA\", \"cubeB\""), "{command} says which objects exist: {err}");
        assert_eq!(err.matches("does not exist").count(), 1, "{command} says it once: {err}");
        assert!(!err.contains("source.hdf5"), "{command} blames the spec, not the sources: {err}");
    }
    assert!(!out.exists());
}

#[test]
fn every_command_ends_quietly_when_its_reader_has_gone() {
    let json = repo_path("core/engine/tests/data/config_D0.json");
    let source = repo_path("core/sim/data/stack_D0_source.hdf5");
    let commands: [&[&std::ffi::OsStr]; 4] = [
        &["tasks".as_ref()],
        &["spec".as_ref(), "convert".as_ref(), json.as_os_str()],
        &["spec".as_ref(), "check".as_ref(), json.as_os_str()],
        &["info".as_ref(), source.as_os_str()],
    ];
    for args in commands {
        // A pipe whose reader is closed before the command starts: its first write fails.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = mimicgen().args(args).stdout(writer).env("HDF5_USE_FILE_LOCKING", "FALSE").output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        assert!(err.is_empty(), "{args:?} says nothing: {err}");
    }
}

fn repo_path(relative: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(relative)
}

#[test]
fn help_teaches_with_examples() {
    let out = mimicgen().arg("--help").output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Examples:") && text.contains("mimicgen spec check"), "{text}");
}

#[test]
fn square_generates_end_to_end_with_each_demos_peg_in_its_model_file() {
    let tasks = mimicgen().arg("tasks").output().unwrap();
    let listing = String::from_utf8_lossy(&tasks.stdout);
    assert!(listing.contains("square") && listing.contains("D2"), "{listing}");
    let bad = mimicgen().args(["generate", "--task", "square", "--variant", "D3"]).output().unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("D0, D1, D2 and C0"), "{}", String::from_utf8_lossy(&bad.stderr));

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("square_d1.hdf5");
    let run = mimicgen()
        .args(["generate", "--task", "square", "--variant", "D1", "--num-demos", "3", "--workers", "1", "--out"])
        .arg(&out)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["attempts"], 3);
    let written = mimicgen_io::read_source_dataset(&out, &Default::default()).unwrap();
    assert!(written.env_args.as_deref().unwrap_or_default().contains("Square_D1"));
    assert!(!written.demos.is_empty(), "{report}");
    for demo in &written.demos {
        let peg = demo.object_poses["square_peg"][0].translation.vector;
        let xml = demo.sim.model_xml.as_deref().unwrap();
        let tag = &xml[xml.find(r#"<body name="peg1""#).unwrap()..];
        let pos = &tag[tag.find("pos=\"").unwrap() + 5..];
        let pos: Vec<f64> = pos[..pos.find('"').unwrap()].split(' ').map(|v| v.parse().unwrap()).collect();
        assert!((pos[0] - peg.x).abs() < 1e-12 && (pos[1] - peg.y).abs() < 1e-12, "{} model_file peg {pos:?} vs {peg:?}", demo.name);
    }
}

#[test]
fn annotate_writes_typed_ends_where_mimicgen_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("annotated.hdf5");
    let source = repo_path("core/io/tests/data/source_D0_prepared.hdf5");
    let run = mimicgen()
        .args(["annotate"])
        .arg(&source)
        .args(["--ends", "demo_2=30", "--starts", "demo_2=1:40", "--auto", "--out"])
        .arg(&out)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("ends typed with --ends") && stdout.contains("within 5 steps"), "{stdout}");
    let back = mimicgen_io::read_source_dataset(&out, &Default::default()).unwrap();
    // The marked segment start, beside the ends (none marked for the grasp).
    assert_eq!(back.demos[2].manual_subtask_starts, Some(vec![None, Some(40)]));
    assert_eq!(back.demos[0].manual_subtask_starts, None);
    let bad = mimicgen().args(["annotate"]).arg(&source).args(["--starts", "demo_2=4:40"]).output().unwrap();
    assert_eq!(bad.status.code(), Some(2), "a subtask the task lacks is a usage error");
    assert!(String::from_utf8_lossy(&bad.stderr).contains("subtask 4"), "{}", String::from_utf8_lossy(&bad.stderr));
    let grasp = &back.demos[2].subtask_term_signals["grasp"];
    // Step 30 is the subtask's last step: the signal turns on there.
    assert_eq!((grasp[29], grasp[30]), (0, 1));
    // The input is never the output.
    let same = mimicgen().args(["annotate"]).arg(&out).args(["--auto", "--out"]).arg(&out).args(["--overwrite"]).output().unwrap();
    assert!(!same.status.success());
}

#[test]
fn a_task_file_of_ones_own_is_listed_recorded_and_generated() {
    // A new task with no code: Stack's file renamed, the red cube swapped for a taller block and
    // both placed wider; its generation spec is Stack's.
    let dir = std::env::temp_dir().join(format!("mimicgen-task-dir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stack = std::fs::read_to_string(repo_path("core/sim/tasks/stack.task.toml")).unwrap();
    let tower = stack
        .replace("name = \"stack\"", "name = \"tower\"")
        .replace("env_name = \"Stack\"", "env_name = \"Tower\"")
        .replace("half_size = [0.02, 0.02, 0.02]", "half_size = [0.02, 0.02, 0.03]")
        .replace("height_m = 0.03\n", "height_m = 0.04\n")
        .replace("release_height_m = 0.051", "release_height_m = 0.061");
    std::fs::write(dir.join("tower.task.toml"), tower).unwrap();
    let spec = std::fs::read_to_string(repo_path("core/sim/tasks/stack.toml")).unwrap().replace("name = \"stack\"", "name = \"tower\"");
    std::fs::write(dir.join("tower.toml"), spec).unwrap();
    let run = |args: &[&str]| mimicgen().env("MIMICGEN_TASK_DIR", &dir).args(args).output().unwrap();
    let listed = String::from_utf8_lossy(&run(&["tasks"]).stdout).into_owned();
    assert!(listed.contains("tower") && listed.contains("pick_place") && listed.contains("ur5e"), "{listed}");
    let sources = dir.join("tower_sources.hdf5");
    let out = run(&["demos", "--task", "tower", "--num-demos", "2", "--out", sources.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let generated = dir.join("tower_D1.hdf5");
    let out = run(&[
        "generate",
        "--task",
        "tower",
        "--variant",
        "D1",
        "--source",
        sources.to_str().unwrap(),
        "--num-demos",
        "4",
        "--out",
        generated.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let info = String::from_utf8_lossy(&mimicgen().args(["info"]).arg(&generated).output().unwrap().stdout).into_owned();
    assert!(info.contains("Tower_D1"), "{info}");
    // A file naming an object it does not have is refused where its task is used, naming the
    // file and the field; every other task still works, and `tasks` marks it.
    std::fs::write(
        dir.join("broken.task.toml"),
        std::fs::read_to_string(dir.join("tower.task.toml"))
            .unwrap()
            .replace("name = \"tower\"", "name = \"broken\"")
            .replace("grasped = \"cubeA\"", "grasped = \"cubeZ\""),
    )
    .unwrap();
    let out = run(&["generate", "--task", "broken", "--num-demos", "1", "--out", dir.join("x.hdf5").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("broken.task.toml") && err.contains("signals.grasp") && err.contains("cubeZ"), "{err}");
    let out = run(&[
        "generate",
        "--task",
        "tower",
        "--source",
        sources.to_str().unwrap(),
        "--num-demos",
        "1",
        "--out",
        dir.join("y.hdf5").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let listed = String::from_utf8_lossy(&run(&["tasks"]).stdout).into_owned();
    assert!(
        listed.contains("tower")
            && listed.contains("stack ")
            && listed.lines().any(|l| l.starts_with("broken") && l.contains("BROKEN") && l.contains("cubeZ")),
        "{listed}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `mimicgen serve` refuses what it cannot serve before it listens, with exit code 2 and a
/// message naming the flag or file.
#[test]
fn serve_refuses_bad_setups_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let bundle = dir.path().join("web");
    std::fs::create_dir(&bundle).unwrap();
    let serve = |args: &[&str]| {
        let out = mimicgen().arg("serve").args(args).args(["--port", "0", "--no-viewer"]).output().unwrap();
        (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    // No bundle built: names the missing file and the script that builds it.
    let (code, err) = serve(&["--web-dir", bundle.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("mimicgen_web.js") && err.contains("build_web.sh"), "{err}");
    // A bundle there (its content is not checked here), a file outside the root.
    for name in ["mimicgen_web.js", "mimicgen_web_bg.wasm"] {
        std::fs::write(bundle.join(name), b"x").unwrap();
    }
    let root = dir.path().join("root");
    std::fs::create_dir(&root).unwrap();
    let (code, err) = serve(&["../outside.hdf5", "--root", root.to_str().unwrap(), "--web-dir", bundle.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("FILE") && err.contains("outside.hdf5"), "{err}");
    // A token too short to guard anything.
    let (code, err) = serve(&["--host", "0.0.0.0", "--token", "short", "--web-dir", bundle.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--token"), "{err}");
}

/// `demos`, `prepare` and `export --mcap` never replace a file that is there without
/// `--overwrite`, and `prepare` never writes onto its own input: the file keeps its bytes.
#[test]
fn commands_refuse_to_replace_an_existing_output() {
    let dir = tempfile::tempdir().unwrap();
    let existing = dir.path().join("existing.bin");
    let bytes = b"a file the user cares about".to_vec();
    std::fs::write(&existing, &bytes).unwrap();
    let input = dir.path().join("input.hdf5");
    std::fs::copy(repo_path("core/io/tests/data/robosuite_lift_demo.hdf5"), &input).unwrap();
    let input_bytes = std::fs::read(&input).unwrap();
    let out = existing.to_str().unwrap();
    let refused = |args: &[&str], names: &str| {
        let run = mimicgen().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(names), "{args:?}: {err}");
    };
    let source = repo_path("core/io/tests/data/source_D0_prepared.hdf5");
    let source = source.to_str().unwrap();
    let advice = "exists; pass --overwrite to replace it, or choose another output";
    refused(&["demos", "--task", "stack", "--num-demos", "1", "--out", out], advice);
    refused(&["prepare", input.to_str().unwrap(), "--out", out], advice);
    refused(&["export", input.to_str().unwrap(), "--mcap", out], advice);
    refused(&["generate", "--source", source, "--num-demos", "1", "--out", out], advice);
    refused(&["render", source, "--out", out], advice);
    refused(&["annotate", source, "--auto", "--out", out], advice);
    // The doctor refuses before it reads the run: the run need not exist for that.
    refused(&["doctor", "no_such_run.json", "--json", out], advice);
    assert_eq!(std::fs::read(&existing).unwrap(), bytes);
    // A run without its report: the file named, a user's mistake.
    refused(&["doctor", dir.path().join("gone.hdf5").to_str().unwrap()], "gone.json");
    // Onto the input itself: refused even when asked to replace.
    refused(&["prepare", input.to_str().unwrap(), "--out", input.to_str().unwrap(), "--overwrite"], "is the input");
    refused(&["export", input.to_str().unwrap(), "--mcap", input.to_str().unwrap(), "--overwrite"], "is the input");
    assert_eq!(std::fs::read(&input).unwrap(), input_bytes);
    // Asked to, the MCAP export replaces the file.
    let run = mimicgen().args(["export", input.to_str().unwrap(), "--mcap", out, "--overwrite"]).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_ne!(std::fs::read(&existing).unwrap(), bytes);
}

#[test]
fn exit_status_tells_a_users_mistake_from_a_failure() {
    let dir = tempfile::tempdir().unwrap();
    let said = |args: &[&str]| {
        let run = mimicgen().args(args).output().unwrap();
        (run.status.code(), String::from_utf8_lossy(&run.stderr).into_owned())
    };
    // A missing input is named in a user's words, not HDF5's.
    let nope = dir.path().join("nope.hdf5");
    let (code, err) = said(&["info", nope.to_str().unwrap()]);
    assert_eq!((code, err.trim()), (Some(2), format!("error: {}: no such file", nope.display()).as_str()));
    let (code, err) = said(&["info", dir.path().to_str().unwrap()]);
    assert!(code == Some(2) && err.contains("is a directory"), "{err}");
    let text = dir.path().join("notes.hdf5");
    std::fs::write(&text, "hello").unwrap();
    let (code, err) = said(&["info", text.to_str().unwrap()]);
    assert!(code == Some(2) && err.contains("notes.hdf5: not an HDF5 file"), "{err}");
    // An unknown task, a bad argument value.
    let (code, err) = said(&["demos", "--task", "nope", "--out", dir.path().join("d.hdf5").to_str().unwrap()]);
    assert!(code == Some(2) && err.contains("nope"), "{err}");
    let (code, _) = said(&["generate", "--num-demos", "many"]);
    assert_eq!(code, Some(2));
    // The machine failing (a full disk: /dev/full refuses every write) is 1: worth a retry.
    let input = repo_path("core/io/tests/data/robosuite_lift_demo.hdf5");
    let (code, err) = said(&["export", input.to_str().unwrap(), "--mcap", "/dev/full", "--overwrite"]);
    assert!(code == Some(1) && err.contains("/dev/full"), "{err}");
    // The table is in --help.
    let help = mimicgen().arg("--help").output().unwrap();
    assert!(String::from_utf8_lossy(&help.stdout).contains("130  interrupted"));
}

/// `mimicgen replay` drives a generated attempt again as generation drove it (closed loop
/// towards its stored controller targets, plus its own action noise): in the simulator that made
/// it, it succeeds again with the end effector where the file says it was at every step. Open
/// loop, the stored actions do the same. A demo the file lacks, or a file without controller
/// targets, is the user's mistake (exit status 2), named.
#[test]
fn replay_repeats_a_generated_attempt_step_for_step() {
    use mimicgen_pipeline::replay::DemoTrace;
    let dir = tempfile::tempdir().unwrap();
    let generated = dir.path().join("g.hdf5");
    let g = generated.to_str().unwrap();
    let run = mimicgen().args(["generate", "--num-demos", "2", "--seed", "1", "--workers", "1", "--out", g]).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let trace = dir.path().join("trace.json");
    let run = mimicgen().args(["replay", g, "--trace", trace.to_str().unwrap()]).output().unwrap();
    let said = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success() && said.contains("replay (targets): 2 of 2 succeeded"),
        "{said}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let traces: Vec<DemoTrace> = serde_json::from_slice(&std::fs::read(&trace).unwrap()).unwrap();
    let dataset = mimicgen_io::RobomimicDataset::open(&generated).unwrap();
    assert_eq!(traces.len(), 2);
    for t in &traces {
        let stored = dataset.demo(&t.demo).unwrap().dataset_at("datagen_info/eef_pose").unwrap().array.values.to_f64().unwrap();
        let steps = stored.len() / 16;
        assert_eq!(t.steps.len(), steps + 1, "{}: the start, then one state per action", t.demo);
        // Bit-for-bit is not promised (the file's state omits the solver's warm start); 1 mm is
        // far below the 5 mm at which scripts/compare_physics.py calls two runs parted.
        let worst = (0..steps)
            .map(|s| {
                let m = &stored[16 * s..16 * s + 16];
                let e = &t.steps[s].eef;
                ((e[0] - m[3]).powi(2) + (e[1] - m[7]).powi(2) + (e[2] - m[11]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        println!("{}: worst end-effector distance to the stored pose {:.3} mm", t.demo, 1000.0 * worst);
        assert!(worst < 1e-3, "{}: the replay parts from the stored attempt by {worst} m", t.demo);
        assert!(t.success && t.objects.contains_key("cubeA") && !t.pads[0].is_empty(), "{}", t.demo);
    }
    let run = mimicgen().args(["replay", g, "--mode", "actions"]).output().unwrap();
    assert!(String::from_utf8_lossy(&run.stdout).contains("replay (actions): 2 of 2 succeeded"));
    // Mistakes: a demo the file lacks; targets from a file that has none.
    let run = mimicgen().args(["replay", g, "--demos", "demo_0,demo_9"]).output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.code() == Some(2) && err.contains("no demo \"demo_9\""), "{err}");
    let lift = repo_path("core/io/tests/data/robosuite_lift_demo.hdf5");
    let run = mimicgen().args(["replay", lift.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.code() == Some(2) && err.contains("datagen_info/eef_pose"), "{err}");
}

/// `mimicgen demos` reproduces every bundled scripted source file (careful and human style) from
/// the command its row in `core/sim/data/README.md` gives: Stack's two files byte for byte, and
/// for the others (to keep the test short) the first three demos, group by group (arrays,
/// attributes, `model_file`): demos are recorded one after another from one seeded generator, so
/// the first three of ten are the three a run asking for three records.
#[test]
fn demos_reproduces_every_bundled_source_file() {
    let readme = std::fs::read_to_string(repo_path("core/sim/data/README.md")).unwrap();
    let commands: Vec<Vec<String>> = readme
        .split('`')
        .filter(|s| s.starts_with("mimicgen demos ") && s.contains(" --out core/sim/data/"))
        .map(|s| s.split_whitespace().skip(1).map(str::to_owned).collect())
        .collect();
    assert!(commands.len() >= 30, "12 one-arm and 3 two-arm tasks in two styles: {} commands in the README", commands.len());
    let dir = tempfile::tempdir().unwrap();
    let check = |args: &Vec<String>| -> Option<String> {
        let at = |flag: &str| args.iter().position(|a| a == flag).unwrap() + 1;
        let bundled = repo_path(&args[at("--out")]);
        let whole = args.iter().any(|a| a == "stack");
        let mut args = args.clone();
        let fresh = dir.path().join(bundled.file_name().unwrap());
        let out = at("--out");
        args[out] = fresh.display().to_string();
        if !whole {
            let n = at("--num-demos");
            args[n] = "3".to_owned();
        }
        let run = mimicgen().args(&args).output().unwrap();
        if !run.status.success() {
            return Some(format!("{}: {}", args.join(" "), String::from_utf8_lossy(&run.stderr)));
        }
        let same = if whole {
            std::fs::read(&fresh).unwrap() == std::fs::read(&bundled).unwrap()
        } else {
            let (fresh, bundled) = (RobomimicDataset::open(&fresh).unwrap(), RobomimicDataset::open(&bundled).unwrap());
            fresh.env_args() == bundled.env_args()
                && fresh.demo_names().len() == 3
                && fresh.demo_names().iter().all(|name| fresh.demo(name).is_some() && fresh.demo(name) == bundled.demo(name))
        };
        (!same).then(|| format!("{} differs from {}", args.join(" "), bundled.display()))
    };
    // Two at a time; each command is checked whatever the other does.
    let (first, second) = commands.split_at(commands.len() / 2);
    let failures: Vec<String> = std::thread::scope(|scope| {
        let other = scope.spawn(|| second.iter().filter_map(check).collect::<Vec<_>>());
        let mut failures: Vec<String> = first.iter().filter_map(check).collect();
        failures.extend(other.join().unwrap());
        failures
    });
    assert!(failures.is_empty(), "{failures:#?}");
}
