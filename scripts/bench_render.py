#!/usr/bin/env python3
"""Milliseconds per camera frame: robosuite 1.4.1 against ours, the same states, one run.

Usage: bench_render.py --cli PATH/TO/mimicgen [--rounds 3] [--json]

Makes one Stack D0 demo (`mimicgen generate --num-demos 1 --guarantee --seed 1`), then, in
alternating rounds, renders every stored state of it from agentview and the wrist camera at
84 x 84 (robosuite's 4x multisampling) in robosuite's own environment (built from the file's
env_args and model_file, `sim.render` per camera, as robosuite makes camera observations) and in
ours (`mimicgen bench-render`, which also times the ways in between and checks their pixels).
Prints per round robosuite's and our milliseconds per frame and their ratio, and the median.

Run with the robosuite environment (scripts/setup_robosuite.sh):
  ~/.cache/mimicgen/venv-robosuite/bin/python scripts/bench_render.py --cli target/release/mimicgen
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import robosuite_replay as replay  # noqa: E402  (sets MUJOCO_GL=disable; rendering wants EGL)

os.environ["MUJOCO_GL"] = "egl"
os.environ["PYOPENGL_PLATFORM"] = "egl"

CAMERAS = ["agentview", "robot0_eye_in_hand"]


def robosuite_ms_per_frame(env, states, size):
    """Every state from every camera, `sim.render` as robosuite's observables call it."""
    import numpy as np

    for c in CAMERAS:  # the first frame makes the context
        env.sim.render(camera_name=c, width=size, height=size)
    spent = 0.0
    for state in states:
        env.sim.set_state_from_flattened(state)
        env.sim.forward()
        for c in CAMERAS:
            started = time.perf_counter()
            np.asarray(env.sim.render(camera_name=c, width=size, height=size))
            spent += time.perf_counter() - started
    return spent * 1e3 / (len(states) * len(CAMERAS))


def ours(cli, path, size):
    out = subprocess.run([cli, "bench-render", path, "--rounds", "1", "--size", str(size), "--cameras", ",".join(CAMERAS)],
                         check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", required=True, help="the mimicgen binary")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--size", type=int, default=84)
    ap.add_argument("--json", action="store_true", help="also print every figure as JSON")
    args = ap.parse_args(argv)
    replay.ensure_robosuite()
    import h5py
    import numpy as np

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "one.hdf5")
        subprocess.run([args.cli, "generate", "--num-demos", "1", "--guarantee", "--seed", "1", "--out", path],
                       check=True, capture_output=True)
        with h5py.File(path, "r") as f:
            env_args = replay.read_env_args(f, path)
            grp = f["data/demo_0"]
            xml = grp.attrs["model_file"]
            xml = xml.decode("utf-8") if isinstance(xml, bytes) else str(xml)
            states = np.asarray(grp["states"][()], dtype=np.float64)
        env, _, _ = replay.make_env(env_args, path, render=True)
        env.reset()
        env.reset_from_xml_string(env.edit_model_xml(xml))
        env.sim.reset()
        rounds = []
        for r in range(args.rounds):
            theirs = robosuite_ms_per_frame(env, states, args.size)
            mine = ours(args.cli, path, args.size)
            ways = {name: w["ms_per_frame"] for name, w in mine["ways"].items()}
            rounds.append({"robosuite": theirs, "ours": ways, "threads": mine["threads"], "vs_mujoco": {n: w["vs_mujoco"] for n, w in mine["ways"].items()}})
            print(f"round {r + 1}: robosuite {theirs:6.2f} ms/frame | ours: " + ", ".join(f"{n} {ms:6.2f}" for n, ms in ways.items())
                  + f" | ours (default) {theirs / ways['default']:.2f}x faster; 2 threads {mine['threads']['speedup_2_vs_1']:.2f}x one", flush=True)
    med = lambda xs: statistics.median(xs)  # noqa: E731
    summary = {
        "states": len(states),
        "lp_num_threads": os.environ.get("LP_NUM_THREADS"),
        "robosuite_ms_per_frame": med([r["robosuite"] for r in rounds]),
        "ours_ms_per_frame": {n: med([r["ours"][n] for r in rounds]) for n in rounds[0]["ours"]},
        "ratio_robosuite_over_ours_default": med([r["robosuite"] / r["ours"]["default"] for r in rounds]),
        "ratio_robosuite_over_ours_mujoco": med([r["robosuite"] / r["ours"]["mujoco"] for r in rounds]),
        "ratio_robosuite_over_ours_reflection": med([r["robosuite"] / r["ours"]["reflection"] for r in rounds]),
        "speedup_2_threads": med([r["threads"]["speedup_2_vs_1"] for r in rounds]),
        "pixels_vs_mujoco": rounds[0]["vs_mujoco"],
    }
    print(f"median of {args.rounds} rounds ({len(states)} states x {len(CAMERAS)} cameras, {args.size}x{args.size}): robosuite "
          f"{summary['robosuite_ms_per_frame']:.2f} ms/frame, ours {summary['ours_ms_per_frame']['default']:.2f} "
          f"({summary['ratio_robosuite_over_ours_default']:.2f}x faster; with the floor's reflection "
          f"{summary['ratio_robosuite_over_ours_reflection']:.2f}x; MuJoCo's way {summary['ratio_robosuite_over_ours_mujoco']:.2f}x)")
    if args.json:
        print(json.dumps({"summary": summary, "rounds": rounds}, indent=1))
    sys.stdout.flush()
    # robosuite's EGL context raises while the interpreter tears down; leave without it.
    os._exit(0)


if __name__ == "__main__":
    sys.exit(main())
