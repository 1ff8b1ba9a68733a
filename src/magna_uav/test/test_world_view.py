"""The UAV manager's picture of the world: nearest-first queries by gaps between safety spheres."""
import math

import numpy as np
import pytest

from magna_uav.shapes import Box, Cylinder
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


def test_the_gaps_of_a_swarm_are_the_floats_of_one_fixed_formula_per_uav():
    # the swarm's gaps are computed in one array operation; each must be the float that the formula gives for
    # that UAV alone, (dx*dx + dy*dy) + dz*dz under the root, on any machine (a BLAS norm may differ in its
    # last bit from one CPU to another, so it is only compared within rounding)
    rng = np.random.default_rng(7)
    others = [AgentState(i, rng.normal(size=3) * 40, safety_radius=0.5 + 0.01 * i) for i in range(2, 52)]
    view = view_with(*others)
    own = view.own
    expected = {}
    for o in others:
        dx, dy, dz = (float(a) - float(b) for a, b in zip(o.position, own.position, strict=True))
        expected[o.id] = math.sqrt((dx * dx + dy * dy) + dz * dz) - o.safety_radius - own.safety_radius
    found = {state.id: gap for state, gap in view.nearest_agents()}
    assert found == expected
    for o in others:
        norm = float(np.linalg.norm(o.position - own.position)) - o.safety_radius - own.safety_radius
        assert found[o.id] == pytest.approx(norm, rel=1e-14, abs=1e-12)


def test_a_spherical_obstacle_is_its_bounding_sphere():
    view = view_with(obstacles=[Obstacle("far", np.array([10.0, 0, 1]), 1.0),
                                Obstacle("near", np.array([0, 2.0, 1]), 1.0)])
    assert [(o.name, gap) for o, gap in view.nearest_obstacles()] == [("near", 0.5), ("far", 8.5)]


def test_boundaries_and_yaw():
    view = view_with(boundaries=[[-1, 1], [-1, 1], [0, 2]])
    assert view.inside_boundaries()
    assert not view.inside_boundaries([0, 0, 2.5])
    half = math.sqrt(0.5)
    assert AgentState(1, orientation=[0, 0, half, half]).yaw == pytest.approx(math.pi / 2)


# --- real shapes: gaps to the surface, not to the bounding sphere ----------------------------------------------

def wire(name="wire", centre=(0, 0, 25)):
    """A power-line wire as the original GAUSS worlds place it: a cylinder 400 m long, 0.3 m thick, along x."""
    along_x = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])  # the cylinder's own z turned onto map x
    return Obstacle.solid(name, Cylinder(centre, along_x, 0.15, 200.0))


def test_a_long_wire_is_as_thin_as_it_is():
    w = wire()
    assert w.radius == pytest.approx(200.0, abs=0.01)  # its bounding sphere: what the old gap measured to
    view = view_with(obstacles=[w])
    view.update_agent(AgentState(1, [120.0, 0, 25 + 95], safety_radius=0.5))
    ((found, gap),) = view.nearest_obstacles()
    assert found is w and gap == pytest.approx(95 - 0.15 - 0.5)
    view.update_agent(AgentState(1, [120.0, 0.4, 25.3], safety_radius=0.5))  # 0.5 m from the axis
    assert view.nearest_obstacles()[0][1] == pytest.approx(0.5 - 0.15 - 0.5)


def test_gap_to_a_box_turned_by_yaw_and_from_inside_it():
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    box = Obstacle.solid("hangar", Box((10, 0, 1), [[c, -s, 0], [s, c, 0], [0, 0, 1]], (6, 1, 1)))
    view = view_with(obstacles=[box])  # own safety radius 0.5, at (0, 0, 1)
    end = np.array([10, 0, 1]) + 6 * np.array([c, s, 0])  # the middle of the box's far end face, 2 m high
    view.update_agent(AgentState(1, end + 3 * np.array([c, s, 0]), safety_radius=0.5))
    assert view.nearest_obstacles()[0][1] == pytest.approx(3 - 0.5)
    view.update_agent(AgentState(1, end + 2 * np.array([-s, c, 0]), safety_radius=0.5))  # beside the end's edge
    assert view.nearest_obstacles()[0][1] == pytest.approx(1 - 0.5)
    view.update_agent(AgentState(1, [10, 0, 1.2], safety_radius=0.5))  # inside: 0.8 m from the top and bottom
    assert view.nearest_obstacles()[0][1] == pytest.approx(-0.8 - 0.5)


def test_nearest_obstacles_are_ordered_by_the_real_gap():
    # the wire's bounding sphere (radius 200) swallows everything; its surface is 25 m below us
    obstacles = [wire(), Obstacle("ball", np.array([0, 8.0, 1]), 1.0),
                 Obstacle.solid("slab", Box((0, -5, 1), None, (1, 1, 1))),
                 Obstacle("twin", np.array([0, -8.0, 1]), 1.0)]
    view = view_with(obstacles=obstacles)
    view.update_agent(AgentState(1, [0, 0, 50], safety_radius=0.5))
    order = [(o.name, round(g, 9)) for o, g in view.nearest_obstacles()]
    assert [n for n, _ in order] == ["wire", "slab", "ball", "twin"]
    assert order[0][1] == pytest.approx(25 - 0.15 - 0.5)
    view.update_agent(AgentState(1, [0, 0, 1], safety_radius=0.5))
    # ball and twin tie at 6.5: the list order decides; k and within as for UAVs
    assert [(o.name, round(g, 9)) for o, g in view.nearest_obstacles()] == [
        ("slab", 3.5), ("ball", 6.5), ("twin", 6.5), ("wire", round(24 - 0.15 - 0.5, 9))]
    assert [o.name for o, _ in view.nearest_obstacles(k=2)] == ["slab", "ball"]
    assert [o.name for o, _ in view.nearest_obstacles(within=6.5)] == ["slab"]
    np.testing.assert_allclose(view.obstacle_distances(), [24 - 0.15, 7, 4, 7])
