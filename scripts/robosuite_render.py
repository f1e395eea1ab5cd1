#!/usr/bin/env python3
"""Render a dataset's stored states in robosuite itself and compare with the dataset's images.

Usage: robosuite_render.py DATASET [--demo demo_0] [--frames 3] [--min-psnr DB] [--save DIR] [--json]

For the demo's first, last and evenly spaced frames in between, this builds robosuite 1.4.1's own
environment from the file's `env_args`, loads the demo's `model_file`, restores the stored state
and renders every camera the dataset has (`obs/<camera>_image`) at the dataset's size, flipped
upright as robomimic stores it. It prints, per camera, the mean absolute error (0-255 scale) and
PSNR (dB) between our image and robosuite's, over those frames. With --save DIR it writes, per
camera and frame, a PNG of ours | robosuite's | 4x the absolute difference.

Exit status: 0 ok, 1 a camera's PSNR below --min-psnr, 2 bad input (no images, no model_file...).

Needs the environment made by scripts/setup_robosuite.sh (robosuite 1.4.1, mujoco 2.3.2, PyOpenGL)
and EGL (Debian's libegl1, libegl-mesa0, libgl1-mesa-dri; scripts/setup.sh installs them).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import robosuite_replay as replay  # noqa: E402  (sets MUJOCO_GL=disable; rendering wants EGL)

os.environ["MUJOCO_GL"] = "egl"
os.environ["PYOPENGL_PLATFORM"] = "egl"


def compare(ours, theirs):
    import numpy as np

    diff = np.abs(ours.astype(np.float64) - theirs.astype(np.float64))
    mse = float((diff ** 2).mean())
    psnr = math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)
    return float(diff.mean()), psnr, mse


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--demo", default="demo_0")
    ap.add_argument("--frames", type=int, default=3, help="frames compared: first, last and evenly spaced between")
    ap.add_argument("--min-psnr", type=float, default=None, help="exit 1 if a camera's PSNR is below this (dB)")
    ap.add_argument("--save", default=None, help="write ours | robosuite | 4x difference PNGs here")
    ap.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    args = ap.parse_args(argv)
    path = args.dataset
    if not os.path.isfile(path):
        print(f"robosuite_render: {path}: no such file", file=sys.stderr)
        return 2
    replay.ensure_robosuite()
    import h5py
    import numpy as np

    with h5py.File(path, "r") as f:
        try:
            env_args = replay.read_env_args(f, path)
        except replay.BadInput as e:
            print(f"robosuite_render: {e}", file=sys.stderr)
            return 2
        grp = f.get(f"data/{args.demo}")
        if grp is None or "obs" not in grp or "states" not in grp:
            print(f"robosuite_render: {path}: data/{args.demo} has no obs or states", file=sys.stderr)
            return 2
        cameras = sorted(k[: -len("_image")] for k in grp["obs"] if k.endswith("_image"))
        if not cameras:
            print(f"robosuite_render: {path}: data/{args.demo}/obs has no <camera>_image (generate with --cameras)", file=sys.stderr)
            return 2
        xml = grp.attrs.get("model_file")
        if xml is None:
            print(f"robosuite_render: {path}: data/{args.demo} has no attribute 'model_file'", file=sys.stderr)
            return 2
        xml = xml.decode("utf-8") if isinstance(xml, bytes) else str(xml)
        states = np.asarray(grp["states"][()], dtype=np.float64)
        n = len(states)
        frames = sorted({round(i * (n - 1) / max(args.frames - 1, 1)) for i in range(args.frames)})
        images = {c: np.asarray(grp["obs"][f"{c}_image"][frames]) for c in cameras}

    env, _, _ = replay.make_env(env_args, path, render=True)
    env.reset()
    env.reset_from_xml_string(env.edit_model_xml(xml))
    env.sim.reset()
    results = {}
    for c in cameras:
        h, w = images[c].shape[1:3]
        errs = []
        for i, t in enumerate(frames):
            env.sim.set_state_from_flattened(states[t])
            env.sim.forward()
            theirs = np.asarray(env.sim.render(camera_name=c, width=w, height=h))[::-1]
            ours = images[c][i]
            errs.append(compare(ours, theirs))
            if args.save:
                from PIL import Image

                os.makedirs(args.save, exist_ok=True)
                diff = np.clip(np.abs(ours.astype(np.int16) - theirs.astype(np.int16)) * 4, 0, 255).astype(np.uint8)
                Image.fromarray(np.concatenate([ours, theirs, diff], axis=1)).save(os.path.join(args.save, f"{c}_{t}.png"))
        mse = sum(e[2] for e in errs) / len(errs)
        results[c] = {
            "mae": sum(e[0] for e in errs) / len(errs),
            "psnr_db": math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse),
            "frames": frames,
            "size": [int(h), int(w)],
        }
        print(f"{c}: {h}x{w}, frames {frames}: mean abs error {results[c]['mae']:.2f} / 255, PSNR {results[c]['psnr_db']:.1f} dB",
              file=sys.stderr if args.json else sys.stdout)
    if args.json:
        print(json.dumps({"dataset": path, "demo": args.demo, "cameras": results}))
    sys.stdout.flush()
    bad = [c for c, r in results.items() if args.min_psnr is not None and r["psnr_db"] < args.min_psnr]
    if bad:
        print(f"robosuite_render: PSNR below {args.min_psnr} dB for {', '.join(bad)}", file=sys.stderr)
    # robosuite's EGL context raises while the interpreter tears down; leave without it.
    os._exit(1 if bad else 0)


if __name__ == "__main__":
    sys.exit(main())
