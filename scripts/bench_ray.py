"""Attempts per second of one run made four ways on this machine: the pipeline in one process
with 1 and 2 worker threads (what `mimicgen generate --workers N` does), and as 1 and 2 Ray tasks
(mimicgen_rs.ray.generate on a local cluster of 2 CPUs), plus Ray's overhead per shard (wall time
beyond the slowest shard's own run and the merge). Run in a venv with the wheel and ray:

    python scripts/bench_ray.py --attempts 60
"""

import argparse
import json
import os
import subprocess
import tempfile
import time

import mimicgen_rs as mg
import mimicgen_rs.ray as mgray


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--attempts", type=int, default=60)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--cli", help="the mimicgen binary, to time `mimicgen generate --workers 1/2` on the same run too")
    args = p.parse_args()
    import ray

    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for workers in (1, 2):
            started = time.perf_counter()
            r = mg.generate(os.path.join(tmp, f"threads{workers}.hdf5"), num_demos=args.attempts, seed=args.seed, workers=workers).wait()
            wall = time.perf_counter() - started
            rows[f"process, {workers} thread(s)"] = {"wall_s": round(wall, 2), "attempts_per_s": round(r["attempts"] / wall, 2)}
        for workers in (1, 2) if args.cli else ():
            out = os.path.join(tmp, f"cli{workers}.hdf5")
            started = time.perf_counter()
            subprocess.run([args.cli, "generate", "--num-demos", str(args.attempts), "--seed", str(args.seed), "--workers", str(workers), "--out", out],
                           check=True, capture_output=True)
            wall = time.perf_counter() - started
            rows[f"CLI, {workers} thread(s)"] = {"wall_s": round(wall, 2), "attempts_per_s": round(args.attempts / wall, 2)}
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        for shards in (1, 2):
            started = time.perf_counter()
            r = mgray.generate(os.path.join(tmp, f"ray{shards}.hdf5"), shards=shards, num_demos=args.attempts, seed=args.seed, progress=False)
            wall = time.perf_counter() - started
            rows[f"ray, {shards} task(s)"] = {
                "wall_s": round(wall, 2),
                "attempts_per_s": round(r["attempts"] / wall, 2),
                "slowest_shard_s": round(r["wall_time_s"], 2),
                "overhead_per_shard_s": round((wall - r["wall_time_s"]) / shards, 2),
            }
        ray.shutdown()
    base = rows["process, 1 thread(s)"]["attempts_per_s"]
    for row in rows.values():
        row["vs_1_thread"] = round(row["attempts_per_s"] / base, 2)
    print(json.dumps({"attempts": args.attempts, "cpus": os.cpu_count(), "runs": rows}, indent=1))


if __name__ == "__main__":
    main()
