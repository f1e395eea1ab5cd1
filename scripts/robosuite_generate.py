"""Generation through our engine driving robosuite 1.4.1's own Stack environment (MuJoCo 2.3.2),
from the reference's source demos and config, with the time split between the engine and
robosuite. Run in the robosuite venv with the wheel installed (scripts/bench_robosuite.sh):

    python scripts/robosuite_generate.py --num 50 --seed 1 --out /tmp/rs_stack.hdf5
"""

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "disable")

import mimicgen_rs as mg  # noqa: E402
import mimicgen_rs.robosuite as mgrs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "core/io/tests/data/source_D0_prepared.hdf5"
CONFIG = ROOT / "core/engine/tests/data/config_D0.json"


class Timed(mgrs.RobosuiteEnv):
    """Counts the time spent in robosuite (every call the engine makes into Python)."""

    spent = 0.0
    depth = 0  # calls from one method into another count once

    def __getattribute__(self, name):
        attr = object.__getattribute__(self, name)
        if name.startswith("_") or name in ("env", "objects", "signals", "site", "max_dpos", "max_drot") or not callable(attr):
            return attr

        def timed(*args, **kwargs):
            started = time.perf_counter()
            Timed.depth += 1
            try:
                return attr(*args, **kwargs)
            finally:
                Timed.depth -= 1
                if Timed.depth == 0:
                    Timed.spent += time.perf_counter() - started

        return timed


# Where each variant places the cubes around the table's centre (m): robosuite's Stack is D0;
# D1 is MimicGen's wider square, as our task file `core/sim/tasks/stack.task.toml` places it.
PLACEMENT = {"D0": 0.08, "D1": 0.2}


def maker(variant):
    def make():
        import numpy as np
        from robosuite.utils.placement_samplers import UniformRandomSampler

        half = PLACEMENT[variant]
        sampler = UniformRandomSampler(
            name="ObjectSampler", x_range=[-half, half], y_range=[-half, half], rotation=None,
            ensure_object_boundary_in_range=False, ensure_valid_placement=True,
            reference_pos=np.array((0, 0, 0.8)), z_offset=0.01,
        )
        base = mgrs.stack(placement_initializer=sampler)
        return Timed(base.env, base.objects, base.signals)

    return make


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num", type=int, default=50, help="attempts")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--variant", choices=sorted(PLACEMENT), default="D0", help="where the cubes are placed (D1: a 0.4 m square)")
    p.add_argument("--out", default="/tmp/rs_stack.hdf5")
    p.add_argument("--min-success", type=int, default=0, help="fail (exit 1) below this many successes")
    args = p.parse_args()
    started = time.perf_counter()
    report = mg.generate(args.out, env=maker(args.variant), source=SOURCE, config=CONFIG, num_demos=args.num, seed=args.seed,
                         overwrite=True).wait()
    wall = time.perf_counter() - started
    summary = {
        "attempts": report["attempts"],
        "successes": report["successes"],
        "generation_rate": report["generation_rate"],
        "wall_s": round(wall, 1),
        "robosuite_s": round(Timed.spent, 1),
        "engine_share": round(1 - Timed.spent / wall, 3),
        "variant": args.variant,
        "reference_rate": 0.96 if args.variant == "D0" else None,
    }
    print(json.dumps(summary, indent=1))
    if report["successes"] < args.min_success:
        raise SystemExit(f"{report['successes']} successes, fewer than --min-success {args.min_success}")


if __name__ == "__main__":
    main()
