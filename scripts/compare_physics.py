#!/usr/bin/env python3
"""Run the same attempts in our simulator and in robosuite, step by step, and say where they part.

Usage: compare_physics.py DATASET [--demos demo_0,demo_3] [--num N] [--mode targets|actions]
                          [--show K] [--json OUT] [--max-eef-mm MM] [--max-object-mm MM]

For each demo of DATASET (a dataset or a failed-attempts file that `mimicgen generate` wrote, on
our backend or on robosuite through `mimicgen_rs.robosuite`), both simulators start from the
demo's first stored state in the demo's own scene (`model_file`: robosuite loads it as robomimic
does) and are driven the same way:

  --mode targets (default)  each step's action is recomputed from where that simulator's arm is
                            towards the stored controller target, plus the attempt's own action
                            noise: the attempt as generation drove it, closed loop.
  --mode actions            the stored actions, open loop (robomimic's playback).

Our side runs `mimicgen replay --trace` (the binary from $MIMICGEN_BIN, else the cargo target
directory); robosuite's side runs here. Per step both record the end effector, the finger joints,
every object's pose, the contact count and the finger pads' contacts and normal force per object.
The script prints, per demo, the outcome in each simulator, the first step where they part
(end effector or an object more than --part-mm apart, or a finger more than 1 mm), and with
--show K the K steps from there side by side; then the demos whose outcome differs.

Exit status: 0 done, 1 when --max-eef-mm or --max-object-mm is given and a demo's end effector
or an object parted by more (the guard scripts/test.sh runs), 2 bad input.

Run it in the robosuite environment (scripts/setup_robosuite.sh); from another interpreter it
re-executes itself with that environment's python.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

os.environ["MUJOCO_GL"] = "disable"
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

import robosuite_replay as rr  # noqa: E402  (the same env construction and model loading)


def geometry():
    """The package's delta-action arithmetic (what generation on robosuite uses), loaded from the
    source tree so that the wheel need not be installed."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("mimicgen_geometry", os.path.join(ROOT, "app/python/python/mimicgen_rs/geometry.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def our_binary():
    if os.environ.get("MIMICGEN_BIN"):
        return os.environ["MIMICGEN_BIN"]
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(rr.CACHE, "target"))
    for profile in ("release", "debug"):
        path = os.path.join(target, profile, "mimicgen")
        if os.path.exists(path):
            return path
    sys.exit("compare_physics: no mimicgen binary; build it (cargo build --release) or set MIMICGEN_BIN")


def ours(path, demos, mode):
    """Our simulator's traces (`mimicgen replay --trace`)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "trace.json")
        cmd = [our_binary(), "replay", path, "--mode", mode, "--trace", out]
        if demos:
            cmd += ["--demos", ",".join(demos)]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(f"compare_physics: {' '.join(cmd)} failed ({done.returncode}):\n{done.stderr.strip()}")
        with open(out) as f:
            return json.load(f)


def pose7(pos, mat):
    import numpy as np
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(mat).reshape(3, 3)).as_quat()
    return [float(pos[0]), float(pos[1]), float(pos[2]), float(w), float(x), float(y), float(z)]


def as_matrix(p7):
    import numpy as np
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([p7[4], p7[5], p7[6], p7[3]]).as_matrix()
    T[:3, 3] = p7[:3]
    return T


def robosuite_trace(env, grp, name, path, mode, ref):
    """The same demo in robosuite, recorded as `mimicgen replay` records it in ours."""
    import mujoco
    import numpy as np
    delta_action = geometry().delta_action

    xml = grp.attrs["model_file"]
    xml = xml.decode() if isinstance(xml, bytes) else str(xml)
    env.reset()
    env.reset_from_xml_string(env.edit_model_xml(xml))
    env.sim.reset()
    sim = env.sim
    m, d = sim.model._model, sim.data._data
    states = np.asarray(grp["states"][()], dtype=float)
    actions = np.asarray(grp["actions"][()], dtype=float)
    sim.set_state_from_flattened(states[0])
    sim.forward()
    ctrl = env.robots[0].controller
    # The first state is the attempt's reset: its arm pose is the posture the controller held.
    ctrl.update_initial_joints(np.array(sim.data.qpos[ctrl.qpos_index]))
    max_dpos, max_drot = float(ctrl.output_max[0]), float(ctrl.output_max[3])
    site = sim.model.site_name2id(ref["eef_site"])
    bodies = {o: sim.model.body_name2id(n["body"]) for o, n in ref["objects"].items()}
    geoms = {o: {sim.model.geom_name2id(g) for g in n["geoms"]} for o, n in ref["objects"].items()}
    pads = [{sim.model.geom_name2id(g) for g in side} for side in ref["pads"]]
    all_pads = pads[0] | pads[1]
    fingers = [sim.model.get_joint_qpos_addr(j) for j in env.robots[0].gripper.joints]
    if mode == "targets":
        info = grp["datagen_info"]
        eefs, targets = np.asarray(info["eef_pose"][()]), np.asarray(info["target_pose"][()])

    def eef_pose():
        return np.asarray(
            [[*sim.data.site_xmat[site][0:3], sim.data.site_xpos[site][0]],
             [*sim.data.site_xmat[site][3:6], sim.data.site_xpos[site][1]],
             [*sim.data.site_xmat[site][6:9], sim.data.site_xpos[site][2]],
             [0, 0, 0, 1]])

    def observe():
        pad_contacts = {}
        wrench = np.zeros(6)
        for o in ref["objects"]:
            count, force = 0, 0.0
            for i in range(d.ncon):
                c = d.contact[i]
                if (c.geom1 in all_pads and c.geom2 in geoms[o]) or (c.geom2 in all_pads and c.geom1 in geoms[o]):
                    mujoco.mj_contactForce(m, d, i, wrench)
                    count, force = count + 1, force + float(wrench[0])
            pad_contacts[o] = [count, force]
        return {
            "eef": pose7(sim.data.site_xpos[site], sim.data.site_xmat[site]),
            "fingers": [float(sim.data.qpos[a]) for a in fingers],
            "objects": {o: pose7(sim.data.body_xpos[b], sim.data.body_xmat[b]) for o, b in bodies.items()},
            "contacts": int(d.ncon),
            "pads": pad_contacts,
            "success": bool(env._check_success()),
        }

    steps = [observe()]
    first = None
    for t, stored in enumerate(actions):
        action = stored.copy()
        if mode == "targets":
            clean_then = delta_action(eefs[t], targets[t], max_dpos, max_drot)
            clean_now = delta_action(eef_pose(), targets[t], max_dpos, max_drot)
            action[:6] = clean_now + (stored[:6] - clean_then)
        env.step(action)
        steps.append(observe())
        if steps[-1]["success"] and first is None:
            first = t
    return {"steps": steps, "success": first is not None, "first_success": first}


def rot_deg(a, b):
    import numpy as np

    qa, qb = np.asarray(a[3:7]), np.asarray(b[3:7])
    return float(np.degrees(2 * np.arccos(min(1.0, abs(float(qa @ qb))))))


def mm(a, b):
    import numpy as np

    return 1000 * float(np.linalg.norm(np.asarray(a[:3]) - np.asarray(b[:3])))


def differences(o, r):
    """Per-step differences between our step `o` and robosuite's `r`."""
    out = {"eef_mm": mm(o["eef"], r["eef"]), "eef_deg": rot_deg(o["eef"], r["eef"]),
           "finger_mm": 1000 * max(abs(a - b) for a, b in zip(o["fingers"], r["fingers"]))}
    for name in o["objects"]:
        out[f"{name}_mm"] = mm(o["objects"][name], r["objects"][name])
        out[f"{name}_deg"] = rot_deg(o["objects"][name], r["objects"][name])
    return out


def parting(diffs, part_mm):
    for t, d in enumerate(diffs):
        over = [k for k, v in d.items() if (k.endswith("_mm") and v > (1.0 if k == "finger_mm" else part_mm))]
        if over:
            return t, over
    return None, []


def show(ours_steps, rs_steps, start, count):
    print("    step | eef mm (ours - rs) | fingers ours / rs (mm) | pads ours / rs (count, N) per object | contacts ours / rs")
    for t in range(start, min(start + count, len(ours_steps), len(rs_steps))):
        o, r = ours_steps[t], rs_steps[t]
        pads = "  ".join(f"{n}: {o['pads'][n][0]},{o['pads'][n][1]:.0f} / {r['pads'][n][0]},{r['pads'][n][1]:.0f}" for n in o["pads"])
        fo = " ".join(f"{1000 * v:+.1f}" for v in o["fingers"])
        fr = " ".join(f"{1000 * v:+.1f}" for v in r["fingers"])
        print(f"    {t:4d} | {mm(o['eef'], r['eef']):6.2f} | {fo} / {fr} | {pads} | {o['contacts']} / {r['contacts']}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--demos", default="", help="comma-separated demo names (default: all, or the first --num)")
    ap.add_argument("--num", type=int, default=None, help="the first N demos")
    ap.add_argument("--mode", choices=["targets", "actions"], default="targets")
    ap.add_argument("--part-mm", type=float, default=5.0, help="end effector or object apart by more than this = parted (default 5)")
    ap.add_argument("--show", type=int, default=0, help="print K steps side by side from where each demo parts")
    ap.add_argument("--json", default=None, help="write per-demo results (and per-step differences) here")
    ap.add_argument("--max-eef-mm", type=float, default=None, help="exit 1 if any demo's end effector parts by more than this")
    ap.add_argument("--max-object-mm", type=float, default=None, help="exit 1 if any demo's object parts by more than this")
    args = ap.parse_args(argv)
    rr.ensure_robosuite()
    import h5py

    path = args.dataset
    if not os.path.exists(path):
        print(f"compare_physics: {path}: no such file", file=sys.stderr)
        return 2
    with h5py.File(path, "r") as f:
        try:
            env_args = rr.read_env_args(f, path)
            env, env_name, _ = rr.make_env(env_args, path)
        except rr.BadInput as e:
            print(f"compare_physics: {e}", file=sys.stderr)
            return 2
        names = sorted(f["data"].keys(), key=lambda n: rr.demo_index(n) if rr.demo_index(n) is not None else 1 << 30)
        if args.demos:
            names = [n for n in args.demos.split(",") if n]
            missing = [n for n in names if n not in f["data"]]
            if missing:
                print(f"compare_physics: {path}: no demo {', '.join(missing)}", file=sys.stderr)
                return 2
        if args.num is not None:
            names = names[: args.num]
        traces = ours(path, names, args.mode)
        results, worst_eef, worst_object = [], 0.0, 0.0
        for ref in traces:
            name = ref["demo"]
            rs = robosuite_trace(env, f["data"][name], name, path, args.mode, ref)
            n = min(len(ref["steps"]), len(rs["steps"]))
            diffs = [differences(ref["steps"][t], rs["steps"][t]) for t in range(n)]
            part, what = parting(diffs, args.part_mm)
            worst = {k: max(d[k] for d in diffs) for k in diffs[0]}
            worst_eef = max(worst_eef, worst["eef_mm"])
            worst_object = max([worst_object] + [worst[o + "_mm"] for o in ref["objects"]])
            outcome = lambda s, fs: f"success at step {fs}" if s else "fails"  # noqa: E731
            where = f"part at step {part} ({', '.join(what)})" if part is not None else "never part"
            print(f"{name}: ours {outcome(ref['success'], ref['first_success'])}, robosuite "
                  f"{outcome(rs['success'], rs['first_success'])}; {where}; worst eef {worst['eef_mm']:.1f} mm, "
                  f"fingers {worst['finger_mm']:.1f} mm"
                  + "".join(f", {o} {worst[o + '_mm']:.1f} mm" for o in ref["objects"])
                  + (f" [generated: {ref['recorded_failure']}]" if ref.get("recorded_failure") else ""))
            if args.show and part is not None:
                show(ref["steps"], rs["steps"], max(0, part - 1), args.show)
            results.append({"demo": name, "ours_success": ref["success"], "robosuite_success": rs["success"],
                            "part_step": part, "parted": what, "worst": worst, "diffs": diffs})
        env.close()
    differ = [r for r in results if r["ours_success"] != r["robosuite_success"]]
    print(f"compare_physics ({args.mode}, {env_name}): ours {sum(r['ours_success'] for r in results)} of {len(results)}, "
          f"robosuite {sum(r['robosuite_success'] for r in results)} of {len(results)}; outcomes differ in "
          f"{len(differ)}: {', '.join(r['demo'] for r in differ) or '-'}; worst gaps: end effector {worst_eef:.1f} mm, "
          f"object {worst_object:.1f} mm")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"dataset": path, "mode": args.mode, "demos": results}, out)
    if args.max_eef_mm is not None and worst_eef > args.max_eef_mm:
        print(f"compare_physics: end effectors parted by {worst_eef:.1f} mm, more than --max-eef-mm {args.max_eef_mm}", file=sys.stderr)
        return 1
    if args.max_object_mm is not None and worst_object > args.max_object_mm:
        print(f"compare_physics: objects parted by {worst_object:.1f} mm, more than --max-object-mm {args.max_object_mm}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
