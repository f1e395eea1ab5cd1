#!/usr/bin/env python3
"""Load a `mimicgen export --lerobot` directory with LeRobot's own dataset class and check it
against the robomimic dataset it came from.

Usage: check_lerobot.py HDF5 LEROBOT_DIR [--json]

Checks, with `LeRobotDataset` (the standalone `lerobot-dataset` package, module `ledataset`, or
`lerobot` when that is what is installed): frame and episode counts; episode boundaries
(`dataset_from_index`/`dataset_to_index` against each demo's length); that the first and last
action of every episode equal the HDF5's (to float32); the task string; and, for each camera,
that the decoded first and last frame of every episode match the HDF5's image (mean absolute
error on the 0-255 scale; H.264 is lossy). pyarrow reads the parquet files directly too.

Exit status: 0 all checks pass, 1 a check fails, 2 bad input.
Needs the environment made by scripts/setup_lerobot.sh.
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
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    import h5py
    import numpy as np
    import pyarrow.parquet as pq

    try:
        from ledataset.datasets.lerobot_dataset import LeRobotDataset
        loader = "lerobot-dataset (ledataset)"
    except ImportError:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
        loader = "lerobot"

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
            start += n
    table = pq.read_table(f"{args.root}/data/chunk-000/file-000.parquet")
    check("observation.state" in table.column_names and "action" in table.column_names, f"parquet columns {table.column_names}")
    for c, errs in image_errors.items():
        check(max(errs) <= args.max_image_mae, f"{c}: decoded frames differ by up to {max(errs):.2f} / 255")
    summary = {
        "loader": loader,
        "episodes": ds.num_episodes,
        "frames": ds.num_frames,
        "task": str(ds.meta.tasks.index[0]),
        "cameras": {c: {"max_mae": max(e), "mean_mae": sum(e) / len(e)} for c, e in image_errors.items()},
        "failures": failures,
    }
    out = sys.stdout
    if args.json:
        print(json.dumps(summary), file=out)
    else:
        print(f"{loader}: {ds.num_episodes} episodes, {ds.num_frames} frames, task {summary['task']!r}; "
              f"first/last actions equal; episode boundaries match", file=out)
        for c, e in summary["cameras"].items():
            print(f"  {c}: decoded first/last frames differ from the HDF5 by {e['mean_mae']:.2f} / 255 on average "
                  f"(max {e['max_mae']:.2f})", file=out)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
