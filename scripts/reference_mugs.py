#!/usr/bin/env python3
"""Measure the reference's ShapeNet mugs (NVlabs/mimicgen's Mug Cleanup and Coffee Preparation).

Our mugs are primitive copies of them (core/sim/tasks/mug_cleanup.task.toml); this prints, for each
mug at the scale the reference loads it, the numbers those copies take, measured from the mug's
collision hulls (collision/*.obj, times the mesh scale 0.15 and the object scale):

  base_m          the centre of the mug's base in the mug's frame (the mesh's origin, which is the
                  frame robosuite and the reference's env interface report)
  handle_yaw_deg  the direction of its handle in that frame (deg about z from +x)
  height_m        base to rim
  radius_m        the cup's outer radius (the 60th percentile of the vertices' distance from its axis)

Usage (the reference's sources, e.g. from `git archive` of NVlabs/mimicgen 72bd767):

  python3 scripts/reference_mugs.py /path/to/mimicgen/mimicgen/models/robosuite/assets/shapenet_core/mugs

Needs numpy.
"""

import argparse
import glob
import math
import os
import sys

# The reference's mugs and scales (mimicgen/envs/robosuite/mug_cleanup.py:665-678, in its order)
# with our labels (mug_cleanup.task.toml's instances); Coffee Preparation's mug is 3143a4ac at 1.0.
MUGS = [
    ("3143a4ac", 0.8, "beige_round"),
    ("34ae0b61", 0.8, "bronze_slim"),
    ("128ecbc1", 2 / 3, "light_blue_thick"),
    ("d75af64a", 2 / 3, "off_white_tall"),
    ("5fe74bab", 0.8, "brown_thin"),
    ("345d3e72", 2 / 3, "black_low"),
    ("48e260a6", 2 / 3, "red_round"),
    ("8012f52d", 0.8, "yellow_wide"),
    ("b4ae56d6", 0.8, "yellow_slim"),
    ("c2eacc52", 0.8, "wooden"),
    ("e94e46bc", 0.8, "dark_blue"),
    ("fad118b3", 2 / 3, "tall_green"),
    ("3143a4ac", 1.0, "coffee_preparation"),
]
MESH_SCALE = 0.15
# A vertex this far beyond the cup's radius belongs to the handle (m).
HANDLE_MARGIN_M = 0.006


def vertices(folder, np):
    rows = []
    for path in sorted(glob.glob(os.path.join(folder, "collision", "*.obj"))):
        with open(path) as f:
            rows.extend([float(t) for t in line.split()[1:4]] for line in f if line.startswith("v "))
    if not rows:
        sys.exit(f"{folder}: no collision/*.obj vertices")
    return np.array(rows)


def measure(v, np):
    z0, z1 = v[:, 2].min(), v[:, 2].max()
    bottom = v[v[:, 2] < z0 + 0.004, :2]
    axis = (bottom.min(0) + bottom.max(0)) / 2
    distance = np.linalg.norm(v[:, :2] - axis, axis=1)
    radius = np.percentile(distance, 60)
    handle = (v[distance > radius + HANDLE_MARGIN_M, :2] - axis).mean(0)
    return {
        "base_m": [round(float(axis[0]), 4), round(float(axis[1]), 4), round(float(z0), 4)],
        "handle_yaw_deg": round(math.degrees(math.atan2(handle[1], handle[0])), 1),
        "height_m": round(float(z1 - z0), 4),
        "radius_m": round(float(radius), 4),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mugs", help="the reference's shapenet_core/mugs folder")
    args = parser.parse_args()
    try:
        import numpy as np
    except ImportError:
        print(f"numpy is missing from {sys.executable}", file=sys.stderr)
        sys.exit(2)
    print(f"{'label':<20} {'mug':<9} {'scale':>6}  base_m (x, y, z)              handle_yaw_deg  height_m  radius_m")
    for mug, scale, label in MUGS:
        m = measure(vertices(os.path.join(args.mugs, mug), np) * MESH_SCALE * scale, np)
        base = ", ".join(f"{c:+.4f}" for c in m["base_m"])
        print(f"{label:<20} {mug:<9} {scale:6.4f}  [{base}]  {m['handle_yaw_deg']:+14.1f}  {m['height_m']:8.4f}  {m['radius_m']:8.4f}")


if __name__ == "__main__":
    main()
