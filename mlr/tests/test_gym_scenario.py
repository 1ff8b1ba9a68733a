"""mlr.gym.scenario: the thesis's missions and worlds as a gym reads them (no ROS master)."""
from __future__ import annotations

import numpy as np
import pytest

from magna_worlds.shapes import contains
from mlr.gym.scenario import ScenarioError, load_scenario
from tests.support import CORPUS

CENTRAL = ("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder")


def test_the_central_obstacle_gives_its_uavs_starts_goals_obstacles_and_orca_parameters():
    scenario = load_scenario(*CENTRAL, [CORPUS])
    assert [u.id for u in scenario.uavs] == [1, 2]
    # the spawn_agents state's take-off poses, 2.5 m either side of the origin, on the ground
    np.testing.assert_allclose(scenario.uavs[0].start, [-2.5, 0.0, 0.05], atol=1e-6)
    np.testing.assert_allclose(scenario.uavs[1].start, [2.5, 0.0, 0.05], atol=1e-6)
    assert all(u.max_speed == 2.0 and u.safety_radius == 0.3 for u in scenario.uavs)
    assert scenario.take_off_height == 3.0
    names, values = scenario.orca_params
    assert dict(zip(names, values, strict=True))["agent_radius"] == 0.5
    # three spheres of 0.5 m diameter, as the managers hear them: bounding spheres of radius 0.25
    assert len(scenario.obstacles) == 3 and {o.radius for o in scenario.obstacles} == {0.25}
    assert [s.shape for s in scenario.solids] == ["sphere"] * 3
    np.testing.assert_allclose(scenario.boundaries, [[-9, 9]] * 3)


def test_goals_come_from_the_missions_path_definitions_and_repeat_by_seed():
    scenario = load_scenario(*CENTRAL, [CORPUS])
    uav = scenario.uavs[0]
    assert uav.goal_definitions[0].as_list()[:3] == ["CentralZone", "Accessible", "random"]
    goals = scenario.goals(uav, seed=3, count=6)
    assert goals.shape == (6, 3)
    np.testing.assert_array_equal(goals, scenario.goals(uav, seed=3, count=6))
    assert not np.allclose(goals, scenario.goals(uav, seed=4, count=6))
    # every goal lies inside the Accessible geometry, a torus around the obstacles, and none in its hole
    placed = scenario.world.geometry("CentralZone", "Accessible")
    assert placed.geometry.spec.shape == "torus"
    local = placed.frame.inverse().apply(goals)
    assert contains(placed.geometry.spec, local).all()
    assert not contains(placed.geometry.spec, [[0.0, 0.0, 0.0]]).any()


def test_an_unknown_world_is_refused_naming_where_it_looked():
    with pytest.raises(ScenarioError, match="Gym/No_Such_World"):
        load_scenario("Gym/No_Such_World", CENTRAL[1], [CORPUS])
