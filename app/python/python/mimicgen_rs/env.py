"""Our simulator as an environment a policy acts in: the scenes ``generate`` draws for a task and
variant, stepped with a policy's actions, observed with the keys and shapes our datasets hold::

    import mimicgen_rs as mg

    env = mg.Env("stack", "D1", seed=0)
    obs = env.reset()                      # {"robot0_eef_pos": (3,), ..., "object": (N,)}
    for _ in range(400):
        obs, reward, done, info = env.step(policy(obs))
        if env.is_success():
            break

The same seed gives the same scenes, episode after episode. ``Env.from_dataset(path)`` builds the
environment a dataset was generated in (its ``env_args``), as robomimic's rollouts do;
``mimicgen_rs.robomimic`` and ``mimicgen_rs.gym`` wrap this class for robomimic and gymnasium.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native

PathLike = Union[str, "os.PathLike[str]"]


class Env:
    """One environment of ``task`` / ``variant`` (default D0) with the arm ``robot`` (default the
    Panda), rendering ``cameras`` (names, e.g. ``["agentview"]``) at ``camera_size`` into every
    observation when given. Two-arm tasks are not served yet.

    Steps follow robomimic's convention: ``step(action)`` returns ``(obs, reward, done, info)``;
    the reward is 1.0 once the task is achieved and ``done`` is never set (robomimic's rollouts
    stop on success or at their horizon).
    """

    def __init__(
        self,
        task: str = "stack",
        variant: Optional[str] = None,
        *,
        robot: Optional[str] = None,
        cameras: Optional[Sequence[str]] = None,
        camera_size: Union[int, Tuple[int, int]] = 84,
        seed: int = 0,
    ) -> None:
        height, width = (camera_size, camera_size) if isinstance(camera_size, int) else (int(camera_size[0]), int(camera_size[1]))
        config: Dict[str, Any] = {"task": task, "variant": variant, "robot": robot, "out": ""}
        if cameras:
            config["cameras"] = {"names": [str(c) for c in cameras], "height": height, "width": width, "depth": False}
        self._native = _native.Env(json.dumps(config), int(seed))
        self.task = task
        self.variant = variant
        self.robot = robot
        self.cameras = list(cameras or [])
        self.camera_size = (height, width)
        self.seed = int(seed)
        self._render_twin: Dict[Tuple[str, int, int], "Env"] = {}

    @classmethod
    def from_env_args(cls, env_args: Union[str, Mapping[str, Any]], *, cameras: Optional[Sequence[str]] = None, seed: int = 0) -> "Env":
        """The environment a dataset's ``env_args`` (robomimic's environment metadata) names:
        its ``env_name`` (``Stack_D1``) and arm (``env_kwargs.robots``)."""
        meta = json.loads(env_args) if isinstance(env_args, str) else dict(env_args)
        task, variant = _native.task_from_env_name(str(meta.get("env_name", "")))
        robots = meta.get("env_kwargs", {}).get("robots")
        robot = (robots[0] if isinstance(robots, list) else robots) if robots else None
        return cls(task, variant, robot=robot, cameras=cameras, seed=seed)

    @classmethod
    def from_dataset(cls, path: PathLike, *, cameras: Optional[Sequence[str]] = None, seed: int = 0) -> "Env":
        """The environment the dataset at ``path`` was generated in (from its ``env_args``)."""
        env_args = _native.Dataset(os.fspath(path)).env_args
        if env_args is None:
            raise _native.MimicgenError(f"{os.fspath(path)}: data attribute env_args: missing, so the environment is unknown")
        return cls.from_env_args(env_args, cameras=cameras, seed=seed)

    @property
    def env_args(self) -> Dict[str, Any]:
        """robomimic's environment metadata for this environment (what our datasets carry)."""
        return json.loads(self._native.env_args())

    @property
    def action_dim(self) -> int:
        """Width of an action: delta position (3), delta rotation (3, axis-angle), gripper
        (and a mobile base's forward, sideways, turn)."""
        return self._native.action_dim()

    def reset(self, seed: Optional[int] = None) -> Dict[str, np.ndarray]:
        """A new episode from the environment's random stream (restarted from ``seed`` when
        given); returns its first observation."""
        if seed is not None:
            self.seed = int(seed)
            self._native.reseed(self.seed)
        self._native.reset()
        return self.get_observation()

    def reset_to(self, state: Union[np.ndarray, Mapping[str, Any]]) -> Dict[str, np.ndarray]:
        """Restores a flattened state (a dataset's ``states`` row, or robomimic's ``{"states":
        ...}``); returns its observation. A ``model`` in the dict must be this environment's
        scene (another scene is refused: build an ``Env`` for it)."""
        if isinstance(state, Mapping):
            model = state.get("model")
            if model is not None and model != self._native.model_xml():
                raise _native.MimicgenError("state: model: another scene than this environment's; make an Env of that dataset's env_args")
            state = state["states"]
        self._native.reset_to(np.asarray(state, dtype=np.float64).ravel().tolist())
        return self.get_observation()

    def step(self, action: Sequence[float]) -> Tuple[Dict[str, np.ndarray], float, bool, Dict[str, Any]]:
        """One control step (20 Hz); returns ``(obs, reward, done, info)``."""
        self._native.step(np.asarray(action, dtype=np.float64).ravel().tolist())
        success = self._native.is_success()
        return self.get_observation(), float(success), False, {"success": success}

    def get_observation(self) -> Dict[str, np.ndarray]:
        """Observations by key: the low-dim ones (float64) and, with cameras, ``<camera>_image``
        (uint8, height x width x 3, upright as our datasets store them)."""
        return dict(self._native.observation())

    def is_success(self) -> bool:
        """Whether the task is achieved now."""
        return self._native.is_success()

    def subtask_signals(self) -> Dict[str, int]:
        """The subtask-end signals now (``{"grasp": 1}``)."""
        return dict(self._native.subtask_signals())

    def get_state(self) -> Dict[str, Any]:
        """``{"states": flattened state, "model": the scene's MJCF}``, as robomimic's."""
        return {"states": self._native.state(), "model": self._native.model_xml()}

    def object_instance(self) -> Optional[str]:
        """The object instance drawn for this episode, under object transfer (``None`` otherwise)."""
        return self._native.object_instance()

    def render(self, camera_name: str = "agentview", height: int = 256, width: int = 256) -> np.ndarray:
        """An image of the present state (uint8, height x width x 3). A camera this environment
        does not observe with is drawn by a second environment of the same scene set to this
        state (made at the first call)."""
        if camera_name in self.cameras and (height, width) == self.camera_size:
            return self.get_observation()[f"{camera_name}_image"]
        key = (camera_name, int(height), int(width))
        twin = self._render_twin.get(key)
        if twin is None:
            twin = Env(self.task, self.variant, robot=self.robot, cameras=[camera_name], camera_size=(int(height), int(width)))
            self._render_twin[key] = twin
        return twin.reset_to(self._native.state())[f"{camera_name}_image"]

    def __repr__(self) -> str:
        return f"Env({self.task!r}, {self.variant!r}, robot={self.robot!r}, seed={self.seed})"
