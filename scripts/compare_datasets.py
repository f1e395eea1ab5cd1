#!/usr/bin/env python3
"""Compare the demos of two generated datasets by the attempt they came from.

Usage: compare_datasets.py A.hdf5 B.hdf5 [--json]

Demos are matched by their `mimicgen_attempt` attribute (the attempt index in the run), and every
dataset under each matched demo (actions, states, obs/*, datagen_info/*, ...) is compared bit for
bit, with the demo's attributes. Prints the attempts only in A, only in B, and the matched demos
that differ. Exit status 0 when both hold the same attempts with identical arrays, 1 otherwise.
Used by BENCHMARKS.md (early abort against the default, a resumed run against an uninterrupted one).
"""
import argparse
import json
import sys

import h5py
import numpy as np


def by_attempt(f):
    out = {}
    for name, g in f["data"].items():
        if "mimicgen_attempt" not in g.attrs:
            sys.exit(f"{f.filename}: data/{name} has no mimicgen_attempt attribute")
        out[int(g.attrs["mimicgen_attempt"])] = g
    return out


def same(a, b):
    if set(a.attrs) != set(b.attrs):
        return False
    for k in a.attrs:
        if k == "mimicgen_attempt":
            continue
        if not np.array_equal(np.asarray(a.attrs[k]), np.asarray(b.attrs[k])):
            return False
    if isinstance(a, h5py.Dataset):
        return isinstance(b, h5py.Dataset) and a.shape == b.shape and a[()].tobytes() == b[()].tobytes()
    return set(a.keys()) == set(b.keys()) and all(same(a[k], b[k]) for k in a)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with h5py.File(args.a, "r") as fa, h5py.File(args.b, "r") as fb:
        a, b = by_attempt(fa), by_attempt(fb)
        common = sorted(set(a) & set(b))
        result = {
            "demos_a": len(a),
            "demos_b": len(b),
            "only_in_a": sorted(set(a) - set(b)),
            "only_in_b": sorted(set(b) - set(a)),
            "matched": len(common),
            "matched_but_different": [k for k in common if not same(a[k], b[k])],
        }
    identical = not (result["only_in_a"] or result["only_in_b"] or result["matched_but_different"])
    result["identical"] = identical
    if args.json:
        print(json.dumps(result))
    else:
        print(f"A: {result['demos_a']} demos, B: {result['demos_b']} demos, {result['matched']} from the same attempts")
        print(f"attempts only in A: {result['only_in_a']}")
        print(f"attempts only in B: {result['only_in_b']}")
        print(f"same attempt, different arrays: {result['matched_but_different']}")
        print("identical" if identical else "different")
    sys.exit(0 if identical else 1)


if __name__ == "__main__":
    main()
