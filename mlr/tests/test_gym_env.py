"""mlr.gym.env.MagnaNavEnv: Gymnasium's checker, seeding, and episodes that end as the reward says."""
from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from magna_uav.nai.inputs import input_names
from mlr.gym.env import MagnaNavEnv
from mlr.gym.scenario import load_scenario
from tests.support import CORPUS


@pytest.fixture(scope="module")
def central():
    return load_scenario("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [CORPUS])


@pytest.fixture
def env(central):
    made = MagnaNavEnv(scenario=central, max_steps=50)
    yield made
    made.close()


def test_gymnasiums_checker_passes(env):
    check_env(env, skip_render_check=True)


def test_the_same_seed_gives_the_same_episode_and_another_seed_another(env):
    def episode(seed):
        observation, info = env.reset(seed=seed)
        rewards = []
        for k in range(15):
            observation, reward, terminated, truncated, _ = env.step(np.array([1.0, 0.5 * np.sin(k), 0.0]))
            rewards.append(reward)
            if terminated or truncated:
                break
        return info["goal"], observation, rewards

    first, again, other = episode(11), episode(11), episode(12)
    np.testing.assert_array_equal(first[0], again[0])
    np.testing.assert_array_equal(first[1], again[1])
    assert first[2] == again[2]
    assert not np.array_equal(first[0], other[0])


def test_the_observation_is_the_nais_path_vector(env):
    observation, info = env.reset(seed=3)
    names = input_names("path", 1, 2)
    assert observation.shape == (len(names),) and observation.dtype == np.float32
    value = dict(zip(names, observation.tolist(), strict=True))
    start = env.scenario.uavs[0].start + [0.0, 0.0, env.scenario.take_off_height]
    np.testing.assert_allclose([value[f"goal_pose_rel.{a}"] for a in "xyz"], info["goal"] - start, atol=1e-5)
    np.testing.assert_allclose([value[f"others_pos_rel[0].{a}"] for a in "xyz"], [5.0, 0.0, 0.0], atol=1e-5)
    assert [value[f"own_vel.{a}"] for a in "xyz"] == [0.0, 0.0, 0.0]


def test_flying_into_a_sphere_ends_the_episode_with_the_collision_penalty(env, central):
    env.reset(seed=5)
    sphere = central.solids[0]
    env.swarm.place(np.array([sphere.position - [1.2, 0.0, 0.0], [6.0, 6.0, 3.0]]))
    for _ in range(40):
        _, reward, terminated, truncated, info = env.step(np.array([2.0, 0.0, 0.0], dtype=np.float32))
        assert reward == pytest.approx(sum(info["reward_terms"].values()))
        if terminated:
            break
    assert terminated and not truncated and info["collided"] and not info["reached"]
    assert info["reward_terms"]["collision"] == -env.weights.collision_penalty


def test_an_episode_is_truncated_after_max_steps(env):
    env.reset(seed=8)
    for step in range(1, 51):
        _, _, terminated, truncated, _ = env.step(np.zeros(3, dtype=np.float32))  # hover: neither goal nor crash
        assert not terminated
        assert truncated == (step == 50)


def test_the_optional_depth_image_sees_the_uav_ahead_and_passes_the_checker(central):
    from gymnasium.utils.env_checker import check_env

    made = MagnaNavEnv(scenario=central, max_steps=20, depth=(64, 48))
    try:
        assert made.observation_space["depth"].shape == (48, 64)
        check_env(made, skip_render_check=True)
        made.reset(seed=2)
        made.swarm.place(np.array([[-6.0, 6.0, 3.0], [-4.0, 6.0, 3.0]]))  # UAV 2 2 m ahead along +x (yaw 0)
        observation, *_ = made.step(np.zeros(3, dtype=np.float32))
        depth = observation["depth"]
        assert depth.dtype == np.float32 and depth.shape == (48, 64)
        # the other UAV's body, a 0.3 m-radius disc seen edge on at the horizon: its near rim, 1.7 m away
        assert 1.5 < float(depth[20:28, 24:40].min()) < 2.0
        assert float(depth[0, 0]) == 20.0  # nothing there within 20 m: the NAI's far value
        np.testing.assert_array_equal(observation["vector"], made.swarm.observation(0))
    finally:
        made.close()
