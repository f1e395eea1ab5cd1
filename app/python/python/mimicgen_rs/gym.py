"""Our simulator as a gymnasium environment::

    import gymnasium as gym
    import mimicgen_rs.gym

    env = gym.make("mimicgen_rs/Stack_D1-v0")        # or mimicgen_rs.gym.MimicGenEnv("stack", "D1")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

Every task and variant is registered as ``mimicgen_rs/<EnvName>_<Variant>-v0`` (the environment
names of our datasets' ``env_args``, ``mimicgen tasks`` lists them) when this module is imported.
Observations are a dict of the keys our datasets hold (``obs_keys`` picks some; camera images with
``cameras``); an episode terminates on success (reward 1) and is truncated at ``max_episode_steps``
(default 400, the reference's evaluation horizon for most tasks). The same ``reset(seed=...)``
gives the same scenes.
"""

from __future__ import annotations

from typing import Any, Dict, Optional, Sequence, Tuple, Union

import gymnasium
import numpy as np
from gymnasium import spaces

from . import _native
from .env import Env


class MimicGenEnv(gymnasium.Env):
    """A gymnasium ``Env`` on :class:`mimicgen_rs.Env` (``task``, ``variant``, ``robot``,
    ``cameras``, ``camera_size`` as there). Actions are in [-1, 1] (delta pose, gripper; a mobile
    base's three after them)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        task: str = "stack",
        variant: Optional[str] = None,
        *,
        robot: Optional[str] = None,
        cameras: Optional[Sequence[str]] = None,
        camera_size: Union[int, Tuple[int, int]] = 84,
        obs_keys: Optional[Sequence[str]] = None,
        render_mode: Optional[str] = None,
        render_size: Tuple[int, int] = (256, 256),
    ) -> None:
        self.env = Env(task, variant, robot=robot, cameras=cameras, camera_size=camera_size, seed=0)
        self.render_mode = render_mode
        self.render_size = render_size
        first = self.env.reset()
        unknown = [k for k in obs_keys or [] if k not in first]
        if unknown:
            raise _native.MimicgenError(f"obs_keys: {unknown} not observed; the keys are {sorted(first)}")
        self.obs_keys = list(obs_keys) if obs_keys else sorted(first)
        self.observation_space = spaces.Dict(
            {
                k: spaces.Box(0, 255, first[k].shape, np.uint8)
                if first[k].dtype == np.uint8
                else spaces.Box(-np.inf, np.inf, first[k].shape, np.float64)
                for k in self.obs_keys
            }
        )
        self.action_space = spaces.Box(-1.0, 1.0, (self.env.action_dim,), np.float32)

    def _obs(self, raw: Dict[str, np.ndarray]) -> Dict[str, np.ndarray]:
        return {k: raw[k] for k in self.obs_keys}

    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None):
        super().reset(seed=seed)
        obs = self.env.reset(seed=seed)
        return self._obs(obs), {"object_instance": self.env.object_instance()}

    def step(self, action):
        obs, reward, _, info = self.env.step(np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0))
        return self._obs(obs), reward, bool(info["success"]), False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return self.env.render("agentview", *self.render_size)


def _register() -> None:
    tasks = _native_tasks()
    for task in tasks:
        for variant in task["variants"]:
            env_id = f"mimicgen_rs/{task['env_name']}_{variant}-v0"
            if env_id in gymnasium.registry:
                continue
            gymnasium.register(
                id=env_id,
                entry_point="mimicgen_rs.gym:MimicGenEnv",
                kwargs={"task": task["name"], "variant": variant},
                max_episode_steps=400,
            )


def _native_tasks():
    import json

    return json.loads(_native.tasks())["tasks"]


_register()
