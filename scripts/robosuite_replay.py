#!/usr/bin/env python3
"""Replay a robomimic-layout dataset's demos in robosuite itself and count task successes.

Usage: robosuite_replay.py DATASET [--num N] [--min-success K] [--json]

For each of the first N demos (data/demo_0, data/demo_1, ... in numeric order) this builds
robosuite's own environment from the file's `data` attr `env_args`, loads the demo's `model_file`
(asset paths re-pointed by the env's `edit_model_xml`), restores the first stored state, steps the
stored actions open loop, and records whether `env._check_success()` held at any step and at the
end, and where the replay parted from the stored states: the first step at which some joint's
position (an arm's joint, a gripper finger, an object's free joint) differed from the stored one by
more than 1 mm (or mrad), 5 mm and 2 cm, and which joint. It prints one line per demo and
`robosuite replay: K of N succeeded`.

Exit status: 0 ok, 1 fewer than --min-success demos succeeded, 2 bad input (missing file, group,
attribute or dataset, or an env_args that robosuite cannot use).

Needs the environment made by scripts/setup_robosuite.sh (robosuite 1.4.1, mujoco 2.3.2, h5py);
run with any other interpreter, it re-executes itself with that environment's python if it exists.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import re
import sys
import time

# Nothing here renders: keep robosuite/mujoco from loading any GL context.
os.environ["MUJOCO_GL"] = "disable"

CACHE = os.environ.get("MIMICGEN_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "mimicgen"))
VENV_PYTHON = os.path.join(CACHE, "venv-robosuite", "bin", "python")


class BadInput(Exception):
    """A problem with the dataset itself (exit status 2)."""


def ensure_robosuite():
    try:
        import robosuite  # noqa: F401
        import h5py  # noqa: F401
    except ImportError as e:
        venv = os.path.dirname(os.path.dirname(VENV_PYTHON))
        if os.path.exists(VENV_PYTHON) and os.path.realpath(sys.prefix) != os.path.realpath(venv) \
                and not os.environ.get("ROBOSUITE_REPLAY_REEXEC"):
            os.environ["ROBOSUITE_REPLAY_REEXEC"] = "1"
            os.execv(VENV_PYTHON, [VENV_PYTHON, os.path.abspath(__file__), *sys.argv[1:]])
        sys.exit(f"robosuite_replay: cannot import {e.name} ({e}); run scripts/setup_robosuite.sh and use {VENV_PYTHON}")


def demo_index(name):
    m = re.fullmatch(r"demo_(\d+)", name)
    return int(m.group(1)) if m else None


def read_env_args(f, path):
    if "data" not in f:
        raise BadInput(f"{path}: no group 'data'")
    raw = f["data"].attrs.get("env_args")
    if raw is None:
        raise BadInput(f"{path}: group 'data' has no attribute 'env_args'")
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8")
    try:
        env_args = json.loads(str(raw))
    except json.JSONDecodeError as e:
        raise BadInput(f"{path}: data attr 'env_args' is not JSON ({e})") from e
    if not isinstance(env_args, dict) or "env_name" not in env_args:
        raise BadInput(f"{path}: data attr 'env_args' has no 'env_name'")
    return env_args


# MimicGen's tasks whose robosuite environment has another name (the variants subclass it).
ROBOSUITE_BASE = {"Square": "NutAssemblySquare"}


def resolve_env_name(name, registered):
    """MimicGen names task variants `Stack_D0`, `Square_D1`, ... (ours also `Stack_C0`, `MugCleanup_O1`); robosuite only has the base task."""
    if name in registered:
        return name
    base = re.sub(r"_[A-Z]\d+$", "", name)
    base = ROBOSUITE_BASE.get(base, base)
    if base in registered:
        return base
    raise BadInput(f"data attr 'env_args': env_name {name!r} is not a robosuite environment "
                   f"(nor is {base!r}); known: {', '.join(sorted(registered))}")


def make_env(env_args, path, render=False):
    import robosuite
    from robosuite.environments.base import REGISTERED_ENVS

    env_name = resolve_env_name(env_args["env_name"], REGISTERED_ENVS)
    kwargs = dict(env_args.get("env_kwargs") or {})
    if "robots" not in kwargs:
        raise BadInput(f"{path}: data attr 'env_args': env_kwargs has no 'robots'")
    if "controller_configs" not in kwargs:
        raise BadInput(f"{path}: data attr 'env_args': env_kwargs has no 'controller_configs'")
    kwargs.update(
        has_renderer=False,
        has_offscreen_renderer=render,
        use_camera_obs=False,
        ignore_done=True,
        hard_reset=False,
        control_freq=kwargs.get("control_freq", 20),
    )
    # Keep only the keyword arguments the robosuite class takes (env_args may carry extras).
    # (NutAssemblySquare takes **kwargs and passes them on: read its bases' signatures too.)
    params = set()
    for cls in REGISTERED_ENVS[env_name].__mro__:
        if "__init__" in vars(cls):
            params |= set(inspect.signature(cls.__init__).parameters)
    dropped = sorted(k for k in kwargs if k not in params)
    kwargs = {k: v for k, v in kwargs.items() if k in params}
    env = robosuite.make(env_name, **kwargs)
    return env, env_name, dropped


# How far a replayed joint position may be from the stored one before the replay counts as parted
# from the recording there (m or rad; a free joint's quaternion components count as they are).
PARTED_AT = (0.001, 0.005, 0.02)


def qpos_names(model):
    """The joint each qpos entry belongs to, `name[k]` for the k-th of a multi-entry joint."""
    names = []
    for j in range(model.njnt):
        size = {0: 7, 1: 4}.get(int(model.jnt_type[j]), 1)
        jn = model.joint_id2name(j) or f"joint{j}"
        names += [jn] if size == 1 else [f"{jn}[{k}]" for k in range(size)]
    return names


def replay_demo(env, grp, name, path):
    import numpy as np

    for field in ("states", "actions"):
        if field not in grp:
            raise BadInput(f"{path}: data/{name} has no dataset '{field}'")
    xml = grp.attrs.get("model_file")
    if xml is None:
        raise BadInput(f"{path}: data/{name} has no attribute 'model_file'")
    if isinstance(xml, bytes):
        xml = xml.decode("utf-8")
    states = np.asarray(grp["states"][()], dtype=np.float64)
    actions = np.asarray(grp["actions"][()], dtype=np.float64)
    if states.ndim != 2 or actions.ndim != 2 or len(states) == 0 or len(actions) == 0:
        raise BadInput(f"{path}: data/{name}: 'states' {states.shape} / 'actions' {actions.shape} are not non-empty 2-D")
    if actions.shape[1] != env.action_dim:
        raise BadInput(f"{path}: data/{name}/actions has width {actions.shape[1]}, the env takes {env.action_dim}")

    # What robomimic's EnvRobosuite.reset_to does with a {model, states} pair.
    # A model_file robosuite cannot load is a failed replay (reported with MuJoCo's message), not bad input.
    try:
        env.reset()
        env.reset_from_xml_string(env.edit_model_xml(str(xml)))
        env.sim.reset()
    except Exception as e:  # noqa: BLE001 - robosuite/mujoco raise assorted types here
        return {"steps": 0, "success": False, "success_at_end": False, "first_success_step": None,
                "error": f"loading model_file: {type(e).__name__}: {e}"}
    sim = env.sim
    nq, nv = sim.model.nq, sim.model.nv
    if states.shape[1] != 1 + nq + nv:
        raise BadInput(f"{path}: data/{name}/states has width {states.shape[1]}, robosuite's model_file scene "
                       f"has 1 + nq {nq} + nv {nv} = {1 + nq + nv}")
    sim.set_state_from_flattened(states[0])
    sim.forward()
    # The arm's controller holds its null-space posture at the joints the episode started from, as
    # in the live episode that recorded the demo (robosuite's reset with initialization noise, and
    # ours). robomimic's reset_to leaves it at the noiseless init_qpos, which starts the arm up to
    # 2 cm off its recorded path before anything is touched.
    for robot in env.robots:
        robot.controller.update_initial_joints(np.array(sim.data.qpos[robot._ref_joint_pos_indexes]))

    # states[t] is the state before actions[t]: compare the replayed state before the last action
    # with the last stored state (robomimic's playback compares the same pairs). Time is left out.
    success_any, first_success, success = False, None, False
    last_err = None
    names, parted = qpos_names(sim.model), {}
    for t, action in enumerate(actions):
        if t < len(states) and len(parted) < len(PARTED_AT):
            d = np.abs(np.asarray(sim.data.qpos, dtype=np.float64) - states[t][1:1 + nq])
            i = int(d.argmax())
            for limit in PARTED_AT:
                if limit not in parted and d[i] > limit:
                    parted[limit] = {"step": t, "joint": names[i] if i < len(names) else str(i), "diff": float(d[i])}
        if t == len(states) - 1:
            rep = np.asarray(sim.get_state().flatten(), dtype=np.float64)
            d = np.abs(rep - states[t])
            last_err = (float(d[1:1 + nq].max()), float(d[1 + nq:].max()))
        env.step(action)
        success = bool(env._check_success())
        if success and not success_any:
            success_any, first_success = True, t
    if last_err is None and len(states) == len(actions) + 1:  # states include the final one
        d = np.abs(np.asarray(sim.get_state().flatten(), dtype=np.float64) - states[-1])
        last_err = (float(d[1:1 + nq].max()), float(d[1 + nq:].max()))
    out = {
        "steps": int(len(actions)),
        "success": success_any,
        "success_at_end": success,
        "first_success_step": first_success,
        # Limit (m or rad) -> where the replay first parted from the stored states by more.
        "parted": {f"{limit:g}": parted[limit] for limit in PARTED_AT if limit in parted},
    }
    if last_err is not None:
        out["qpos_err"], out["qvel_err"] = last_err
        out["state_err"] = max(last_err)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--num", type=int, default=None, help="replay the first N demos (default all)")
    ap.add_argument("--min-success", type=int, default=0, help="exit 1 if fewer than K demos succeed")
    ap.add_argument("--json", action="store_true", help="print a machine-readable JSON summary on stdout (the per-demo lines go to stderr)")
    args = ap.parse_args(argv)
    # With --json, stdout carries only the JSON summary; the human-readable lines go to stderr.
    log = sys.stderr if args.json else sys.stdout

    path = args.dataset
    if not os.path.isfile(path):
        print(f"robosuite_replay: {path}: no such file", file=sys.stderr)
        return 2
    ensure_robosuite()
    import h5py

    t0 = time.time()
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        print(f"robosuite_replay: {path}: cannot open as HDF5 ({e})", file=sys.stderr)
        return 2
    results = []
    with f:
        try:
            env_args = read_env_args(f, path)
            names = sorted((k for k in f["data"].keys() if demo_index(k) is not None), key=demo_index)
            if not names:
                raise BadInput(f"{path}: group 'data' has no demo_N groups")
            if args.num is not None:
                if args.num > len(names):
                    raise BadInput(f"{path}: --num {args.num} but group 'data' has only {len(names)} demos")
                names = names[:args.num]
            env, env_name, dropped = make_env(env_args, path)
        except BadInput as e:
            print(f"robosuite_replay: {e}", file=sys.stderr)
            return 2
        import robosuite

        print(f"robosuite {robosuite.__version__}: env {env_name} (file says {env_args['env_name']!r})"
              + (f", ignored env_kwargs {dropped}" if dropped else ""), file=log)
        for name in names:
            t1 = time.time()
            try:
                r = replay_demo(env, f["data"][name], name, path)
            except BadInput as e:
                print(f"robosuite_replay: {e}", file=sys.stderr)
                return 2
            r["demo"] = name
            r["seconds"] = round(time.time() - t1, 3)
            results.append(r)
            if "error" in r:
                print(f"{name}: FAILED {r['error']}", file=log)
                continue
            err = f"{r['state_err']:.3g} (qpos {r['qpos_err']:.3g}, qvel {r['qvel_err']:.3g})" if "state_err" in r else "n/a"
            parted = ", ".join(f">{k} at step {v['step']} ({v['joint']})" for k, v in r["parted"].items()) or "never by 1 mm"
            print(f"{name}: steps {r['steps']} success {r['success']} (at end {r['success_at_end']}, "
                  f"first at step {r['first_success_step']}) last-state max abs diff {err}; parted {parted} [{r['seconds']:.1f}s]", file=log)
        env.close()

    k, n = sum(r["success"] for r in results), len(results)
    print(f"robosuite replay: {k} of {n} succeeded ({time.time() - t0:.1f}s)", file=log)
    if args.json:
        print(json.dumps({
            "dataset": os.path.abspath(path),
            "env_name": env_name,
            "num": n,
            "num_success": k,
            "min_success": args.min_success,
            "ok": k >= args.min_success,
            "seconds": round(time.time() - t0, 3),
            "demos": results,
        }))
    return 0 if k >= args.min_success else 1


if __name__ == "__main__":
    sys.exit(main())
