"""Shards as Ray tasks on a local cluster: the merged dataset equals the single-process run's,
also when a task's worker is killed and Ray retries it."""

import os
from pathlib import Path

import numpy as np
import pytest
import ray

import mimicgen_rs as mg
import mimicgen_rs.ray as mgray


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    crash_dir = tmp_path_factory.mktemp("crash")
    # The workers run this test's hook (crash_once.py, beside this file) before any task: the
    # product's code has no test switch.
    tests = str(Path(__file__).resolve().parent)
    path = os.pathsep.join(p for p in [tests, os.environ.get("PYTHONPATH", "")] if p)
    runtime_env = {"env_vars": {"CRASH_ONCE_DIR": str(crash_dir), "PYTHONPATH": path}, "worker_process_setup_hook": "crash_once.install"}
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env=runtime_env)
    yield crash_dir
    ray.shutdown()


def test_ray_shards_give_the_single_process_dataset_even_after_a_retry(cluster, tmp_path):
    single = tmp_path / "single.hdf5"
    want = mg.generate(single, num_demos=6, seed=5, keep_failed=True).wait()
    out = tmp_path / "ray.hdf5"
    got = mgray.generate(out, shards=2, num_demos=6, seed=5, keep_failed=True, max_retries=2)
    assert (cluster / "crashed_once").exists(), "shard 0's first try was killed"
    assert (got["attempts"], got["successes"], got["per_source_demo"]) == (want["attempts"], want["successes"], want["per_source_demo"])
    a, b = mg.Dataset(single), mg.Dataset(out)
    assert a.demo_names == b.demo_names
    for name in a.demo_names:
        xa, xb = a.demo(name), b.demo(name)
        assert all(np.array_equal(np.asarray(xa[k]), np.asarray(xb[k])) for k in xa), name
    for suffix in ("_failed.hdf5",):
        fa, fb = mg.Dataset(str(single).replace(".hdf5", suffix)), mg.Dataset(str(out).replace(".hdf5", suffix))
        assert fa.demo_names == fb.demo_names
    assert not Path(tmp_path / ".ray.hdf5.shards").exists()


def test_shard_options_place_shards_but_leave_cpus_and_retries_to_generate(cluster, tmp_path):
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    node = ray.get_runtime_context().get_node_id()
    placed = []

    def on_this_node(part):
        placed.append(part)
        return {"scheduling_strategy": NodeAffinitySchedulingStrategy(node, soft=False)}

    got = mgray.generate(tmp_path / "placed.hdf5", shards=2, num_demos=2, seed=5, shard_options=on_this_node, progress=False)
    assert placed == [0, 1] and got["attempts"] == 2
    with pytest.raises(mg.MimicgenError, match=r"shard_options\(0\): num_cpus"):
        mgray.generate(tmp_path / "cpus.hdf5", shards=2, num_demos=2, seed=5, shard_options=lambda part: {"num_cpus": 2})
