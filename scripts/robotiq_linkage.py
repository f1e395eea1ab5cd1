#!/usr/bin/env python3
"""Measure how robosuite 1.4.1's Robotiq grippers move under its own MuJoCo (2.3.2), and fit the
couplings our simulation uses in their place (`core/sim/src/robot.rs`, `SimPatch`).

Usage: robotiq_linkage.py [UR5e|IIWA ...]

For each arm it builds robosuite's Lift environment (no reset noise), opens the gripper for 20
steps and closes it for 40 with the arm held still, records the six gripper joints per step, and
fits every passive joint as `offset + slope * driver` (least squares; the driver is the knuckle
its side's actuator drives). It prints the fitted couplings, the worst residual, and the distance
between the finger pads open and closed, which is what the patched model is compared against.

Needs the environment made by scripts/setup_robosuite.sh; run with another interpreter it
re-executes itself with that environment's python if it exists.
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "disable")
VENV_PYTHON = Path.home() / ".cache/mimicgen/venv-robosuite/bin/python"
try:
    import robosuite  # noqa: F401
except ImportError:
    if VENV_PYTHON.exists() and Path(sys.executable) != VENV_PYTHON:
        os.execv(str(VENV_PYTHON), [str(VENV_PYTHON), *sys.argv])
    sys.exit("robotiq_linkage.py: robosuite is not installed (run scripts/setup_robosuite.sh)")

import numpy as np  # noqa: E402
import robosuite  # noqa: E402,F811

# Per side: the driven knuckle, then the joints that follow it.
SIDES = [
    ("gripper0_finger_joint", ["gripper0_left_inner_knuckle_joint", "gripper0_left_inner_finger_joint"]),
    ("gripper0_right_outer_knuckle_joint", ["gripper0_right_inner_knuckle_joint", "gripper0_right_inner_finger_joint"]),
]
PADS = ("gripper0_left_fingerpad_collision", "gripper0_right_fingerpad_collision")


def measure(robot):
    config = robosuite.load_controller_config(default_controller="OSC_POSE")
    env = robosuite.make("Lift", robots=[robot], has_renderer=False, has_offscreen_renderer=False,
                         use_camera_obs=False, ignore_done=True, controller_configs=config,
                         initialization_noise=None)
    env.reset()
    model, data = env.sim.model, env.sim.data
    qpos = {n: model.jnt_qposadr[model.joint_name2id(n)] for side in SIDES for n in [side[0], *side[1]]}
    pads = [model.geom_name2id(n) for n in PADS]
    rows, gaps = [], []
    for step in range(60):
        close = 1.0 if step >= 20 else -1.0
        # A rotation delta just off zero: on an exactly zero one robosuite keeps an old goal.
        env.step(np.array([0, 0, 0, 1e-6, 0, 0, close]))
        rows.append({n: data.qpos[a] for n, a in qpos.items()})
        gaps.append(np.linalg.norm(data.geom_xpos[pads[0]] - data.geom_xpos[pads[1]]))
    print(f"{robot}: pads {gaps[19] * 100:.1f} cm apart open, {gaps[-1] * 100:.1f} cm closed")
    for driver, passive in SIDES:
        x = np.array([r[driver] for r in rows])
        print(f"  {driver}: {x[19]:+.3f} rad open, {x[-1]:+.3f} closed")
        for joint in passive:
            y = np.array([r[joint] for r in rows])
            slope, offset = np.polyfit(x, y, 1)
            worst = np.abs(offset + slope * x - y).max()
            print(f'    follows("{joint}", "{driver}", {offset:.4f}, {slope:.3f}),  // worst residual {worst:.3f} rad')


if __name__ == "__main__":
    for name in sys.argv[1:] or ["UR5e", "IIWA"]:
        measure(name)
