#!/usr/bin/env python3
"""Load a `mimicgen export --lerobot` directory with LeRobot's own dataset class and check it
against the robomimic dataset it came from.

Usage: check_lerobot.py HDF5 LEROBOT_DIR [--json]

Checks, with LeRobot's `LeRobotDataset` (the `lerobot` package, which reads subtasks; else the
standalone `lerobot-dataset`, module `ledataset`, which does not): frame and episode counts;
episode boundaries (`dataset_from_index`/`dataset_to_index` against each demo's length); that the
first and last action of every episode equal the HDF5's (to float32); every checked frame's task
(the instruction); with subtasks, every frame's `subtask` against the one MimicGen's segmentation
gives from the HDF5's `datagen_info/subtask_term_signals` (a subtask "X until SIGNAL" ends one
step after SIGNAL first turns on); and, for each camera, that the decoded first and last frame of
every episode match the HDF5's image (mean absolute error on the 0-255 scale; H.264 is lossy).
pyarrow reads the parquet files directly too.

Exit status: 0 all checks pass, 1 a check fails, 2 bad input.
Needs the environment made by scripts/setup_learners.sh.
"""

from __future__ import annotations

import argparse
import json
import sys


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("hdf5")
    ap.add_argument("root")
    ap.add_argument("--max-image-mae", type=float, default=6.0, help="largest mean abs error (0-255) of a decoded frame")
    ap.add_argument("--require-subtasks", action="store_true",
                    help="fail unless the loader returns a subtask for every frame (lerobot, an export of demos with signals)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    import h5py
    import numpy as np
    import pyarrow.parquet as pq

    try:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
        import lerobot
        loader = f"lerobot {lerobot.__version__}" if hasattr(lerobot, "__version__") else "lerobot"
    except ImportError:
        from ledataset.datasets.lerobot_dataset import LeRobotDataset
        loader = "lerobot-dataset (ledataset)"

    failures = []

    def check(ok, what):
        if not ok:
            failures.append(what)
            print(f"FAIL {what}", file=sys.stderr)

    ds = LeRobotDataset("local/mimicgen", root=args.root, video_backend="pyav")
    with h5py.File(args.hdf5, "r") as f:
        names = sorted(f["data"].keys(), key=lambda n: int(n.split("_")[1]))
        lengths = [int(f["data"][n]["actions"].shape[0]) for n in names]
        check(ds.num_episodes == len(names), f"episodes: LeRobot {ds.num_episodes}, HDF5 {len(names)}")
        check(ds.num_frames == sum(lengths), f"frames: LeRobot {ds.num_frames}, HDF5 {sum(lengths)}")
        episodes = ds.meta.episodes
        cameras = [k for k in ds.meta.video_keys]
        image_errors = {c: [] for c in cameras}
        subtasks = getattr(ds.meta, "subtasks", None)
        subtasks = [str(t) for t in subtasks.index] if subtasks is not None and "subtask_index" in ds.features else []
        subtask_frames = 0
        if subtasks:
            data = pq.read_table(f"{args.root}/data/chunk-000/file-000.parquet", columns=["subtask_index"])
            frame_subtasks = data.column("subtask_index").to_pylist()
        start = 0
        for i, (name, n) in enumerate(zip(names, lengths)):
            ep = episodes[i]
            check((ep["dataset_from_index"], ep["dataset_to_index"]) == (start, start + n),
                  f"episode {i} spans {ep['dataset_from_index']}..{ep['dataset_to_index']}, expected {start}..{start + n}")
            actions = np.asarray(f["data"][name]["actions"][()], dtype=np.float32)
            for at, frame in ((0, ds[start]), (n - 1, ds[start + n - 1])):
                check(int(frame["episode_index"]) == i and int(frame["frame_index"]) == at,
                      f"frame {start + at}: episode {int(frame['episode_index'])} step {int(frame['frame_index'])}, expected {i} step {at}")
                check(np.array_equal(frame["action"].numpy(), actions[at]), f"{name} action[{at}] differs")
                check(frame["task"] == ds.meta.tasks.index[0], f"frame {start + at}: task {frame['task']!r}")
                for c in cameras:
                    ours = np.asarray(f["data"][name]["obs"][c.split(".")[-1] + "_image"][at], dtype=np.float64)
                    theirs = frame[c].numpy().transpose(1, 2, 0) * 255.0
                    image_errors[c].append(float(np.abs(ours - theirs).mean()))
            if subtasks:
                # Every frame's index from the parquet; LeRobot's own `subtask` at each boundary.
                expected = expected_subtasks(f["data"][name], subtasks, n)
                got = frame_subtasks[start:start + n]
                wrong = [t for t in range(n) if got[t] != expected[t]]
                check(not wrong, f"{name}: subtask_index {got[wrong[0]] if wrong else ''} at step "
                                 f"{wrong[0] if wrong else ''}, expected {expected[wrong[0]] if wrong else ''}")
                subtask_frames += n - len(wrong)
                for t in [0] + [t for t in range(1, n) if expected[t] != expected[t - 1]] + [n - 1]:
                    theirs = ds[start + t]["subtask"]
                    check(theirs == subtasks[expected[t]], f"{name} step {t}: LeRobot's subtask {theirs!r}, expected {subtasks[expected[t]]!r}")
            start += n
    check(subtasks or not args.require_subtasks, f"{loader}: no subtasks (subtask_index and meta/subtasks.parquet) to check")
    table = pq.read_table(f"{args.root}/data/chunk-000/file-000.parquet")
    check("observation.state" in table.column_names and "action" in table.column_names, f"parquet columns {table.column_names}")
    for c, errs in image_errors.items():
        check(max(errs) <= args.max_image_mae, f"{c}: decoded frames differ by up to {max(errs):.2f} / 255")
    summary = {
        "loader": loader,
        "episodes": ds.num_episodes,
        "frames": ds.num_frames,
        "task": str(ds.meta.tasks.index[0]),
        "subtasks": subtasks,
        "subtask_frames": subtask_frames,
        "cameras": {c: {"max_mae": max(e), "mean_mae": sum(e) / len(e)} for c, e in image_errors.items()},
        "failures": failures,
    }
    out = sys.stdout
    if args.json:
        print(json.dumps(summary), file=out)
    else:
        print(f"{loader}: {ds.num_episodes} episodes, {ds.num_frames} frames, task {summary['task']!r}; "
              f"first/last actions equal; episode boundaries match", file=out)
        if subtasks:
            print(f"  subtask of all {subtask_frames} frames as the HDF5's signals cut them: {subtasks}", file=out)
        for c, e in summary["cameras"].items():
            print(f"  {c}: decoded first/last frames differ from the HDF5 by {e['mean_mae']:.2f} / 255 on average "
                  f"(max {e['max_mae']:.2f})", file=out)
    return 1 if failures else 0


def expected_subtasks(demo, subtasks, n):
    """The subtask of each of the demo's n steps: "X until SIGNAL" ends one step after SIGNAL's
    first 0 -> 1 step at or after the subtask's start (MimicGen's segmentation); the last runs on."""
    import numpy as np

    labels, start = [], 0
    for i, text in enumerate(subtasks):
        end = n
        if i < len(subtasks) - 1 and " until " in text:
            signal = np.asarray(demo["datagen_info"]["subtask_term_signals"][text.split(" until ", 1)[1]][()])
            rising = [t for t in range(max(start, 1), n) if signal[t - 1] == 0 and signal[t] != 0]
            end = rising[0] + 1 if rising else n
        end = max(end, start)
        labels += [i] * (end - start)
        start = end
        if start >= n:
            break
    return labels + [len(subtasks) - 1] * (n - len(labels))


if __name__ == "__main__":
    sys.exit(main())
