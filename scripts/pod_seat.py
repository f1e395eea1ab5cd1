#!/usr/bin/env python3
"""Where the pod ended in each attempt of a Coffee or Coffee Preparation run: its offset from the
holder's axis, its height over the holder's centre and its tilt, at the attempt's last step.

  python scripts/pod_seat.py OUT_failed.hdf5 [--holder 0 0.1061 0.0635]

--holder is the cup's centre in the machine's frame: Coffee's (the default) or Coffee
Preparation's (0 0 0.097). A seated pod is at +7 mm, upright, within 0.7 mm of the axis. Needs
h5py and numpy (the project's venv: $MIMICGEN_CACHE/venv/bin/python).
"""
import argparse

import h5py
import numpy as np


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataset")
    parser.add_argument("--holder", type=float, nargs=3, default=[0.0, 0.1061, 0.0635])
    args = parser.parse_args()
    kinds = {"below the cup (not taken yet, never lifted, or dropped)": [], "on the cup's rim (over 35 mm)": [],
             "wedged in the cup's mouth (10 to 35 mm)": [], "down in the cup (under 10 mm)": []}
    with h5py.File(args.dataset, "r") as f:
        for name in f["data"]:
            poses = f["data"][name]["datagen_info"]["object_poses"]
            pod, machine = poses["coffee_pod"][-1], poses["coffee_machine"][-1]
            offset = (np.linalg.inv(machine) @ pod)[:3, 3] - np.array(args.holder)
            off_axis_mm = 1000 * float(np.hypot(offset[0], offset[1]))
            height_mm = 1000 * float(offset[2])
            tilt_deg = float(np.degrees(np.arccos(np.clip(pod[2, 2], -1.0, 1.0))))
            if height_mm < -40:
                kind = "below the cup (not taken yet, never lifted, or dropped)"
            elif height_mm > 35:
                kind = "on the cup's rim (over 35 mm)"
            elif height_mm > 10:
                kind = "wedged in the cup's mouth (10 to 35 mm)"
            else:
                kind = "down in the cup (under 10 mm)"
            kinds[kind].append((off_axis_mm, height_mm, tilt_deg))
    for kind, rows in kinds.items():
        if not rows:
            print(f"{kind}: 0")
            continue
        off, height, tilt = (np.median([r[i] for r in rows]) for i in range(3))
        print(f"{kind}: {len(rows)} (median {off:.1f} mm off the axis, {height:.1f} mm up, tilted {tilt:.1f} deg)")


if __name__ == "__main__":
    main()
