#!/usr/bin/env python3
"""Replay our source demos in the reference MimicGen's own task environments, open loop.

Usage: reference_replay.py DATASET [--num N] [--diag] [--write OUT [--overwrite]] [--json]

The question it answers: is our task the reference's task? For each of the first N demos of
DATASET (a source file of ours, e.g. core/sim/data/coffee_D0_source.hdf5) it builds the reference's
environment named by the file's `env_args` (`Coffee_D0`: NVlabs/mimicgen's Coffee_D0 on robosuite
1.4.1, Panda, OSC_POSE, 20 Hz), puts the robot's joints and every object where our demo's first
state has them (each object through the pose the reference's env interface reports for it, under
the same name, carried across by the robot base's pose, so scenes whose world frames differ by the
base's place still agree), steps our demo's actions, and records whether the reference's own
`_check_success()` held at any step. It prints one line per demo and
`<env>: K of N succeeded in the reference's env`.

  --diag   also say where the replay leaves ours: for each subtask signal the first step it is on in
           ours and in theirs, for each object the first step it is more than 1 cm from ours and
           how far at the end, and the same for the end effector.
  --write  write the first demo whose replay succeeded (else demo 0) as a source file in the
           reference's layout: `states`, `actions`, `model_file` of the reference's env and
           `datagen_info` from its env interface, what its prepare_src_dataset.py stores. This is how
           the fixtures in core/sim/tests/data/reference/ were made.

Needs robosuite 1.4.1's environment (scripts/setup_robosuite.sh) and the reference's sources on
PYTHONPATH, at the commits docs/fidelity.md cites (they are not ours to ship):

  git clone https://github.com/NVlabs/mimicgen /tmp/ref/mimicgen
  git -C /tmp/ref/mimicgen checkout 72bd767c255545f462e7ccfb2731f2e5d4c1d9bb
  git clone https://github.com/ARISE-Initiative/robosuite-task-zoo /tmp/ref/zoo
  git -C /tmp/ref/zoo checkout 74eab7f88214c21ca1ae8617c2b2f8d19718a9ed
  ~/.cache/mimicgen/venv-robosuite/bin/pip install --target /tmp/ref/py six==1.16.0
  PYTHONPATH=/tmp/ref/mimicgen:/tmp/ref/zoo:/tmp/ref/py ~/.cache/mimicgen/venv-robosuite/bin/python \\
      scripts/reference_replay.py core/sim/data/stack_D0_source.hdf5 --diag

Exit status: 0 ok, 2 bad input or the reference's code not found.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import xml.etree.ElementTree as ET

os.environ.setdefault("MUJOCO_GL", "disable")

try:
    import h5py
    import numpy as np
except ImportError as e:
    print(f"reference_replay: cannot import {e.name}: use robosuite 1.4.1's python (see --help)", file=sys.stderr)
    sys.exit(2)


def die(msg):
    print(f"reference_replay: {msg}", file=sys.stderr)
    sys.exit(2)


def quat_wxyz_to_mat(q):
    import robosuite.utils.transform_utils as T
    w, x, y, z = q
    return T.quat2mat(np.array([x, y, z, w], dtype=float))


def mat_to_quat_wxyz(rot):
    import robosuite.utils.transform_utils as T
    x, y, z, w = T.mat2quat(np.asarray(rot))
    return np.array([w, x, y, z])


def qpos_layout(xml):
    """Our model's joints in qpos order: (name, width)."""
    world = ET.fromstring(xml).find("worldbody")
    out = []
    for el in world.iter():
        if el.tag == "freejoint":
            out.append((el.get("name"), 7))
        elif el.tag == "joint":
            out.append((el.get("name"), {"free": 7, "ball": 4}.get(el.get("type", "hinge"), 1)))
    return out


def world_from_body(xml, name):
    """The pose of body `name` in our model_file, composed from its ancestors' pos/quat."""

    def local(b):
        t = np.eye(4)
        if b.get("pos"):
            t[:3, 3] = [float(v) for v in b.get("pos").split()]
        if b.get("quat"):
            t[:3, :3] = quat_wxyz_to_mat([float(v) for v in b.get("quat").split()])
        return t

    def walk(el, pose):
        for b in el.findall("body"):
            here = pose @ local(b)
            if b.get("name") == name:
                return here
            found = walk(b, here)
            if found is not None:
                return found
        return None

    found = walk(ET.fromstring(xml).find("worldbody"), np.eye(4))
    if found is None:
        die(f"our model_file has no body {name!r}")
    return found


def body_pose(sim, body_id):
    t = np.eye(4)
    t[:3, 3] = sim.data.body_xpos[body_id]
    t[:3, :3] = sim.data.body_xmat[body_id].reshape(3, 3)
    return t


def with_bodies_at(xml, fixed):
    """The model XML with each named body's pos/quat (relative to its parent) replaced."""
    if not fixed:
        return xml
    root = ET.fromstring(xml)
    for el in root.iter("body"):
        if el.get("name") in fixed:
            pos, quat = fixed[el.get("name")]
            el.set("pos", " ".join(repr(float(v)) for v in pos))
            el.set("quat", " ".join(repr(float(v)) for v in quat))
            for k in ("euler", "axisangle", "xyaxes", "zaxis"):
                el.attrib.pop(k, None)
    return ET.tostring(root, encoding="unicode")


class Reference:
    """The reference's env and env interface for one task variant."""

    def __init__(self, env_name):
        try:
            import robosuite
            from robosuite.controllers import load_controller_config
            import mimicgen  # noqa: F401  (registers the reference's task variants with robosuite)
            from mimicgen.env_interfaces.base import make_interface
        except ImportError as e:
            die(f"cannot import {e.name}: put NVlabs/mimicgen and robosuite-task-zoo on PYTHONPATH "
                "and use robosuite 1.4.1's python (see --help)")
        from robosuite.environments.base import REGISTERED_ENVS
        if env_name not in REGISTERED_ENVS:
            die(f"{env_name!r} is not one of the reference's environments "
                f"({', '.join(sorted(k for k in REGISTERED_ENVS if re.search(r'_D[0-9]$', k)))})")
        self.env_name = env_name
        self.controller = load_controller_config(default_controller="OSC_POSE")
        self.env = robosuite.make(
            env_name, robots="Panda", controller_configs=self.controller, has_renderer=False,
            has_offscreen_renderer=False, use_camera_obs=False, ignore_done=True,
            reward_shaping=False, control_freq=20, use_object_obs=True)
        base = re.sub(r"_D[0-9]$", "", env_name)
        self.iface = make_interface(f"MG_{base}", "robosuite", env=self.env)
        self.robosuite_version = robosuite.__version__

    def object_bodies(self):
        """Each object name the interface reports -> the body it reads."""
        read = []
        real = self.iface.get_object_pose

        def spy(obj_name, obj_type):
            read.append(obj_name)
            return real(obj_name=obj_name, obj_type=obj_type)

        self.iface.get_object_pose = spy
        try:
            names = list(self.iface.get_object_poses())
        finally:
            self.iface.get_object_pose = real
        return dict(zip(names, read))

    def start_at(self, demo):
        """Reset, then put the robot and objects where our demo starts. Returns the names of our
        objects the reference does not have, of theirs we do not have, and the base shift."""
        np.random.seed(0)  # robosuite's reset draws from numpy's global generator
        self.env.reset()  # a hard reset: a new sim
        sim = self.env.sim
        xml = demo["model_file"]
        adr = 1  # states: [time, qpos, qvel]
        ours = {}
        for name, width in qpos_layout(xml):
            ours[name] = demo["states"][0][adr:adr + width]
            adr += width
        for name, value in ours.items():
            if name.startswith(("robot0_", "gripper0_")) and name in sim.model.joint_names:
                sim.data.qpos[sim.model.get_joint_qpos_addr(name)] = value[0]
        sim.data.qvel[:] = 0
        sim.forward()
        # The controller's nullspace posture is the arm's start, as in ours (robosuite sets it
        # from the joints its reset drew).
        robot = self.env.robots[0]
        robot.controller.update_initial_joints(sim.data.qpos[robot._ref_joint_pos_indexes])
        shift = body_pose(sim, sim.model.body_name2id("robot0_base")) @ np.linalg.inv(world_from_body(xml, "robot0_base"))
        bodies = self.object_bodies()
        fixed = {}
        for name, body in bodies.items():
            if name not in demo["object_poses"]:
                continue
            want = shift @ demo["object_poses"][name][0]
            b = sim.model.body_name2id(body)
            jnt = sim.model.body_jntadr[b]
            if jnt >= 0 and sim.model.jnt_type[jnt] == 0:
                qa = sim.model.jnt_qposadr[jnt]
                sim.data.qpos[qa:qa + 3] = want[:3, 3]
                sim.data.qpos[qa + 3:qa + 7] = mat_to_quat_wxyz(want[:3, :3])
            else:
                local = np.linalg.inv(body_pose(sim, sim.model.body_parentid[b])) @ want
                sim.model.body_pos[b] = local[:3, 3]
                sim.model.body_quat[b] = mat_to_quat_wxyz(local[:3, :3])
                fixed[body] = (local[:3, 3].copy(), mat_to_quat_wxyz(local[:3, :3]))
        sim.forward()
        missing = sorted(set(demo["object_poses"]) - set(bodies))
        extra = sorted(set(bodies) - set(demo["object_poses"]))
        # A body without a free joint is not in the state: its place goes into the model itself.
        self.model_xml = with_bodies_at(sim.model.get_xml(), fixed)
        return missing, extra, shift

    def replay(self, actions):
        """Step the actions; record what the reference's prepare_src_dataset.py would store."""
        rec = {"states": [], "eef_pose": [], "target_pose": [], "gripper_action": [],
               "object_poses": {}, "signals": {}}
        ever = False
        for a in actions:
            info = self.iface.get_datagen_info(action=a)
            rec["states"].append(self.env.sim.get_state().flatten())
            rec["eef_pose"].append(info.eef_pose)
            rec["target_pose"].append(info.target_pose)
            rec["gripper_action"].append(info.gripper_action)
            for k, v in info.object_poses.items():
                rec["object_poses"].setdefault(k, []).append(v)
            for k, v in info.subtask_term_signals.items():
                rec["signals"].setdefault(k, []).append(v)
            self.env.step(a)
            ever = ever or bool(self.env._check_success())
        rec["actions"] = np.asarray(actions)
        rec["model_file"] = self.model_xml
        return ever, bool(self.env._check_success()), rec

    def write(self, out, rec):
        env_args = {"env_name": self.env_name, "type": 1, "env_version": self.robosuite_version,
                    "env_kwargs": {"robots": ["Panda"], "controller_configs": self.controller,
                                   "has_renderer": False, "has_offscreen_renderer": False,
                                   "use_camera_obs": False, "ignore_done": True, "reward_shaping": False,
                                   "control_freq": 20, "use_object_obs": True}}
        with h5py.File(out, "w") as f:
            data = f.create_group("data")
            data.attrs["env_args"] = json.dumps(env_args)
            data.attrs["total"] = len(rec["actions"])
            g = data.create_group("demo_0")
            g.attrs["num_samples"] = len(rec["actions"])
            g.attrs["model_file"] = rec["model_file"]
            g.create_dataset("states", data=np.array(rec["states"]))
            g.create_dataset("actions", data=np.array(rec["actions"]))
            info = g.create_group("datagen_info")
            for k in ("eef_pose", "target_pose", "gripper_action"):
                info.create_dataset(k, data=np.array(rec[k]))
            for k, v in rec["object_poses"].items():
                info.create_dataset(f"object_poses/{k}", data=np.array(v))
            for k, v in rec["signals"].items():
                info.create_dataset(f"subtask_term_signals/{k}", data=np.array(v))
            f.create_group("mask").create_dataset("train", data=np.array([b"demo_0"]))


def diagnose(demo, rec, shift):
    """Where the replay leaves ours: signals' first steps, objects' and the hand's first 1 cm."""
    out = {}
    for name, ours in demo["signals"].items():
        o = np.nonzero(ours)[0]
        t = np.nonzero(np.asarray(rec["signals"].get(name, [])))[0]
        out[f"signal {name}"] = [int(o[0]) if len(o) else None, int(t[0]) if len(t) else None]

    def strays(ours, theirs):
        ours = np.einsum("ij,tjk->tik", shift, ours)[:, :3, 3]
        dist = np.linalg.norm(ours - np.asarray(theirs)[:, :3, 3], axis=1)
        far = np.nonzero(dist > 0.01)[0]
        return [int(far[0]) if len(far) else None, round(float(dist[-1]), 4)]

    for name, ours in demo["object_poses"].items():
        if name in rec["object_poses"]:
            out[f"object {name}"] = strays(ours, rec["object_poses"][name])
    out["eef"] = strays(demo["eef_pose"], rec["eef_pose"])
    return out


def read_demos(path, num):
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        die(f"{path}: cannot open as HDF5 ({e})")
    with f:
        if "data" not in f:
            die(f"{path}: no group 'data'")
        try:
            env_name = json.loads(f["data"].attrs["env_args"])["env_name"]
        except (KeyError, ValueError) as e:
            die(f"{path}: data attr 'env_args' has no env_name ({e})")
        keys = sorted((k for k in f["data"] if re.fullmatch(r"demo_\d+", k)), key=lambda k: int(k[5:]))[:num]
        demos = []
        for k in keys:
            g = f["data"][k]
            try:
                info = g["datagen_info"]
                demos.append({
                    "name": k,
                    "model_file": g.attrs["model_file"],
                    "states": np.asarray(g["states"]),
                    "actions": np.asarray(g["actions"]),
                    "eef_pose": np.asarray(info["eef_pose"]),
                    "object_poses": {n: np.asarray(info["object_poses"][n]) for n in info["object_poses"]},
                    "signals": {n: np.asarray(info["subtask_term_signals"][n]) for n in info["subtask_term_signals"]},
                })
            except KeyError as e:
                die(f"{path}: data/{k}: missing {e} (a source file of ours has states, actions, model_file and datagen_info)")
    return env_name, demos


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("dataset")
    p.add_argument("--num", type=int, default=10, help="demos to replay (default 10)")
    p.add_argument("--diag", action="store_true", help="say where each replay leaves ours")
    p.add_argument("--write", metavar="OUT", help="write one replay as a source file in the reference's layout")
    p.add_argument("--json", action="store_true", help="one JSON object per demo, then a summary object")
    p.add_argument("--overwrite", action="store_true", help="let --write replace an existing file")
    args = p.parse_args()
    if args.write and os.path.exists(args.write) and not args.overwrite:
        die(f"{args.write}: exists (--overwrite replaces it)")
    env_name, demos = read_demos(args.dataset, args.num)
    ref = Reference(env_name)
    rows, first_ok, first_any = [], None, None
    for demo in demos:
        missing, extra, shift = ref.start_at(demo)
        ever, end, rec = ref.replay(demo["actions"])
        row = {"demo": demo["name"], "success": ever, "success_at_end": end}
        if missing or extra:
            row["names"] = {"ours_only": missing, "theirs_only": extra}
        if args.diag:
            row.update(diagnose(demo, rec, shift))
        rows.append(row)
        print(json.dumps(row) if args.json else " ".join(f"{k}={v}" for k, v in row.items()), flush=True)
        first_any = first_any or rec
        if ever and first_ok is None:
            first_ok = rec
    if args.write:
        ref.write(args.write, first_ok or first_any)
    n = sum(r["success"] for r in rows)
    if args.json:
        print(json.dumps({"env": env_name, "successes": n, "demos": len(rows)}))
    print(f"{env_name}: {n} of {len(rows)} succeeded in the reference's env")


if __name__ == "__main__":
    main()
