"""The evaluator on hand-made world views: gaps, collisions named and counted per episode, outcomes by priority."""
import math

import numpy as np
import pytest

from magna_uav.config import configs_from_mission
from magna_uav.evaluator import Evaluator
from magna_uav.manager import new_trouble, troubles
from magna_uav.shapes import Cylinder
from magna_uav.world_view import AgentState, Obstacle, WorldView

R = 0.3  # iris safety radius
BOUNDS = [[-10, 10], [-10, 10], [0, 10]]


def config(agent_id=1, model="iris"):
    entry = {"ID": agent_id, "model": model, "mode": "sitl", "marker_color": [255, 0, 0, 0.5]}
    return configs_from_mission([entry], "test.json")[0]


def view(own=(0, 0, 1), others=(), obstacles=(), battery=math.nan, boundaries=BOUNDS):
    v = WorldView(1, boundaries)
    v.update_agent(AgentState(1, position=own, battery=battery, safety_radius=R))
    for agent_id, position in others:
        v.update_agent(AgentState(agent_id, position=position, safety_radius=R))
    v.set_obstacles(Obstacle(name, np.array(position, float), radius) for name, position, radius in obstacles)
    return v


def test_gaps_to_every_agent_and_obstacle():
    e = Evaluator(config()).step(view(others=[(2, (3, 0, 1)), (3, (0, 2, 1))],
                                      obstacles=[("column", (0, 0, 6), 1.0), ("box", (-4, 0, 1), 0.5)]))
    assert e.agent_gaps == pytest.approx({2: 3 - 2 * R, 3: 2 - 2 * R})
    assert e.obstacle_gaps == pytest.approx({"column": 5 - 1 - R, "box": 4 - 0.5 - R})
    assert e.nearest_agent_gap == pytest.approx(2 - 2 * R)
    assert e.nearest_obstacle_gap == pytest.approx(4 - 0.5 - R)
    assert e.outcome is None and e.safe and e.collided_with == [] and not e.out_of_bounds


def test_alone_in_an_empty_world_the_gaps_are_infinite():
    e = Evaluator(config()).step(view())
    assert e.agent_gaps == {} and e.nearest_agent_gap == math.inf and e.nearest_obstacle_gap == math.inf
    assert e.outcome is None


def test_collision_names_the_uav_and_the_obstacle_nearest_first():
    # touching (gap exactly 0) is not yet a collision; uav_3 overlaps by 0.1 m, the pillar by 0.2 m
    e = Evaluator(config()).step(view(others=[(2, (2 * R, 0, 1)), (3, (0, 2 * R - 0.1, 1))],
                                      obstacles=[("pillar", (0, 0, 1 + R + 0.8), 1.0)]))
    assert e.collided_with == ["pillar", "uav_3"]
    assert e.outcome == "collision"
    assert "pillar (gap -0.20 m)" in e.reason and "uav_3 (gap -0.10 m)" in e.reason and "uav_2" not in e.reason


def test_a_collision_is_counted_once_per_contact_episode():
    ev = Evaluator(config(), release_gap=0.05)
    for gap in (1.0, -0.1, -0.2, -0.05, 0.02, -0.01, 0.5, -0.1, 0.3):  # gap between the spheres of uav_1 and uav_2
        ev.step(view(others=[(2, (2 * R + gap, 0, 1))]))
    # episode 1: -0.1 .. -0.01 (0.02 is within the release gap); episode 2: the -0.1 after 0.5
    assert ev.collisions == {"uav_2": 2} and ev.collision_count == 2
    assert ev.min_agent_gap == pytest.approx(-0.2) and ev.steps == 9


def test_a_contact_stays_open_until_its_gap_opens_past_the_release_gap():
    ev = Evaluator(config(), release_gap=0.05)
    open_episodes = [ev.step(view(others=[(2, (2 * R + gap, 0, 1))])).in_contact
                     for gap in (0.2, -0.02, 0.03, -0.01, 0.08, 0.02)]
    assert open_episodes == [[], ["uav_2"], ["uav_2"], ["uav_2"], [], []]


def test_a_role_started_just_out_of_contact_is_not_ended_by_the_gap_flickering_around_zero():
    """Two hovering UAVs just apart when a role starts, their gap dipping below zero and back (the
    rostest's head-on flight saw it): until the gap opens past the release gap, it is the contact
    the role started in, and only a new contact after it ends the role."""
    ev = Evaluator(config(), release_gap=0.05)

    def step(gap):
        return ev.step(view(others=[(2, (2 * R + gap, 0, 1))]))

    step(-0.1)  # the contact that stopped the last role
    standing = troubles(step(0.03))  # the next role starts just out of contact
    assert [new_trouble(step(gap), standing) for gap in (-0.02, 0.04, -0.01)] == [None, None, None]
    assert new_trouble(step(0.3), standing) is None  # apart: the contact is over
    assert new_trouble(step(-0.02), standing) == "collision"


def test_contacts_with_different_things_count_separately():
    ev = Evaluator(config())
    ev.step(view(others=[(2, (0.5, 0, 1))], obstacles=[("wall", (0, 0.5, 1), 0.3)]))
    ev.step(view(others=[(2, (0.5, 0, 1))], obstacles=[("wall", (0, 0.5, 1), 0.3)]))
    assert ev.collisions == {"uav_2": 1, "wall": 1}
    ev.reset()
    assert ev.collision_count == 0 and ev.steps == 0


def test_out_of_bounds_is_aborted_and_counted_per_exit():
    ev = Evaluator(config())
    outside = ev.step(view(own=(10.5, 0, 1)))
    assert outside.out_of_bounds and outside.outcome == "aborted"
    assert "out of the world boundaries at (10.50, 0.00, 1.00)" in outside.reason
    ev.step(view(own=(11, 0, 1)))
    ev.step(view(own=(9, 0, 1)))
    ev.step(view(own=(0, 0, -0.5)))
    assert ev.out_of_bounds_episodes == 2
    assert ev.step(view(own=(50, 0, 1), boundaries=None)).outcome is None  # a world without boundaries


def test_low_battery_only_when_known_and_below_the_threshold():
    ev = Evaluator(config(), low_battery=0.2)
    assert ev.step(view(battery=math.nan)).outcome is None
    assert ev.step(view(battery=0.2)).outcome is None
    low = ev.step(view(battery=0.19))
    assert low.low_battery and low.outcome == "low_battery" and low.reason == "low battery 19% < 20%"
    assert low.battery == pytest.approx(0.19)


def test_ground_station_critical_event():
    e = Evaluator(config()).step(view(), gs_critical_event=True)
    assert e.gs_critical and e.outcome == "GS_critical_event" and e.reason == "ground station critical event"


@pytest.mark.parametrize("own, gs, battery, outcome", [
    ((0.1, 0, 1), True, 0.05, "collision"),  # overlapping uav_2, below every other condition too
    ((10.5, 5, 1), True, 0.05, "aborted"),
    ((0, 5, 1), True, 0.05, "GS_critical_event"),
    ((0, 5, 1), False, 0.05, "low_battery"),
])
def test_outcome_priority(own, gs, battery, outcome):
    v = view(own=own, others=[(2, (0, 0, 1))], battery=battery)
    e = Evaluator(config()).step(v, gs_critical_event=gs)
    assert e.outcome == outcome
    first = {"collision": "collision with", "aborted": "out of", "GS_critical_event": "ground", "low_battery": "low"}
    assert e.reason.split("; ")[0].startswith(first[outcome])
    assert e.low_battery and e.gs_critical is gs  # every finding is reported, not only the winner


def test_before_the_first_pose_only_the_ground_station_counts():
    ev = Evaluator(config())
    empty = WorldView(1, BOUNDS)
    assert ev.step(empty).outcome is None and ev.step(empty).reason == "no pose of uav_1 yet"
    assert ev.step(empty, gs_critical_event=True).outcome == "GS_critical_event"


def test_the_view_must_be_the_evaluated_uavs_own():
    with pytest.raises(ValueError, match="the evaluator of uav_2 was given the world view of uav_1"):
        Evaluator(config(2)).step(view())


@pytest.mark.parametrize("threshold", [-0.1, 15, math.nan])
def test_the_threshold_is_a_fraction(threshold):
    with pytest.raises(ValueError, match="low_battery: .* give a value in 0..1"):
        Evaluator(config(), low_battery=threshold)


def power_line_view(own, safety_radius=R):
    """One 400 m x 0.3 m wire along x at 25 m, as the original GAUSSUseCase1 worlds have them."""
    along_x = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])
    v = WorldView(1, [[-1000, 1000], [-1000, 1000], [-10, 500]])
    v.update_agent(AgentState(1, position=own, safety_radius=safety_radius))
    v.set_obstacles([Obstacle.solid("wire", Cylinder((0, 0, 25), along_x, 0.15, 200.0))])
    return v


def test_flying_95_m_above_a_long_wire_is_no_collision():
    # its bounding sphere has a radius of 200 m: measured to it, this was a collision (gap about -105 m)
    e = Evaluator(config(model="plane")).step(power_line_view((50, 0, 120), safety_radius=1.0))
    assert e.outcome is None and e.collided_with == []
    assert e.obstacle_gaps == pytest.approx({"wire": 95 - 0.15 - 1.0})


def test_touching_a_long_wire_is_a_collision():
    ev = Evaluator(config())
    near = ev.step(power_line_view((-150, 0.3, 25.4)))  # 0.5 m from the axis: 0.35 m from the surface
    assert near.outcome is None and near.obstacle_gaps["wire"] == pytest.approx(0.35 - R)
    touching = ev.step(power_line_view((-150, 0.0, 25.4)))  # 0.4 m from the axis
    assert touching.outcome == "collision" and touching.collided_with == ["wire"]
    assert "wire (gap -0.05 m)" in touching.reason and ev.collisions == {"wire": 1}
