"""mlr.gym.parallel.MagnaNavParallelEnv: PettingZoo's API test, seeding, and agents that end on their own."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from mlr.gym.parallel import MagnaNavParallelEnv
from mlr.gym.scenario import load_scenario
from tests.support import CORPUS


@pytest.fixture(scope="module")
def central():
    return load_scenario("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [CORPUS])


@pytest.fixture
def env(central):
    made = MagnaNavParallelEnv(scenario=central, max_steps=40)
    yield made
    made.close()


def test_pettingzoos_parallel_api_test_passes(env):
    parallel_api_test(env, num_cycles=60)


def test_agents_are_the_missions_uavs_and_a_seed_repeats_their_episode(env):
    def episode(seed):
        observations, infos = env.reset(seed=seed)
        assert env.agents == ["uav_1", "uav_2"]
        trace = []
        for k in range(10):
            actions = {name: np.array([0.5, np.cos(k), 0.2 * i], dtype=np.float32)
                       for i, name in enumerate(env.agents)}
            observations, rewards, *_ = env.step(actions)
            trace.append((observations["uav_1"].copy(), rewards["uav_2"]))
        return infos, trace

    first, again, other = episode(4), episode(4), episode(5)
    np.testing.assert_array_equal(first[0]["uav_2"]["goal"], again[0]["uav_2"]["goal"])
    for (obs_a, reward_a), (obs_b, reward_b) in zip(first[1], again[1], strict=True):
        np.testing.assert_array_equal(obs_a, obs_b)
        assert reward_a == reward_b
    assert not np.array_equal(first[0]["uav_1"]["goal"], other[0]["uav_1"]["goal"])


def test_two_uavs_flying_into_each_other_both_end_and_leave_the_agent_list(env):
    env.reset(seed=1)
    env.swarm.place(np.array([[-1.5, 6.0, 3.0], [1.5, 6.0, 3.0]]))  # head on, clear of the spheres
    actions = {"uav_1": np.array([2.0, 0.0, 0.0], dtype=np.float32),
               "uav_2": np.array([-2.0, 0.0, 0.0], dtype=np.float32)}
    for _ in range(20):
        _, rewards, terminations, _, infos = env.step(actions)
        if any(terminations.values()):
            break
    assert terminations == {"uav_1": True, "uav_2": True}
    assert all(infos[name]["collided"] for name in ("uav_1", "uav_2"))
    assert all(rewards[name] < -env.weights.collision_penalty / 2 for name in ("uav_1", "uav_2"))
    assert env.agents == []



def test_overlapping_safety_spheres_collide_as_the_uav_managers_evaluator_counts_it(central):
    # An airframe whose safety sphere (0.6 m) is wider than its body: at 1.0 m apart the bodies are clear
    # of each other, the safety spheres are not, and the stack's evaluator would count a collision.
    wide = tuple(dataclasses.replace(uav, airframe=dataclasses.replace(uav.airframe, safety_radius=0.6))
                 for uav in central.uavs)
    env = MagnaNavParallelEnv(scenario=dataclasses.replace(central, uavs=wide), max_steps=40)
    try:
        hover = np.zeros((1, 2, 3))
        env.reset(seed=1)
        env.swarm.place(np.array([[0.0, 6.0, 3.0], [1.0, 6.0, 3.0]]))
        assert not env.swarm.fleet.control_step(hover)  # no physical contact in the simulator
        env.swarm.place(np.array([[0.0, 6.0, 3.0], [1.0, 6.0, 3.0]]))
        _, _, terminations, _, infos = env.step({name: hover[0, 0] for name in env.agents})
        assert terminations == {"uav_1": True, "uav_2": True}
        assert all(infos[name]["collided"] and infos[name]["reward_terms"]["collision"] < 0 for name in infos)

        env.reset(seed=1)
        env.swarm.place(np.array([[0.0, 6.0, 3.0], [1.3, 6.0, 3.0]]))  # a 0.1 m gap: inside the near-miss margin
        _, _, terminations, _, infos = env.step({name: hover[0, 0] for name in env.agents})
        assert terminations == {"uav_1": False, "uav_2": False}
        assert all(infos[name]["reward_terms"]["near_miss"] < 0 for name in infos)
    finally:
        env.close()


def test_with_depth_images_every_agent_gets_its_own_and_the_api_test_passes(central):
    env = MagnaNavParallelEnv(scenario=central, max_steps=20, depth=(16, 12))
    try:
        parallel_api_test(env, num_cycles=20)
        observations, _ = env.reset(seed=3)
        assert all(observations[name]["depth"].shape == (12, 16) for name in env.agents)
        env.swarm.place(np.array([[-6.0, 6.0, 3.0], [6.0, 6.0, 3.0]]))
        observations, *_ = env.step({name: np.zeros(3, dtype=np.float32) for name in env.agents})
        # both look along +x: the second sees only the sky and the ground; the first also the central obstacle
        assert not np.array_equal(observations["uav_1"]["depth"], observations["uav_2"]["depth"])
    finally:
        env.close()
