"""mlr.gym.vector.SwarmVecEnv: every UAV of K copies as a sub-environment of a stable-baselines3 VecEnv."""
from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecMonitor

from mlr.gym.scenario import load_scenario
from mlr.gym.vector import SwarmVecEnv
from tests.support import CORPUS


@pytest.fixture(scope="module")
def central():
    return load_scenario("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [CORPUS])


@pytest.fixture
def venv(central):
    made = SwarmVecEnv(central, copies=3, max_steps=30)
    yield made
    made.close()


def test_sub_environments_are_the_uavs_of_every_copy(venv):
    assert venv.num_envs == 6
    observations = venv.reset()
    assert observations.shape == (6, venv.observation_space.shape[0]) and observations.dtype == np.float32
    # UAV 2 sits 5 m along +x of UAV 1 in every copy, whatever the copy's offset in the world
    for c in range(3):
        np.testing.assert_allclose(observations[2 * c, 6:9], [5.0, 0.0, 0.0], atol=1e-5)  # others_pos_rel[0]


def test_a_seed_repeats_the_goals_of_every_copy(venv):
    def goals(seed):
        venv.seed(seed)
        venv.reset()
        return np.array([venv.swarm.goal(j, c) for c in range(3) for j in range(2)])

    first, again, other = goals(7), goals(7), goals(8)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)
    assert len({tuple(g) for g in first[::2]}) == 3  # the copies differ from each other


def test_a_touch_ends_the_episodes_of_that_copy_only(venv, central):
    venv.reset()
    sphere = central.solids[0]
    venv.swarm.place(np.array([sphere.position - [1.2, 0.0, 0.0], [6.0, 6.0, 3.0]]), copy=1)
    actions = np.zeros((6, 3))
    actions[2] = [2.0, 0.0, 0.0]  # copy 1, UAV 1: into the sphere
    for _ in range(20):
        observations, rewards, dones, infos = venv.step(actions)
        if dones.any():
            break
    assert dones.tolist() == [False, False, True, True, False, False]
    assert infos[2]["collided"] and not infos[2]["TimeLimit.truncated"]
    assert infos[3]["TimeLimit.truncated"] and not infos[3]["collided"]  # cut short by the other's crash
    assert rewards[2] < -venv.weights.collision_penalty / 2
    assert "terminal_observation" in infos[2] and "terminal_observation" not in infos[0]
    # copy 1 started again: UAV 1 hovers at its take-off point, 5 m from UAV 2
    np.testing.assert_allclose(observations[2, 6:9], [5.0, 0.0, 0.0], atol=1e-5)


def test_reaching_a_goal_pays_the_bonus_and_the_uav_flies_on_to_the_next_in_the_same_episode(venv):
    venv.reset()
    goal = venv.swarm.goal(0, 0).copy()
    venv.swarm.place(np.array([goal - [0.6, 0.0, 0.0], goal + [4.0, 4.0, 0.0]]), copy=0)
    actions = np.zeros((6, 3))
    actions[0] = [1.0, 0.0, 0.0]
    for _ in range(10):
        _, rewards, dones, infos = venv.step(actions)
        if infos[0]["reached"]:
            break
    assert infos[0]["reached"] and rewards[0] > venv.weights.goal_bonus / 2
    assert not dones.any()  # the episode goes on, towards the next goal
    assert not np.array_equal(venv.swarm.goal(0, 0), goal)
    _, rewards, _, infos = venv.step(actions)
    assert not infos[0]["reached"] and rewards[0] < venv.weights.goal_bonus / 2  # the bonus is paid once


def test_episodes_are_truncated_after_max_steps_and_vecmonitor_counts_them(venv):
    monitored = VecMonitor(venv)
    monitored.reset()
    for step in range(1, 31):
        _, _, dones, infos = monitored.step(np.zeros((6, 3)))  # all hover
        assert dones.any() == (step == 30)
    assert dones.all() and all(info["TimeLimit.truncated"] for info in infos)
    assert all(info["episode"]["l"] == 30 for info in infos)



def test_encounter_starts_put_two_uavs_on_a_collision_course():
    from magna_uav.nai.inputs import input_names
    from mlr.gym.swarm import Swarm

    four = load_scenario("Gym/Empty_4_Cylinders", "Gym/2UAVs_2paths_4_Cylinders", [CORPUS])  # UAVs, no obstacle
    names = input_names("path", 1, 0)
    goal = [names.index(f"goal_pose_rel.{axis}") for axis in "xyz"]
    lift = np.array([0.0, 0.0, four.take_off_height])
    take_off = np.array([uav.start + lift for uav in four.uavs])
    swarm = Swarm(four, 1, 0)

    def straight_flights(encounter):
        """(starts moved, collisions) over 12 episodes of both UAVs flying straight to their first goal."""
        moved = collided = 0
        for seed in range(12):
            swarm.start(seed, encounter=encounter)
            moved += not np.allclose(swarm.fleet.positions()[0], take_off, atol=0.05)
            for _ in range(60):
                if swarm.fly(2.0 * np.array([swarm.observation(j)[goal] for j in range(2)])):
                    collided += 1
                    break
                if min(swarm.distance(0), swarm.distance(1)) < 0.5:
                    break
        return moved, collided

    try:
        plain = straight_flights(False)
        assert plain[0] == 0 and plain[1] <= 2  # from the take-off points, first paths rarely meet
        moved, collided = straight_flights(True)
        assert moved >= 10 and collided >= moved - 2  # a start is kept only where there is no room for the course
    finally:
        swarm.close()


def test_the_share_of_encounters_is_checked():
    with pytest.raises(ValueError, match="encounters: 1.5 is the share"):
        SwarmVecEnv(None, encounters=1.5)
