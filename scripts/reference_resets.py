#!/usr/bin/env python3
"""Print where the reference MimicGen's own environment puts its objects after each reset.

For checking a task's reset distribution against ours (docs/fidelity.md): for each of N resets of
ENV (a reference environment such as HammerCleanup_D1), every object its env interface reports
(`get_object_poses`, the names our task files use), as position and the world directions of the
object's x, y and z axes.

  PYTHONPATH=<NVlabs/mimicgen>:<robosuite-task-zoo>:<six> MUJOCO_GL=disable \\
    python scripts/reference_resets.py HammerCleanup_D1 --num 12 --seed 0

Needs what scripts/reference_replay.py needs (see its --help). robosuite's resets draw from
numpy's global generator, seeded here with --seed.
"""

import argparse
import os
import sys

os.environ.setdefault("MUJOCO_GL", "disable")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import reference_replay  # noqa: E402  (the reference's env and env interface, built the same way)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("env", help="a reference environment, e.g. HammerCleanup_D1")
    p.add_argument("--num", type=int, default=10, help="resets (default 10)")
    p.add_argument("--seed", type=int, default=0, help="numpy's global seed (default 0)")
    p.add_argument("--object", help="only this object (an env-interface name, e.g. hammer)")
    args = p.parse_args()
    import numpy as np
    ref = reference_replay.Reference(args.env)
    np.random.seed(args.seed)
    for k in range(args.num):
        ref.env.reset()
        for name, pose in ref.iface.get_object_poses().items():
            if args.object and name != args.object:
                continue
            axes = " ".join(f"{a}=({pose[0, i]:+.3f},{pose[1, i]:+.3f},{pose[2, i]:+.3f})" for i, a in enumerate("xyz"))
            print(f"reset {k} {name} pos=({pose[0, 3]:+.4f},{pose[1, 3]:+.4f},{pose[2, 3]:+.4f}) {axes}")


if __name__ == "__main__":
    main()
