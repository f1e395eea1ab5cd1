"""Spread a run over a Ray cluster: one Ray task per shard, retried if its worker dies, the
outputs gathered to the driver and merged into the dataset one process makes with the same seed.

    import ray, mimicgen_rs.ray
    ray.init()                                   # or ray.init(address="auto") on a cluster
    report = mimicgen_rs.ray.generate("stack.hdf5", shards=8, num_demos=1000, seed=7)

On a multi-node cluster: every node needs the wheel installed (``pip install mimicgen_rs-*.whl``,
or ``ray.init(runtime_env={"pip": [...]})``) and the ``source`` file (when given) at the same
path; the shards' files come back to the driver through Ray's object store, so no shared file
system is needed, and the driver writes the merged dataset. A shard whose machine dies silently
is retried once the driver's gRPC keepalive gives up on it: set
``RAY_grpc_client_keepalive_time_ms`` and ``RAY_grpc_client_keepalive_timeout_ms`` for the
driver and the nodes (Ray's defaults add up to 7 minutes; scripts/test_ray_hosts.sh tests this
across two hosts).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from typing import Any, Callable, Dict, List, Optional

import mimicgen_rs

def _run_shard(part: int, count: int, kwargs: Dict[str, Any]) -> Dict[str, Any]:
    """Runs one shard in a scratch directory; returns its files by name (``files``), the address
    of the node it ran on (``node``) and the shard's own run time (``wall_time_s``)."""
    import ray

    with tempfile.TemporaryDirectory(prefix=f"mimicgen_shard{part}_") as scratch:
        out = os.path.join(scratch, f"shard_{part}.hdf5")
        report = mimicgen_rs.generate(out, shard=(part, count), overwrite=True, **kwargs).wait()
        files = {}
        for name in os.listdir(scratch):
            with open(os.path.join(scratch, name), "rb") as f:
                files[name] = f.read()
        return {"files": files, "node": ray.util.get_node_ip_address(), "wall_time_s": report["wall_time_s"]}


def generate(
    out: str,
    *,
    shards: int,
    overwrite: bool = False,
    max_retries: int = 3,
    progress: bool = True,
    shard_options: Optional[Callable[[int], Dict[str, Any]]] = None,
    **kwargs: Any,
) -> Dict[str, Any]:
    """Run ``mimicgen_rs.generate(out, **kwargs)`` as ``shards`` Ray tasks and merge them.

    Each task makes shard ``i/shards`` with 1 worker thread (Ray schedules one per CPU); a task
    whose worker dies is retried up to ``max_retries`` times, from scratch, which gives the same
    files. Returns the merged run's report (the same counts as a single process's), plus
    ``shards``: by shard, the address of the node whose try made its files (``node``) and that
    try's own run time (``wall_time_s``).

    ``shard_options(i)``, when given, returns Ray task options for shard ``i`` (those of
    ``.options()``: ``scheduling_strategy``, ``resources``, ...), e.g. to keep shards on the nodes
    that hold a large ``source`` file:

        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy
        near = lambda i: {"scheduling_strategy": NodeAffinitySchedulingStrategy(node_ids[i % 2], soft=True)}
        mimicgen_rs.ray.generate("out.hdf5", shards=8, num_demos=1000, shard_options=near)

    With ``soft=True`` a shard whose node dies is retried on another; with ``soft=False`` the retry
    waits for that node (and fails if it is gone). ``num_cpus`` and ``max_retries`` are set here.
    """
    import ray

    if shards < 1:
        raise mimicgen_rs.MimicgenError(f"shards: must be at least 1, got {shards}")
    if "shard" in kwargs or "out" in kwargs:
        raise mimicgen_rs.MimicgenError("shard/out: mimicgen_rs.ray.generate makes the shards itself")
    kwargs.setdefault("workers", 1)
    for key in ("source", "config"):
        if kwargs.get(key) is not None:
            kwargs[key] = os.path.abspath(os.fspath(kwargs[key]))
    task = ray.remote(max_retries=max_retries, num_cpus=1)(_run_shard)
    pending = {}
    for i in range(shards):
        options = dict(shard_options(i)) if shard_options is not None else {}
        for key in ("num_cpus", "max_retries"):
            if key in options:
                raise mimicgen_rs.MimicgenError(f"shard_options({i}): {key} is set by mimicgen_rs.ray.generate (max_retries: its own argument)")
        pending[(task.options(**options) if options else task).remote(i, shards, kwargs)] = i
    started = time.monotonic()
    results: Dict[int, Dict[str, Any]] = {}
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            part = pending.pop(ref)
            results[part] = ray.get(ref)
            if progress:
                print(f"mimicgen_rs.ray: shard {part}/{shards} done on {results[part]['node']} ({len(results)} of {shards}, {time.monotonic() - started:.1f} s)", file=sys.stderr)
    gathered = os.path.join(os.path.dirname(os.path.abspath(out)) or ".", f".{os.path.basename(out)}.shards")
    os.makedirs(gathered, exist_ok=True)
    paths: List[str] = []
    for part in range(shards):
        for name, data in results[part]["files"].items():
            with open(os.path.join(gathered, name), "wb") as f:
                f.write(data)
        paths.append(os.path.join(gathered, f"shard_{part}.hdf5"))
    report = mimicgen_rs.merge(paths, out, overwrite=overwrite)
    for name in os.listdir(gathered):
        os.remove(os.path.join(gathered, name))
    os.rmdir(gathered)
    report["shards"] = [{"node": results[part]["node"], "wall_time_s": results[part]["wall_time_s"]} for part in range(shards)]
    return report


def available() -> Optional[str]:
    """Ray's version when it is installed, else ``None``."""
    try:
        import ray
    except ImportError:
        return None
    return str(ray.__version__)
