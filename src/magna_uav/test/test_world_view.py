"""The UAV manager's picture of the world: nearest-first queries by gaps between safety spheres."""
import math

import numpy as np
import pytest

from magna_uav.world_view import AgentState, Obstacle, WorldView


def view_with(*others, obstacles=(), boundaries=None):
    view = WorldView(1, boundaries)
    view.update_agent(AgentState(1, [0, 0, 1], safety_radius=0.5))
    for other in others:
        view.update_agent(other)
    view.set_obstacles(obstacles)
    return view


def test_own_state_is_required_and_the_error_names_the_topic():
    with pytest.raises(LookupError, match="/uav_3/ual/pose"):
        _ = WorldView(3).own


def test_nearest_agents_sorted_by_gap_between_safety_spheres_ties_by_id():
    view = view_with(AgentState(4, [3, 0, 1], safety_radius=0.5), AgentState(2, [0, 3, 1], safety_radius=0.5),
                     AgentState(3, [0, 0, 3], safety_radius=1.5))
    found = [(state.id, round(gap, 9)) for state, gap in view.nearest_agents()]
    assert found == [(3, 0.0), (2, 2.0), (4, 2.0)]
    assert [s.id for s, _ in view.nearest_agents(k=2)] == [3, 2]
    assert [s.id for s, _ in view.nearest_agents(within=1.0)] == [3]
    assert [s.id for s in view.others()] == [2, 3, 4]


def test_nearest_obstacles_use_their_bounding_sphere():
    view = view_with(obstacles=[Obstacle("far", np.array([10.0, 0, 1]), 1.0),
                                Obstacle("near", np.array([0, 2.0, 1]), 1.0)])
    assert [(o.name, gap) for o, gap in view.nearest_obstacles()] == [("near", 0.5), ("far", 8.5)]


def test_boundaries_and_yaw():
    view = view_with(boundaries=[[-1, 1], [-1, 1], [0, 2]])
    assert view.inside_boundaries()
    assert not view.inside_boundaries([0, 0, 2.5])
    half = math.sqrt(0.5)
    assert AgentState(1, orientation=[0, 0, half, half]).yaw == pytest.approx(math.pi / 2)
