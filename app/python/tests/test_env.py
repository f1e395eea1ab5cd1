"""Our simulator as an environment for policies (``mg.Env``, ``mimicgen_rs.gym``): the physics the
pipeline generated with, the observations our datasets hold, seeded resets, errors."""

import gymnasium
import numpy as np
import pytest

import mimicgen_rs as mg
import mimicgen_rs.gym  # noqa: F401  (registers the gymnasium ids)
from gymnasium.utils.env_checker import check_env


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    out = tmp_path_factory.mktemp("env") / "stack_d1.hdf5"
    mg.generate(out, task="stack", variant="D1", num_demos=2, guarantee=True, seed=3, workers=1).wait()
    return out


def test_stored_actions_replay_to_success_from_the_first_state(generated):
    ds = mg.Dataset(generated)
    env = mg.Env.from_dataset(generated)
    assert env.env_args["env_name"] == "Stack_D1"
    for name in ds.demo_names:
        demo = ds.demo(name)
        obs = env.reset_to({"states": demo["states"][0]})
        stored = {k[len("obs/"):]: v for k, v in demo.items() if k.startswith("obs/")}
        assert set(stored) <= set(obs), "the environment observes every key the dataset holds"
        for key, value in stored.items():
            np.testing.assert_allclose(obs[key], value[0], atol=1e-6, err_msg=key)
        successes = []
        for t, action in enumerate(demo["actions"]):
            if t == len(demo["actions"]) - 1:
                # states[t] is the state before action t: the replay reached the stored last one.
                np.testing.assert_allclose(env.get_state()["states"], demo["states"][t], atol=1e-6)
            _, reward, done, info = env.step(action)
            successes.append(info["success"])
            assert reward == float(info["success"]) and not done
        assert successes[-1], f"{name}: the generated demo succeeds when its actions are replayed in Env"


def test_the_same_seed_gives_the_same_scenes():
    a, b, c = mg.Env("square", "D1", seed=5), mg.Env("square", "D1", seed=5), mg.Env("square", "D1", seed=6)
    scenes_a = [a.reset()["object"] for _ in range(3)]
    scenes_b = [b.reset()["object"] for _ in range(3)]
    assert all(np.array_equal(x, y) for x, y in zip(scenes_a, scenes_b))
    assert not np.array_equal(scenes_a[0], c.reset()["object"])
    assert not np.array_equal(scenes_a[0], scenes_a[1]), "each reset draws a new scene"
    # reset(seed=...) restarts the stream.
    assert np.array_equal(a.reset(seed=5)["object"], scenes_a[0])


def test_bad_actions_and_names_are_errors_naming_the_field():
    env = mg.Env("stack", seed=0)
    env.reset()
    with pytest.raises(mg.MimicgenError, match=r"action: has 3 values; stack D0 takes 7"):
        env.step([0.0, 0.0, 0.0])
    with pytest.raises(mg.MimicgenError, match=r"action\[2\]: is NaN"):
        env.step([0, 0, float("nan"), 0, 0, 0, 0])
    with pytest.raises(mg.MimicgenError, match="unknown task"):
        mg.Env("no_such_task")
    with pytest.raises(mg.MimicgenError, match="two-arm"):
        mg.Env("two_arm_lift")
    with pytest.raises(mg.MimicgenError, match="not one of ours"):
        mg.Env.from_env_args({"env_name": "NoSuchEnv_D0", "type": 1, "env_kwargs": {}})


def test_render_draws_the_present_state():
    env = mg.Env("stack", seed=0)
    env.reset()
    before = env.render("agentview", 64, 64)
    assert before.shape == (64, 64, 3) and before.dtype == np.uint8
    for _ in range(20):
        env.step([0, 0, 1, 0, 0, 0, -1])  # the hand rises
    after = env.render("agentview", 64, 64)
    assert np.abs(after.astype(int) - before.astype(int)).sum() > 0


def test_gymnasium_env_passes_gymnasium_checks():
    env = gymnasium.make("mimicgen_rs/Stack_D1-v0", obs_keys=["robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object"])
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=1)
    again, _ = env.reset(seed=1)
    assert np.array_equal(obs["object"], again["object"])
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert set(obs) == {"robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object"}
    assert (reward, terminated, truncated) == (0.0, False, False)
    assert env.spec.max_episode_steps == 400
