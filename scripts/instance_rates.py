#!/usr/bin/env python3
"""Generation rate per object instance of an object-transfer run (Mug Cleanup O2).

Reads a dataset written with `--keep-failed` and its `_failed` file beside it; each demo names
its instance in the `mimicgen_object_instance` attribute. For every failure to be counted, the
run's spec must keep them all (`max_num_failures` at least the attempts), e.g.:

    sed 's/^max_num_failures = 50/max_num_failures = 100000/' core/sim/tasks/mug_cleanup.toml > all.toml
    mimicgen generate --task mug_cleanup --variant O2 --config all.toml --num-demos 240 --seed 7 \\
        --keep-failed --out o2.hdf5
    python3 scripts/instance_rates.py o2.hdf5

Prints a Markdown table: instance, successes / attempts, rate, and the failures by subtask.
"""
import collections
import pathlib
import sys

import h5py


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    kept = pathlib.Path(sys.argv[1])
    failed = kept.with_name(kept.stem + "_failed" + kept.suffix)
    if not failed.exists():
        print(f"{failed}: missing; run generate with --keep-failed", file=sys.stderr)
        return 1
    ok, bad = collections.Counter(), collections.Counter()
    why = collections.defaultdict(collections.Counter)
    for path, counts in ((kept, ok), (failed, bad)):
        with h5py.File(path, "r") as f:
            for name in f["data"]:
                attrs = f["data"][name].attrs
                label = attrs.get("mimicgen_object_instance")
                if label is None:
                    print(f"{path}: data/{name} has no mimicgen_object_instance", file=sys.stderr)
                    return 1
                counts[label] += 1
                if counts is bad:
                    why[label][str(attrs.get("mimicgen_failure", "?")).split(":")[0]] += 1
    print("| instance | successes / attempts | rate | failures by subtask |")
    print("|---|---|---|---|")
    for label in sorted(set(ok) | set(bad)):
        n = ok[label] + bad[label]
        failures = ", ".join(f"{k}: {v}" for k, v in sorted(why[label].items()))
        print(f"| {label} | {ok[label]} / {n} | {100 * ok[label] / n:.0f} % | {failures} |")
    total = sum(ok.values()) + sum(bad.values())
    print(f"| all | {sum(ok.values())} / {total} | {100 * sum(ok.values()) / total:.1f} % | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
