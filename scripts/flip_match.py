#!/usr/bin/env python3
"""Success by whether an attempt's object lies the same way up as in its source demo.

robosuite turns Hammer Cleanup's hammer 180 deg about its handle at half the resets. A source
demo's grasp, transformed to a hammer lying the other way up, comes at it from below. This
counts, for every generated attempt (a dataset and, from --keep-failed, its failed one), whether
the object's z axis pointed the same way (up or down) at the start as in the source demo the
attempt was made from (the first entry of its src_demo_inds: the first subtask's source, the
same for every subtask unless --select-src-per-subtask), and how many of each kind succeeded.

  python scripts/flip_match.py SOURCE.hdf5 OUT.hdf5 OUT_failed.hdf5 [--object hammer]

Needs h5py (the project's venv: $MIMICGEN_CACHE/venv/bin/python).
"""
import argparse

import h5py


def upside_down(world_from_object):
    return bool(world_from_object[2, 2] < 0)


def demos(f):
    return sorted(f["data"].keys(), key=lambda k: int(k.split("_")[1]))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("source")
    parser.add_argument("generated", nargs="+", help="the run's dataset, then its _failed dataset")
    parser.add_argument("--object", default="hammer")
    args = parser.parse_args()
    with h5py.File(args.source, "r") as src:
        source_flip = [upside_down(src["data"][d]["datagen_info"]["object_poses"][args.object][0]) for d in demos(src)]
    counts = {"same": [0, 0], "other": [0, 0]}
    for path in args.generated:
        with h5py.File(path, "r") as f:
            for d in demos(f):
                g = f["data"][d]
                source = int(g["src_demo_inds"][0])
                kind = "same" if upside_down(g["datagen_info"]["object_poses"][args.object][0]) == source_flip[source] else "other"
                succeeded = not path.endswith("_failed.hdf5")
                counts[kind][0] += int(succeeded)
                counts[kind][1] += 1
    print(f"source demos upside down: {sum(source_flip)} of {len(source_flip)}")
    for kind, (ok, n) in counts.items():
        print(f"{kind} way up as the source: {ok} of {n} succeeded")


if __name__ == "__main__":
    main()
