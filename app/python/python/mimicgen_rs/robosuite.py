"""robosuite environments as simulators the Rust engine drives (``generate(..., env=...)``),
the way the reference MimicGen's robosuite interface reads them: the end effector at the
gripper's grip site, objects at their root bodies, OSC_POSE delta actions scaled by the
controller's output limits, states as MuJoCo's flattened state.

    import mimicgen_rs as mg, mimicgen_rs.robosuite as mgrs
    mg.generate("stack.hdf5", env=mgrs.stack, source="source_D0_prepared.hdf5",
                config="config_D0.json", num_demos=50).wait()

Needs robosuite 1.4 and its MuJoCo (2.3.x) in the same environment as this package.
"""

from typing import Callable, Dict

import numpy as np

from .geometry import delta_action, delta_target, make_pose


class RobosuiteEnv:
    """A robosuite environment (one arm, OSC_POSE delta control) as an ``Environment``.

    ``objects`` maps the spec's object names to attributes of the robosuite env holding object
    models (``{"cubeA": "cubeA"}``); ``signals`` maps subtask-end signal names to functions of the
    robosuite env returning 0 or 1.
    """

    def __init__(self, env, objects: Dict[str, str], signals: Dict[str, Callable[[object], int]]):
        self.env = env
        self.objects = objects
        self.signals = signals
        controller = env.robots[0].controller
        self.max_dpos = float(controller.output_max[0])
        self.max_drot = float(controller.output_max[3])
        self.site = env.sim.model.site_name2id(controller.eef_name)

    def action_dim(self) -> int:
        return int(self.env.action_dim)

    def reset(self, seed: int) -> None:
        # robosuite's placement samplers draw from numpy's global generator.
        np.random.seed(seed % 2**32)
        self.env.reset()

    def eef_pose(self) -> np.ndarray:
        data = self.env.sim.data
        return make_pose(np.array(data.site_xpos[self.site]), np.array(data.site_xmat[self.site]).reshape(3, 3))

    def object_poses(self) -> Dict[str, np.ndarray]:
        sim = self.env.sim
        poses = {}
        for name, attribute in self.objects.items():
            body = sim.model.body_name2id(getattr(self.env, attribute).root_body)
            poses[name] = make_pose(np.array(sim.data.body_xpos[body]), np.array(sim.data.body_xmat[body]).reshape(3, 3))
        return poses

    def subtask_term_signals(self) -> Dict[str, int]:
        return {name: int(f(self.env)) for name, f in self.signals.items()}

    def is_success(self) -> bool:
        return bool(self.env._check_success())

    def target_pose_to_action(self, target) -> np.ndarray:
        return delta_action(self.eef_pose(), np.asarray(target), self.max_dpos, self.max_drot)

    def action_to_target_pose(self, action) -> np.ndarray:
        return delta_target(self.eef_pose(), action, self.max_dpos, self.max_drot)

    def step(self, action) -> None:
        self.env.step(np.asarray(action, dtype=float))

    def get_state(self) -> np.ndarray:
        return np.array(self.env.sim.get_state().flatten())

    def set_state(self, state) -> None:
        self.env.sim.set_state_from_flattened(np.asarray(state, dtype=float))
        self.env.sim.forward()

    def observations(self) -> Dict[str, np.ndarray]:
        """robosuite's own low-dimensional observations of the current state."""
        obs = self.env._get_observations(force_update=True)
        return {k: np.asarray(v, dtype=float) for k, v in obs.items() if np.ndim(v) == 1}


def stack(**make_kwargs) -> RobosuiteEnv:
    """robosuite's Stack (Panda, OSC_POSE at 20 Hz, no rendering), with Stack's objects and its
    ``grasp`` signal as MimicGen defines them."""
    import robosuite
    from robosuite.controllers import load_controller_config

    options = dict(
        robots=["Panda"],
        controller_configs=load_controller_config(default_controller="OSC_POSE"),
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        ignore_done=True,
        reward_shaping=False,
        control_freq=20,
    )
    options.update(make_kwargs)
    env = robosuite.make("Stack", **options)
    grasp = lambda e: e._check_grasp(gripper=e.robots[0].gripper, object_geoms=e.cubeA)  # noqa: E731
    return RobosuiteEnv(env, objects={"cubeA": "cubeA", "cubeB": "cubeB"}, signals={"grasp": grasp})
