"""Our simulator as a robomimic environment, so robomimic's own scripts train on our datasets and
roll policies out in our scenes::

    python -m mimicgen_rs.robomimic train --config bc_rnn.json --dataset stack_d1.hdf5
    python -m mimicgen_rs.robomimic run_trained_agent --agent model_epoch_100.pth --n_rollouts 50

Each runs robomimic's script of that name (``robomimic.scripts.train``,
``robomimic.scripts.run_trained_agent``, ...) unchanged, after :func:`register`.

How robomimic picks the environment: it reads the dataset's (or checkpoint's) ``env_args`` and
builds the class its ``type`` names (``EnvType``: 1 robosuite, 2 gym, 3 iGibson). Our datasets
say type 1 with MimicGen's environment names (``Stack_D1``), so robosuite and the reference
MimicGen tools read them unchanged. :func:`register` teaches robomimic a fourth type,
``EnvType.MIMICGEN_RS_TYPE`` (:data:`MIMICGEN_RS_TYPE`), built as :class:`EnvMimicGenRs`, and
makes robomimic read type 1 metadata whose environment is one of our tasks as that type: from
then on in the process, rollouts of our tasks run in our simulator, and other environments are
built as before. Metadata that says type 101 itself is ours with or without that rule.
"""

from __future__ import annotations

import runpy
import sys
from copy import deepcopy
from typing import Any, Dict, Optional

import numpy as np

import robomimic.envs.env_base as EB
import robomimic.utils.env_utils as EnvUtils
import robomimic.utils.obs_utils as ObsUtils

from . import __version__, _native
from .env import Env

#: The ``type`` robomimic's environment metadata gives our environment.
MIMICGEN_RS_TYPE = 101


def _ours(env_name: str) -> bool:
    try:
        _native.task_from_env_name(env_name)
    except _native.MimicgenError:
        return False
    return True


class EnvMimicGenRs(EB.EnvBase):
    """robomimic's ``EnvBase`` on :class:`mimicgen_rs.Env`. Built by robomimic from metadata:
    ``env_name`` (``Stack_D1``) names the task and variant, ``env_kwargs`` the arm (``robots``),
    the cameras (``camera_names``, ``camera_heights``, ``camera_widths``, used when robomimic
    asks for image observations) and ``seed`` (default: a draw from numpy's global generator,
    which robomimic's scripts seed, so the same seed gives the same rollouts)."""

    def __init__(
        self,
        env_name: str,
        render: bool = False,
        render_offscreen: bool = False,
        use_image_obs: bool = False,
        postprocess_visual_obs: bool = True,
        **kwargs: Any,
    ) -> None:
        self._env_name = env_name
        self._init_kwargs = deepcopy(kwargs)
        self.postprocess_visual_obs = postprocess_visual_obs
        robots = kwargs.get("robots")
        robot = (robots[0] if isinstance(robots, (list, tuple)) else robots) if robots else None
        cameras = None
        size: Any = 84
        if use_image_obs:
            names = kwargs.get("camera_names") or ["agentview", "robot0_eye_in_hand"]
            cameras = [names] if isinstance(names, str) else list(names)
            height, width = kwargs.get("camera_heights", 84), kwargs.get("camera_widths", 84)
            size = (height[0] if isinstance(height, list) else height, width[0] if isinstance(width, list) else width)
        seed = kwargs.get("seed")
        if seed is None:
            seed = int(np.random.randint(0, 2**31 - 1))
        task, variant = _native.task_from_env_name(env_name)
        self.env = Env(task, variant, robot=robot, cameras=cameras, camera_size=size, seed=int(seed))
        self._current_obs: Optional[Dict[str, np.ndarray]] = None

    def step(self, action):
        obs, reward, done, info = self.env.step(action)
        return self.get_observation(obs), reward, self.is_done(), info

    def reset(self):
        return self.get_observation(self.env.reset())

    def reset_to(self, state):
        if "states" not in state:
            return None
        return self.get_observation(self.env.reset_to(state))

    def render(self, mode="human", height=None, width=None, camera_name="agentview"):
        if mode != "rgb_array":
            raise NotImplementedError(f"render mode {mode!r}: EnvMimicGenRs draws offscreen only (mode='rgb_array')")
        return self.env.render(camera_name or "agentview", height or 256, width or 256)

    def get_observation(self, di=None):
        raw = self.env.get_observation() if di is None else di
        out: Dict[str, np.ndarray] = {}
        for key, value in raw.items():
            if key.endswith("_image"):
                value = np.ascontiguousarray(value)
                if self.postprocess_visual_obs and key in ObsUtils.OBS_KEYS_TO_MODALITIES:
                    value = ObsUtils.process_obs(obs=value, obs_key=key)
            out[key] = value
        return out

    def get_state(self):
        return self.env.get_state()

    def get_reward(self):
        return float(self.env.is_success())

    def get_goal(self):
        raise NotImplementedError("our tasks have no goal observations")

    def set_goal(self, **kwargs):
        raise NotImplementedError("our tasks have no goal observations")

    def is_done(self):
        return False

    def is_success(self):
        return {"task": self.env.is_success()}

    @property
    def action_dimension(self):
        return self.env.action_dim

    @property
    def name(self):
        return self._env_name

    @property
    def type(self):
        return MIMICGEN_RS_TYPE

    @property
    def version(self):
        return __version__

    @property
    def base_env(self):
        return self.env

    def serialize(self):
        return dict(env_name=self.name, type=self.type, env_kwargs=deepcopy(self._init_kwargs))

    @classmethod
    def create_for_data_processing(cls, env_name, camera_names, camera_height, camera_width, reward_shaping, **kwargs):
        kwargs = dict(kwargs, camera_names=camera_names, camera_heights=camera_height, camera_widths=camera_width)
        return cls(env_name=env_name, render=False, render_offscreen=bool(camera_names), use_image_obs=bool(camera_names), postprocess_visual_obs=False, **kwargs)

    @property
    def rollout_exceptions(self):
        return (_native.MimicgenError,)

    def __repr__(self):
        return f"EnvMimicGenRs({self._env_name!r}, {self.env!r})"


_registered = False


def register() -> None:
    """Teach robomimic (in this process) to build :class:`EnvMimicGenRs` for metadata of type
    :data:`MIMICGEN_RS_TYPE`, and for type 1 (robosuite) metadata naming one of our tasks.
    Calling it again does nothing."""
    global _registered
    if _registered:
        return
    EB.EnvType.MIMICGEN_RS_TYPE = MIMICGEN_RS_TYPE
    robomimic_class = EnvUtils.get_env_class
    robomimic_type = EnvUtils.get_env_type

    def get_env_type(env_meta=None, env_type=None, env=None):
        found = robomimic_type(env_meta=env_meta, env_type=env_type, env=env)
        if env_meta is not None and found == EB.EnvType.ROBOSUITE_TYPE and _ours(str(env_meta.get("env_name", ""))):
            return MIMICGEN_RS_TYPE
        return found

    def get_env_class(env_meta=None, env_type=None, env=None):
        if get_env_type(env_meta=env_meta, env_type=env_type, env=env) == MIMICGEN_RS_TYPE:
            return EnvMimicGenRs
        return robomimic_class(env_meta=env_meta, env_type=env_type, env=env)

    EnvUtils.get_env_type = get_env_type
    EnvUtils.get_env_class = get_env_class
    _registered = True


SCRIPTS = ("train", "run_trained_agent", "playback_dataset", "get_dataset_info", "split_train_val", "dataset_states_to_obs")


def main(argv: Optional[list] = None) -> None:
    """``python -m mimicgen_rs.robomimic SCRIPT ARGS...``: robomimic's ``robomimic/scripts/SCRIPT.py``
    with our environment registered."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help") or args[0] not in SCRIPTS:
        print(
            "usage: python -m mimicgen_rs.robomimic SCRIPT [ARGS...]\n\n"
            "Runs robomimic's own script SCRIPT (" + ", ".join(SCRIPTS) + ") with our simulator registered,\n"
            "so rollouts of our tasks run in it. ARGS are the script's: see\n"
            "  python -m mimicgen_rs.robomimic SCRIPT --help\n\n"
            "examples:\n"
            "  python -m mimicgen_rs.robomimic train --config bc_rnn.json --dataset stack_d1.hdf5\n"
            "  python -m mimicgen_rs.robomimic run_trained_agent --agent model.pth --n_rollouts 50 --horizon 400 --seed 1",
            file=sys.stderr if args and args[0] not in ("-h", "--help") else sys.stdout,
        )
        sys.exit(0 if args and args[0] in ("-h", "--help") else 2)
    register()
    script = args[0]
    sys.argv = [f"robomimic/scripts/{script}.py", *args[1:]]
    runpy.run_module(f"robomimic.scripts.{script}", run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main()
