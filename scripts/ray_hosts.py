"""The driver of scripts/test_ray_hosts.sh, run on the head of a two-node Ray cluster (the head
and one worker node, 1 CPU each, in separate network and mount namespaces). Not for direct use:
the shell script makes the cluster and passes the addresses and the command that kills the
worker node.

Test (default): the single-process run, then the same run as Ray shards, placed by the test rather
than by Ray's scheduler (mimicgen_rs.ray.generate's shard_options): shards 0 and 1 on the worker
node (soft node affinity: a retry goes elsewhere once that node is dead), the rest on the head. Of
the two on the worker node, the first to start runs through and comes back; the second makes its
files and then holds them until the node is lost (the workers' set-up hook asks a log actor which
one it is), so the --kill command (SIGKILL to the node's every process; with its link cut first
when --loss is "vanished") always lands while a shard of that node is running and after one came
back from it, whatever order Ray starts them in and however fast the machine is. The merged
dataset must equal the single-process one (demo names, every array, the failed attempts' file
too), both nodes' files must be in it, and the held shard must have been made again on the head.

--bench: attempts/s of one run made as 1, 2, 4 and 8 shards (and in one process on the head),
with the wall time beyond the shards' own run times.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
import ray
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

import mimicgen_rs as mg
import mimicgen_rs.ray as mgray

LOG_ACTOR = "mimicgen_shard_log"


def say(message):
    print(f"ray_hosts: {message}", file=sys.stderr, flush=True)


class Tee:
    """sys.stderr that also keeps mimicgen_rs.ray's progress lines, to know when a shard came back
    from a node."""

    def __init__(self, inner):
        self.inner = inner
        self.lines = []

    def write(self, text):
        self.lines.extend(text.splitlines())
        return self.inner.write(text)

    def flush(self):
        self.inner.flush()


@ray.remote(num_cpus=0)
class ShardLog:
    """Where each try of a shard started, finished or held its files (node address, time), as the
    workers' set-up hook reports them."""

    def __init__(self):
        self.events = []

    def start(self, part, node):
        """Logs a try's start; returns how many tries started on that node before it (the
        actor's calls run one at a time, so each try on a node gets its own number)."""
        before = sum(1 for event, _, n, _ in self.events if event == "started" and n == node)
        self.events.append(("started", part, node, time.time()))
        return before

    def add(self, event, part, node):
        self.events.append((event, part, node, time.time()))

    def get(self):
        return list(self.events)


def log_shards():
    """Worker set-up hook (sent to the nodes by value): wraps mgray._run_shard, as
    app/python/tests/crash_once.py does, to report each try's start and end to the ShardLog. On
    the node named by $MG_HOLD_NODE, the second try to start holds its finished files instead of
    returning them, until its node is killed (bounded, so a test that never kills it fails)."""
    import os as os_
    import time as time_

    import ray as ray_
    import mimicgen_rs.ray as mgray_

    original = mgray_._run_shard

    def run_shard(part, count, kwargs):
        shard_log = ray_.get_actor(LOG_ACTOR)
        node = ray_.util.get_node_ip_address()
        ordinal = ray_.get(shard_log.start.remote(part, node))
        result = original(part, count, kwargs)
        if node == os_.environ.get("MG_HOLD_NODE") and ordinal == 1:
            ray_.get(shard_log.add.remote("held", part, node))
            deadline = time_.monotonic() + float(os_.environ["MG_HOLD_S"])
            while time_.monotonic() < deadline:
                time_.sleep(0.1)
            raise RuntimeError(f"shard {part} held its files on {node} for {os_.environ['MG_HOLD_S']} s and its node was never lost")
        # Not waited for: a task blocked in ray.get lends its CPU to another task.
        shard_log.add.remote("finished", part, node)
        return result

    mgray_._run_shard = run_shard


def connect(address, runtime_env=None):
    started = time.monotonic()
    ray.init(address=address, log_to_driver=False, runtime_env=runtime_env)
    while len([n for n in ray.nodes() if n["Alive"]]) < 2:
        if time.monotonic() - started > 120:
            raise SystemExit(f"ray_hosts: FAILED: the worker node did not join in 120 s: {ray.nodes()}")
        time.sleep(0.2)
    nodes = sorted(n["NodeManagerAddress"] for n in ray.nodes() if n["Alive"])
    say(f"cluster up in {time.monotonic() - started:.1f} s: nodes {nodes}, {ray.cluster_resources().get('CPU')} CPUs")
    return nodes


def node_id(ip):
    return next(n["NodeID"] for n in ray.nodes() if n["Alive"] and n["NodeManagerAddress"] == ip)


def same_datasets(path_a, path_b):
    """Demo names and every array equal; returns the number of demos compared."""
    a, b = mg.Dataset(path_a), mg.Dataset(path_b)
    assert a.demo_names == b.demo_names, f"{path_b}: demos {b.demo_names}, want {a.demo_names}"
    for name in a.demo_names:
        xa, xb = a.demo(name), b.demo(name)
        assert sorted(xa) == sorted(xb), f"{name}: keys {sorted(xb)}, want {sorted(xa)}"
        for key in xa:
            assert np.array_equal(np.asarray(xa[key]), np.asarray(xb[key])), f"{path_b}: {name}/{key} differs"
    return len(a.demo_names)


def test(args):
    began = time.monotonic()
    env = {"MG_HOLD_NODE": args.worker_ip, "MG_HOLD_S": str(args.hold_s)}
    connect(args.address, runtime_env={"worker_process_setup_hook": log_shards, "env_vars": env})
    head, worker = node_id(args.head_ip), node_id(args.worker_ip)
    shard_log = ShardLog.options(name=LOG_ACTOR, scheduling_strategy=NodeAffinitySchedulingStrategy(head, soft=False)).remote()
    ray.get(shard_log.get.remote())
    with tempfile.TemporaryDirectory(prefix="ray_hosts_") as tmp:
        single = os.path.join(tmp, "single.hdf5")
        started = time.monotonic()
        want = mg.generate(single, num_demos=args.demos, seed=args.seed, keep_failed=True).wait()
        say(f"single process: {want['attempts']} attempts, {want['successes']} successes in {time.monotonic() - started:.1f} s")

        tee = Tee(sys.stderr)
        killed = {}

        def killer():
            try:
                kill_worker_node()
            except Exception as e:  # reported by the main thread
                killed["error"] = repr(e)

        def kill_worker_node():
            # Kill once a shard's files came back from the worker node and the other shard there
            # holds its own: both are events, so the kill lands inside that shard on any machine.
            while "part" not in killed and not stop.is_set():
                came_back = any(re.search(rf" done on {re.escape(args.worker_ip)} ", line) for line in tee.lines)
                events = ray.get(shard_log.get.remote())
                held = [part for event, part, node, _ in events if event == "held" and node == args.worker_ip]
                if came_back and held:
                    subprocess.run(args.kill, shell=True, check=True)
                    killed.update(part=held[0], at=time.time())
                    say(f"worker node {args.worker_ip} {args.loss} while shard {held[0]} ran there")
                    while any(n["Alive"] and n["NodeManagerAddress"] == args.worker_ip for n in ray.nodes()):
                        time.sleep(0.05)
                    killed["dead_at"] = time.time()
                    return
                time.sleep(0.02)

        def placed(part):
            # Shards 0 and 1 on the worker node, softly (once it is dead, their retries run on the
            # head); the rest on the head.
            if part < 2:
                return {"scheduling_strategy": NodeAffinitySchedulingStrategy(worker, soft=True)}
            return {"scheduling_strategy": NodeAffinitySchedulingStrategy(head, soft=False)}

        stop = threading.Event()
        thread = threading.Thread(target=killer, daemon=True)
        thread.start()
        out = os.path.join(tmp, "ray.hdf5")
        sys.stderr = tee
        started = time.monotonic()
        try:
            got = mgray.generate(out, shards=args.shards, num_demos=args.demos, seed=args.seed, keep_failed=True, max_retries=2, shard_options=placed)
            ray_s = time.monotonic() - started
        finally:
            sys.stderr = tee.inner
            stop.set()
            thread.join()
        events = ray.get(shard_log.get.remote())
        say(f"Ray, {args.shards} shards: {got['attempts']} attempts in {ray_s:.1f} s; shards' files from {[s['node'] for s in got['shards']]}")
        timeline = [(at, f"shard {part} {event} on {node}") for event, part, node, at in events]
        if "at" in killed:
            timeline.append((killed["at"], f"worker node {args.worker_ip} {args.loss}"))
        if "dead_at" in killed:
            timeline.append((killed["dead_at"], f"worker node {args.worker_ip} seen dead by the driver (ray.nodes())"))
        for at, what in sorted(timeline):
            say(f"  +{at - events[0][3]:.2f} s  {what}")

        assert "error" not in killed, f"killing the worker node: {killed.get('error')}"
        assert "part" in killed, "the worker node was never killed: no shard came back from it, or none held its files there"
        part = killed["part"]
        assert got["shards"][part]["node"] == args.head_ip, f"killed shard {part}: files from {got['shards'][part]['node']}, want the head {args.head_ip}"
        assert ("finished", part, args.worker_ip) not in {(e, p, n) for e, p, n, _ in events}, f"shard {part} finished on the worker node before the kill landed"
        again = [at for event, p, node, at in events if event == "started" and p == part and node == args.head_ip]
        assert again, f"shard {part} was not started again on the head"
        nodes = {s["node"] for s in got["shards"]}
        assert nodes == {args.head_ip, args.worker_ip}, f"shards' files came from {nodes}, want both nodes"
        key = ("attempts", "successes", "per_source_demo")
        assert [got[k] for k in key] == [want[k] for k in key], f"report {[got[k] for k in key]}, want {[want[k] for k in key]}"
        demos = same_datasets(single, out)
        assert want["attempts"] > want["successes"], "the run has no failed attempt: pick a seed that has some"
        failed = same_datasets(single.replace(".hdf5", "_failed.hdf5"), out.replace(".hdf5", "_failed.hdf5"))
        assert not os.path.exists(os.path.join(tmp, ".ray.hdf5.shards"))
        say(f"the worker node ({args.loss}) was seen dead {killed['dead_at'] - killed['at']:.2f} s later; shard {part} was made again on the head {again[0] - killed['at']:.2f} s after the loss")
        say(f"merged dataset equals the single-process one: {demos} demos and {failed} failed attempts, every array")
    say(f"test passed ({args.loss}) in {time.monotonic() - began:.1f} s (driver)")


def bench(args):
    nodes = connect(args.address)
    rows = {}
    with tempfile.TemporaryDirectory(prefix="ray_hosts_") as tmp:
        # Warm-up: each node's worker process imports the package once, as a long run would.
        mgray.generate(os.path.join(tmp, "warm.hdf5"), shards=2, num_demos=2, seed=args.seed, progress=False)
        started = time.perf_counter()
        r = mg.generate(os.path.join(tmp, "single.hdf5"), num_demos=args.attempts, seed=args.seed, workers=1).wait()
        wall = time.perf_counter() - started
        rows["one process on the head, 1 thread"] = {"wall_s": round(wall, 2), "attempts_per_s": round(r["attempts"] / wall, 2)}
        for shards in (1, 2, 4, 8):
            started = time.perf_counter()
            r = mgray.generate(os.path.join(tmp, f"ray{shards}.hdf5"), shards=shards, num_demos=args.attempts, seed=args.seed, progress=False)
            wall = time.perf_counter() - started
            per_node = {n: sum(s["wall_time_s"] for s in r["shards"] if s["node"] == n) for n in nodes}
            busiest = max(per_node.values())
            rows[f"Ray, {shards} shard(s)"] = {
                "wall_s": round(wall, 2),
                "attempts_per_s": round(r["attempts"] / wall, 2),
                "shards_per_node": {n: sum(1 for s in r["shards"] if s["node"] == n) for n in nodes},
                "slowest_shard_s": round(r["wall_time_s"], 2),
                "overhead_per_shard_s": round((wall - r["wall_time_s"]) / shards, 2),
                "busiest_node_shards_s": round(busiest, 2),
                "beyond_busiest_node_s": round(wall - busiest, 2),
            }
    base = rows["one process on the head, 1 thread"]["attempts_per_s"]
    for row in rows.values():
        row["vs_1_process"] = round(row["attempts_per_s"] / base, 2)
    print(json.dumps({"attempts": args.attempts, "seed": args.seed, "nodes": nodes, "runs": rows}, indent=1))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--address", required=True, help="the head's GCS, host:port")
    p.add_argument("--head-ip", required=True)
    p.add_argument("--worker-ip", required=True)
    p.add_argument("--kill", required=True, help="shell command that kills every process of the worker node")
    p.add_argument("--loss", default="killed", help="test: how the --kill command loses the node, for the messages")
    p.add_argument("--bench", action="store_true")
    p.add_argument("--demos", type=int, default=16, help="test: attempts of the run")
    p.add_argument("--shards", type=int, default=8, help="test: shards of the run (at least 3: two on the worker node, the rest on the head)")
    p.add_argument("--attempts", type=int, default=48, help="bench: attempts of the run")
    p.add_argument("--hold-s", type=float, default=240, help="test: how long the worker node's second shard holds its files before it gives up on the kill and fails")
    p.add_argument("--seed", type=int, default=1, help="the run's seed (1: some of the test's attempts fail)")
    args = p.parse_args()
    if args.bench:
        bench(args)
    elif args.shards < 3:
        p.error("--shards: the test needs at least 3 (two on the worker node, one or more on the head)")
    else:
        test(args)


if __name__ == "__main__":
    main()
