"""Rotations as robosuite's OSC_POSE controller reads delta actions: axis-angle vectors (radians)
and 3x3 matrices, in numpy."""

import numpy as np


def rotation(axis_angle) -> np.ndarray:
    """The rotation matrix of an axis-angle vector (Rodrigues)."""
    angle = float(np.linalg.norm(axis_angle))
    if angle < 1e-12:
        return np.eye(3)
    k = np.asarray(axis_angle, dtype=float) / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def axis_angle(R) -> np.ndarray:
    """The axis-angle vector of a rotation matrix (angle in [0, pi])."""
    R = np.asarray(R, dtype=float)
    angle = float(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)))
    if angle < 1e-9:
        return np.zeros(3)
    if np.pi - angle < 1e-6:
        w, v = np.linalg.eigh((R + R.T) / 2)
        return v[:, np.argmax(w)] * angle
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return v / (2 * np.sin(angle)) * angle


def make_pose(position, R) -> np.ndarray:
    """A 4x4 homogeneous transform."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = position
    return T


def delta_action(current, target, max_dpos: float, max_drot: float) -> np.ndarray:
    """The six pose numbers of an OSC_POSE delta action from pose ``current`` towards ``target``
    (position and rotation each scaled by the controller's limits and clipped to [-1, 1])."""
    dp = (target[:3, 3] - current[:3, 3]) / max_dpos
    dr = axis_angle(target[:3, :3] @ current[:3, :3].T) / max_drot
    return np.clip(np.concatenate([dp, dr]), -1.0, 1.0)


def delta_target(current, action, max_dpos: float, max_drot: float) -> np.ndarray:
    """The target pose a delta action asks for from pose ``current`` (inverse of
    :func:`delta_action` inside the limits)."""
    a = np.asarray(action[:6], dtype=float)
    return make_pose(current[:3, 3] + a[:3] * max_dpos, rotation(a[3:6] * max_drot) @ current[:3, :3])
