"""A small pure-Python simulator of the Stack task for tests of "bring your own simulator": a
gripper that goes exactly where an OSC_POSE-style delta action points it, two cubes on a table
(cubeA sampled near cubeB, as Stack D0 does), a grasp when the gripper closes within 3 cm of
cubeA, and success when cubeA is released on top of cubeB."""

import numpy as np

from mimicgen_rs.geometry import delta_action, delta_target, rotation

MAX_DPOS = 0.05  # metres per unit action, as robosuite's OSC_POSE
MAX_DROT = 0.5  # radians per unit action


def pose(x, y, z, yaw):
    T = np.eye(4)
    T[:3, :3] = rotation([0, 0, yaw])
    T[:3, 3] = [x, y, z]
    return T


class KinematicStack:
    def __init__(self):
        self.steps = 0

    def action_dim(self):
        return 7

    def reset(self, seed):
        rng = np.random.default_rng(seed)
        self.eef = np.array([[0.0, 1, 0, -0.1], [1, 0, 0, 0], [0, 0, -1, 1.0], [0, 0, 0, 1]])
        while True:
            a, b = rng.uniform(-0.08, 0.08, 2), rng.uniform(-0.08, 0.08, 2)
            if np.linalg.norm(a - b) > 0.06:
                break
        self.cube_a = pose(a[0], a[1], 0.82, rng.uniform(0, 2 * np.pi))
        self.cube_b = pose(b[0], b[1], 0.825, rng.uniform(0, 2 * np.pi))
        self.eef_from_a = None

    def eef_pose(self):
        return self.eef.copy()

    def object_poses(self):
        return {"cubeA": self.cube_a.copy(), "cubeB": self.cube_b.copy()}

    def subtask_term_signals(self):
        return {"grasp": int(self.eef_from_a is not None)}

    def is_success(self):
        d = self.cube_a[:3, 3] - self.cube_b[:3, 3]
        return self.eef_from_a is None and np.linalg.norm(d[:2]) < 0.03 and 0.02 < d[2] < 0.08

    def target_pose_to_action(self, target):
        return delta_action(self.eef, target, MAX_DPOS, MAX_DROT)

    def action_to_target_pose(self, action):
        return delta_target(self.eef, np.clip(action[:6], -1, 1), MAX_DPOS, MAX_DROT)

    def step(self, action):
        self.steps += 1
        self.eef = self.action_to_target_pose(action)
        if self.eef_from_a is not None:
            self.cube_a = self.eef @ self.eef_from_a
        closing = action[6] > 0
        near = np.linalg.norm(self.eef[:3, 3] - self.cube_a[:3, 3]) < 0.03
        if closing and self.eef_from_a is None and near:
            self.eef_from_a = np.linalg.inv(self.eef) @ self.cube_a
        elif not closing:
            self.eef_from_a = None

    def get_state(self):
        held = np.zeros(16) if self.eef_from_a is None else self.eef_from_a.ravel()
        return np.concatenate([self.eef.ravel(), self.cube_a.ravel(), self.cube_b.ravel(), [float(self.eef_from_a is not None)], held])

    def set_state(self, state):
        s = np.asarray(state, dtype=float)
        self.eef, self.cube_a, self.cube_b = (s[i * 16:(i + 1) * 16].reshape(4, 4) for i in range(3))
        self.eef_from_a = s[49:65].reshape(4, 4) if s[48] > 0.5 else None

    def observations(self):
        return {"robot0_eef_pos": self.eef[:3, 3].copy(), "object": np.concatenate([self.cube_a[:3, 3], self.cube_b[:3, 3]])}
