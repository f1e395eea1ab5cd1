"""The wheel from Python: datasets, specs, annotation, generation (events, report, Ctrl-C),
coverage, shards, and a simulator written in Python driven by the Rust engine."""

import os
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

import mimicgen_rs as mg
from kinematic_stack import KinematicStack

FIXTURE = Path(__file__).resolve().parents[3] / "core/io/tests/data/source_D0_prepared.hdf5"


def same_datasets(a, b):
    da, db = mg.Dataset(a), mg.Dataset(b)
    assert da.demo_names == db.demo_names
    for name in da.demo_names:
        xa, xb = da.demo(name), db.demo(name)
        assert xa.keys() == xb.keys()
        for key in xa:
            assert np.array_equal(np.asarray(xa[key]), np.asarray(xb[key])), f"{name}/{key}"


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "stack.hdf5"
    run = mg.generate(out, num_demos=4, seed=1, workers=2, keep_failed=True)
    events = list(run)
    return out, events, run.report


def test_generate_reports_events_and_a_report(small_run):
    out, events, report = small_run
    assert events[0]["kind"] == "started" and events[0]["seed"] == 1
    attempts = [e for e in events if e["kind"] == "attempt"]
    assert [e["index"] for e in attempts] == [0, 1, 2, 3]
    assert report["attempts"] == 4
    assert report["successes"] == sum(e["success"] for e in attempts) == attempts[-1]["stats"]["successes"]
    assert Path(report["output"]) == out and out.is_file()


def test_a_dataset_reads_as_numpy_arrays(small_run):
    out, _, report = small_run
    ds = mg.Dataset(out)
    assert len(ds) == report["successes"] and ds.demo_names[0] == "demo_0"
    demo = ds.demo("demo_0")
    actions = demo["actions"]
    assert isinstance(actions, np.ndarray) and actions.dtype == np.float64 and actions.shape[1] == 7
    assert demo["obs/robot0_eef_pos"].shape == (actions.shape[0], 3)
    info = ds.datagen_info("demo_0")
    assert info["eef_pose"].shape == (actions.shape[0], 4, 4)
    assert set(info["object_poses"]) == {"cubeA", "cubeB"}
    assert np.allclose(info["eef_pose"][:, 3], [0, 0, 0, 1])
    assert "Stack" in ds.env_args


def test_the_same_seed_gives_the_same_dataset(small_run, tmp_path):
    out, _, _ = small_run
    again = tmp_path / "again.hdf5"
    mg.generate(again, num_demos=4, seed=1, workers=1, keep_failed=True).wait()
    same_datasets(out, again)


def test_errors_are_mimicgen_errors_naming_the_file_and_field(tmp_path):
    with pytest.raises(mg.MimicgenError, match="missing.hdf5"):
        mg.Dataset(tmp_path / "missing.hdf5")
    with pytest.raises(mg.MimicgenError, match="missing_source.hdf5: source: no such file"):
        mg.generate(tmp_path / "o.hdf5", source=tmp_path / "missing_source.hdf5").wait()
    # A run's fields are named as Python names them, never by the CLI's flags.
    with pytest.raises(mg.MimicgenError, match=r'spec\["action_noise"\]: names subtask 7') as err:
        mg.generate(tmp_path / "o.hdf5", num_demos=1, spec={"action_noise": {7: 0.1}}).wait()
    assert "--" not in str(err.value)
    with pytest.raises(mg.MimicgenError, match="unknown field"):
        mg.generate(tmp_path / "o.hdf5", spec={"noise": 0.1})


def test_planned_transit_in_clutter_is_a_spec_field(tmp_path):
    report = mg.generate(tmp_path / "c0.hdf5", task="stack", variant="C0", num_demos=2, workers=1, spec={"transit": "plan"}).wait()
    assert report["transit"]["planned"] >= 2 and report["spec_overrides"]["transit"][0]["value"] == "plan"
    with pytest.raises(mg.MimicgenError, match="interpolate"):
        mg.generate(tmp_path / "o.hdf5", num_demos=1, spec={"transit": "teleport"}).wait()


def test_an_existing_output_is_refused_in_pythons_words_and_keeps_its_bytes(small_run, tmp_path):
    out, _, _ = small_run
    before = out.read_bytes()
    with pytest.raises(mg.MimicgenError, match="exists; pass overwrite=True to replace it") as err:
        mg.generate(out, num_demos=1).wait()
    assert "--overwrite" not in str(err.value)
    assert out.read_bytes() == before
    lerobot = tmp_path / "lerobot"
    lerobot.mkdir()
    (lerobot / "mine.txt").write_text("mine")
    with pytest.raises(mg.MimicgenError, match="lerobot: exists; pass overwrite=True"):
        mg.export_lerobot(out, lerobot)
    assert (lerobot / "mine.txt").read_text() == "mine"


def test_specs_load_edit_and_check(tmp_path):
    spec = mg.Spec.bundled("stack")
    d = spec.to_dict()
    assert [s["object_ref"] for s in d["subtask"]] == ["cubeA", "cubeB"]
    d["subtask"][0]["action_noise"] = 0.02
    edited = mg.Spec.from_dict(d)
    assert "action_noise = 0.02" in edited.to_toml()
    edited.save(tmp_path / "spec.toml")
    assert mg.Spec.load(tmp_path / "spec.toml").to_dict() == edited.to_dict()
    d["subtask"][0]["object_ref"] = None
    with pytest.raises(mg.MimicgenError):
        mg.Spec.from_dict(d)


def test_proposed_ends_are_written_where_mimicgen_reads_them(tmp_path):
    proposals = mg.propose_subtask_ends(FIXTURE)
    assert len(proposals) == len(mg.Dataset(FIXTURE))
    ends = {demo: [p["end"] for p in ps] for demo, ps in proposals.items()}
    assert all(len(e) == 1 for e in ends.values())
    out = tmp_path / "annotated.hdf5"
    mg.write_subtask_ends(FIXTURE, out, ends)
    ds = mg.Dataset(out)
    for demo, (end,) in ends.items():
        grasp = ds.datagen_info(demo)["subtask_term_signals"]["grasp"]
        # MimicGen's convention: the signal turns on at the subtask's last step (end - 1), and a
        # segment ends one step after its signal turns on.
        assert grasp[end - 2] == 0 and grasp[end - 1] == 1


def test_coverage_is_the_clis(small_run):
    out, _, report = small_run
    c = mg.coverage(out)
    assert (c["task"], c["variant"], c["bins"]) == ("stack", "D0", 3)
    assert c["scenes"] == report["successes"]
    assert 0 < c["support_coverage"] <= 1 and c["joint_bins_hit"] <= c["scenes"]


def test_shards_merged_equal_the_single_run(small_run, tmp_path):
    out, _, report = small_run
    shards = []
    for part in range(2):
        path = tmp_path / f"s{part}.hdf5"
        mg.generate(path, num_demos=4, seed=1, keep_failed=True, shard=(part, 2)).wait()
        shards.append(path)
    merged = mg.merge(shards, tmp_path / "merged.hdf5")
    same_datasets(out, tmp_path / "merged.hdf5")
    assert (merged["attempts"], merged["successes"]) == (report["attempts"], report["successes"])


def test_ctrl_c_cancels_and_leaves_a_valid_dataset(tmp_path):
    out = tmp_path / "long.hdf5"
    run = mg.generate(out, num_demos=500, seed=2, workers=1)
    # Ctrl-C from another thread once two attempts are in, so that it lands while the main
    # thread waits in the run's Rust code for the next event.
    seen = 0
    with pytest.raises(KeyboardInterrupt):
        for event in run:
            seen += event["kind"] == "attempt"
            if seen == 2:
                threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGINT)).start()
    report = run.report
    assert report["cancelled"] and 2 <= report["attempts"] < 500
    assert len(mg.Dataset(out)) == report["successes"]


def test_ctrl_c_in_the_loop_body_cancels_the_run_too(tmp_path):
    out = tmp_path / "body.hdf5"
    run = mg.generate(out, num_demos=500, seed=2, workers=1)
    seen = 0
    with pytest.raises(KeyboardInterrupt):
        for event in run:
            seen += event["kind"] == "attempt"
            if seen == 2:
                os.kill(os.getpid(), signal.SIGINT)  # lands here, in Python, not in the run's Rust code
    assert run.report["cancelled"] and 2 <= run.report["attempts"] < 500
    assert len(mg.Dataset(out)) == run.report["successes"]


def test_a_python_simulator_drives_the_rust_engine(tmp_path):
    first, second = tmp_path / "py1.hdf5", tmp_path / "py2.hdf5"
    report = mg.generate(first, env=KinematicStack, num_demos=8, seed=3, keep_failed=True).wait()
    assert report["attempts"] == 8
    assert report["successes"] >= 5, report
    ds = mg.Dataset(first)
    demo = ds.demo("demo_0")
    steps = demo["actions"].shape[0]
    # Observations come from the environment's observations(), per stored state.
    assert demo["obs/robot0_eef_pos"].shape == (steps, 3) and demo["obs/object"].shape == (steps, 6)
    assert np.allclose(demo["obs/robot0_eef_pos"], ds.datagen_info("demo_0")["eef_pose"][:, :3, 3])
    # Seeded: the same run again is the same dataset.
    mg.generate(second, env=KinematicStack, num_demos=8, seed=3, keep_failed=True).wait()
    same_datasets(first, second)


class NeverStacked(KinematicStack):
    """Never achieves the task, and says which part of it is unmet."""

    def is_success(self):
        return False

    def unmet_success(self):
        return "cube A on cube B"


def test_a_python_simulator_names_what_is_unmet_in_the_report(tmp_path):
    run = mg.generate(tmp_path / "never.hdf5", env=NeverStacked, num_demos=4, seed=3)
    causes = [e["cause"] for e in run if e["kind"] == "attempt"]
    report = run.wait()
    assert report["successes"] == 0
    reasons = {f["reason"] for f in report["failures"]}
    assert "task not achieved: cube A on cube B failed" in reasons, report
    # Every attempt's event carries its cause; the report counts them by subtask.
    assert causes == [{"kind": "success_unmet", "clause": "cube A on cube B"}] * 4, causes
    assert report["causes"] == [{"subtask": 1, "cause": "success_unmet", "count": 4}], report


def test_a_python_simulator_error_ends_the_run_with_its_message(tmp_path):
    class Broken(KinematicStack):
        def step(self, action):
            raise RuntimeError("the arm fell off")

    with pytest.raises(mg.MimicgenError, match="the arm fell off"):
        mg.generate(tmp_path / "b.hdf5", env=Broken, num_demos=2).wait()


def test_another_arm_from_the_same_source_demos(tmp_path):
    import json

    out = tmp_path / "sawyer.hdf5"
    report = mg.generate(out, robot="sawyer", num_demos=3, seed=1).wait()
    assert report["successes"] >= 2
    assert json.loads(mg.Dataset(out).env_args)["env_kwargs"]["robots"] == ["Sawyer"]
    with pytest.raises(mg.MimicgenError, match="baxter"):
        mg.generate(tmp_path / "b.hdf5", robot="baxter", num_demos=1).wait()


def test_tasks_list_the_task_files_and_a_new_task_generates(tmp_path):
    listed = mg.tasks()
    names = [t["name"] for t in listed["tasks"]]
    assert {"stack", "threading", "coffee", "three_piece_assembly", "pick_place"} <= set(names)
    coffee = next(t for t in listed["tasks"] if t["name"] == "coffee")
    assert coffee["env_name"] == "Coffee" and coffee["variants"] == ["D0", "D1", "D2"] and coffee["objects"] == ["coffee_pod", "coffee_machine"]
    assert [r["name"] for r in listed["robots"]] == ["panda", "sawyer", "iiwa", "ur5e"]
    # A generated Threading dataset names robosuite's environment for its variant.
    import json

    out = tmp_path / "threading.hdf5"
    report = mg.generate(out, task="threading", variant="D1", num_demos=4, seed=1).wait()
    assert report["attempts"] >= 4
    assert json.loads(mg.Dataset(out).env_args)["env_name"] == "Threading_D1"


def test_cameras_and_a_lerobot_export_that_pyarrow_reads(tmp_path):
    import pyarrow.parquet as pq

    out = tmp_path / "cams.hdf5"
    report = mg.generate(out, num_demos=2, guarantee=True, seed=1, cameras=True, camera_size=(32, 48)).wait()
    assert report["successes"] == 2
    ds = mg.Dataset(out)
    demo = ds.demo("demo_0")
    steps = demo["actions"].shape[0]
    for camera in ("agentview", "robot0_eye_in_hand"):
        image = demo[f"obs/{camera}_image"]
        assert image.dtype == np.uint8 and image.shape == (steps, 32, 48, 3)
        assert image.std() > 5, f"{camera} rendered a flat image"
    summary = mg.export_lerobot(out, tmp_path / "lerobot")
    assert summary["episodes"] == 2 and summary["videos"] == ["observation.images.agentview", "observation.images.robot0_eye_in_hand"]
    table = pq.read_table(tmp_path / "lerobot/data/chunk-000/file-000.parquet")
    assert table.num_rows == summary["frames"] == sum(ds.demo(n)["actions"].shape[0] for n in ds.demo_names)
    actions = np.asarray(table.column("action").to_pylist(), dtype=np.float32)
    assert np.array_equal(actions[0], demo["actions"][0].astype(np.float32))
    assert table.column("episode_index").to_pylist()[steps] == 1
    with pytest.raises(mg.MimicgenError, match="obs/nope"):
        mg.export_lerobot(out, tmp_path / "other", state_keys=["nope"])


def test_a_two_arm_task_generates_with_the_same_call(tmp_path):
    """`task="two_arm_handover"`: both arms' actions in one row, events and the report as for one
    arm, subtasks numbered through both arms; what two-arm runs lack is refused by name."""
    out = tmp_path / "handover.hdf5"
    run = mg.generate(out, task="two_arm_handover", num_demos=4, seed=1, workers=2)
    events = list(run)
    report = run.wait()
    assert events[0]["kind"] == "started" and events[0]["task"] == "two_arm_handover"
    attempts = [e for e in events if e["kind"] == "attempt"]
    assert [e["index"] for e in attempts] == [0, 1, 2, 3]
    assert report["attempts"] == 4 and report["successes"] == sum(e["success"] for e in attempts)
    assert len(report["per_subtask_source"]) == max(len(e["sources"]) for e in attempts)
    for e in attempts:
        if e["failure"] is not None:
            assert e["failure"]["arm"] in (0, 1, None) and e["failure"]["reason"]
    ds = mg.Dataset(out)
    assert len(ds) == report["successes"]
    if len(ds):
        assert ds.demo("demo_0")["actions"].shape[1] == 14
    with pytest.raises(mg.MimicgenError, match="keep_failed"):
        mg.generate(tmp_path / "kept.hdf5", task="two_arm_lift", keep_failed=True).wait()
