"""ORCA-3D through the NAI: agents built from the WorldView, kinematic flights that keep clear."""
import logging

import numpy as np
import pytest

from magna_orca_cpp import reference
from magna_orca_cpp.model import Params, Solution
from magna_uav.nai.goal import Goal
from magna_uav.nai.interface import NavigationInterface, canonical_name
from magna_uav.nai.orca import OrcaNavigator, ReferenceSolver
from magna_uav.world_view import AgentState, Obstacle, WorldView

RADIUS, MAX_SPEED, DT = 0.3, 2.0, 0.05


def segment_gap(a0, a1, b0, b1, clearance):
    """Smallest distance minus `clearance` between two points moving linearly over one step."""
    d0, dd = a0 - b0, (a1 - a0) - (b1 - b0)
    t = 0.0 if dd @ dd < 1e-18 else float(np.clip(-(d0 @ dd) / (dd @ dd), 0.0, 1.0))
    return float(np.linalg.norm(d0 + t * dd)) - clearance


def fly(algorithm, starts, goals, obstacles=(), seconds=20.0):
    """Step every UAV kinematically (v then x); returns (final positions, min gap UAV-UAV, min gap UAV-obstacle)."""
    ids = list(range(1, len(starts) + 1))
    navs = {i: NavigationInterface(MAX_SPEED, RADIUS, solver=ReferenceSolver()) for i in ids}
    for nav in navs.values():
        nav.control(algorithm, "set")
    states = {i: AgentState(i, p, safety_radius=RADIUS) for i, p in zip(ids, starts, strict=True)}
    min_agents = min_obstacles = np.inf
    for _ in range(int(seconds / DT)):
        commands = {}
        for i in ids:
            view = WorldView(i)
            for s in states.values():
                view.update_agent(AgentState(s.id, s.position.copy(), velocity=s.velocity.copy(),
                                             safety_radius=RADIUS))
            view.set_obstacles(obstacles)
            commands[i] = navs[i].velocity(view, Goal(goals[i - 1]))
            assert commands[i].algorithm == canonical_name(algorithm) and not commands[i].error
        before = {i: states[i].position.copy() for i in ids}
        for i in ids:
            states[i].velocity = commands[i].velocity
            states[i].position = before[i] + commands[i].velocity * DT
        for a in ids:
            for b in ids:
                if a < b:
                    min_agents = min(min_agents, segment_gap(before[a], states[a].position, before[b],
                                                             states[b].position, 2 * RADIUS))
            for o in obstacles:
                min_obstacles = min(min_obstacles, segment_gap(before[a], states[a].position, o.position,
                                                               o.position, RADIUS + o.radius))
    return [states[i].position for i in ids], min_agents, min_obstacles


def test_two_uavs_head_on_keep_their_separation_with_orca_and_collide_with_simple_guidance():
    starts = [np.array([0.0, 0.0, 5.0]), np.array([10.0, 0.01, 5.0])]
    goals = [np.array([10.0, 0.0, 5.0]), np.array([0.0, 0.01, 5.0])]
    finals, gap, _ = fly("orca3", starts, goals)
    assert gap >= -1e-6, f"ORCA-3D let the safety spheres overlap by {-gap:.3g} m"
    for final, goal in zip(finals, goals, strict=True):
        assert np.linalg.norm(final - goal) < 0.05
    _, gap, _ = fly("simple", starts, goals)
    assert gap < -0.5, "straight-line guidance flies them through each other"


def test_a_still_obstacle_on_the_line_is_flown_around():
    obstacle = Obstacle("pillar", np.array([5.0, 0.1, 5.0]), 1.0)
    start, goal = np.array([0.0, 0.0, 5.0]), np.array([10.0, 0.0, 5.0])
    (final,), _, gap = fly("orca3d", [start], [goal], obstacles=[obstacle], seconds=30.0)
    assert gap >= -1e-6
    assert np.linalg.norm(final - goal) < 0.05
    _, _, gap = fly("simple", [start], [goal], obstacles=[obstacle])
    assert gap < -1.0


class SpySolver:
    """Records what the NAI sends and answers with the reference."""

    def __init__(self, using_service=False):
        self.using_service = using_service
        self.calls = []

    def new_velocity(self, agent, others, params):
        self.calls.append((agent, others, params))
        return reference.new_velocity(agent, others, params)


def crowd_view():
    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 5], velocity=[1, 0, 0], safety_radius=RADIUS))
    for i, (x, r) in enumerate([(2.0, 0.3), (1.5, 0.3), (-5.0, 0.3), (9.0, 0.3)], start=2):
        view.update_agent(AgentState(i, [x, 0.5, 5], velocity=[-0.2 * i, 0, 0], safety_radius=r))
    view.set_obstacles([Obstacle("far", np.array([0, 20.0, 5]), 1.0), Obstacle("wall", np.array([0, -3.0, 5]), 2.0),
                        Obstacle("post", np.array([0, 2.5, 5]), 0.5)])
    return view


def test_the_nearest_uavs_and_obstacles_within_neighbor_dist_are_sent_as_orca_agents():
    solver = SpySolver()
    nav = NavigationInterface(MAX_SPEED, 0.4, solver=solver)
    nav.control("orca3", "set", ["N_neighbors_aware", "N_obstacles_aware", "neighborDist", "agent_radius"],
                [2, 5, 4.0, 0.35])
    command = nav.velocity(crowd_view(), Goal([10, 0, 5]))
    assert command.neighbors == (3, 2)  # nearest first; 4 is 4.4 m away (gap 3.7) but only 2 are taken
    assert command.obstacles == ("wall", "post")  # gaps 0.6 and 1.1; "far" is beyond neighborDist
    agent, others, params = solver.calls[-1]
    assert agent.radius == 0.4 and agent.max_speed == MAX_SPEED and agent.cooperative
    np.testing.assert_allclose(agent.preferred_velocity, [2, 0, 0])  # simple guidance at full speed
    np.testing.assert_allclose(agent.velocity, [1, 0, 0])
    assert [o.cooperative for o in others] == [True, True, False, False]
    np.testing.assert_allclose(others[0].position, [1.5, 0.5, 5])
    np.testing.assert_allclose(others[0].preferred_velocity, [-0.6, 0, 0])  # their current velocity
    np.testing.assert_allclose(others[2].velocity, 0)
    np.testing.assert_allclose(others[2].preferred_velocity, 0)
    # UAVs get at least agent_radius (0.35 > their 0.3, < our 0.4); obstacles keep their own
    assert [o.radius for o in others] == [0.35, 0.35, 2.0, 0.5]
    assert params.max_neighbors == 4 and params.neighbor_dist == 4.0  # the solver keeps every agent sent
    np.testing.assert_allclose(command.velocity, reference.new_velocity(agent, others, params).velocity)


def test_agent_radius_is_the_margin_around_smaller_safety_spheres():
    solver = SpySolver()
    nav = NavigationInterface(MAX_SPEED, 0.3, solver=solver)
    nav.control("orca3", "set", ["agent_radius"], [0.5])  # the original missions' value
    nav.velocity(crowd_view(), Goal([10, 0, 5]))
    agent, others, _ = solver.calls[-1]
    assert agent.radius == 0.5
    assert [o.radius for o in others if o.cooperative] == [0.5] * sum(o.cooperative for o in others)


def test_n_obstacles_follows_n_neighbors_until_set():
    nav = NavigationInterface(MAX_SPEED, RADIUS, solver=SpySolver())
    nav.control("orca3", "set", ["N_neighbors_aware"], [1])
    command = nav.velocity(crowd_view(), Goal([10, 0, 5]))
    assert command.neighbors == (3,) and command.obstacles == ("wall",)
    assert nav.params("orca3d")["N_obstacles_aware"] == 1


def test_one_warning_when_the_solver_runs_on_the_reference(caplog):
    solver = SpySolver(using_service=True)
    navigator = OrcaNavigator(solver)
    view = crowd_view()
    with caplog.at_level(logging.WARNING, logger="magna_uav.nai"):
        for _ in range(3):
            navigator.velocity(view, np.array([1.0, 0, 0]), Params(), 1, RADIUS, MAX_SPEED)
        assert not caplog.records
        solver.using_service = False  # the server went away
        for _ in range(3):
            navigator.velocity(view, np.array([1.0, 0, 0]), Params(), 1, RADIUS, MAX_SPEED)
    warnings = [r for r in caplog.records if r.name == "magna_uav.nai"]
    assert len(warnings) == 1 and warnings[0].levelno == logging.WARNING
    assert "/magna/orca3d/compute_velocity" in warnings[0].getMessage()


def test_default_solver_flies_with_or_without_the_service(caplog):
    nav = NavigationInterface(MAX_SPEED, RADIUS)
    nav.control("orca3d", "set")
    with caplog.at_level(logging.WARNING, logger="magna_uav.nai"):
        commands = [nav.velocity(crowd_view(), Goal([10, 0, 5])) for _ in range(2)]
    assert all(np.all(np.isfinite(c.velocity)) and not c.error for c in commands)
    if getattr(nav._orca.solver, "using_service", True) is False:
        assert len([r for r in caplog.records if r.levelno == logging.WARNING]) == 1


def test_the_reference_chosen_on_purpose_flies_without_a_warning(caplog):
    nav = NavigationInterface(MAX_SPEED, RADIUS, solver=ReferenceSolver())
    nav.control("orca3d", "set")
    with caplog.at_level(logging.WARNING, logger="magna_uav.nai"):
        command = nav.velocity(crowd_view(), Goal([10, 0, 5]))
    assert np.all(np.isfinite(command.velocity)) and not caplog.records


def test_an_infeasible_program_is_reported():
    class Infeasible:
        def new_velocity(self, agent, others, params):
            return Solution(np.array([0.1, 0, 0]), False)

    nav = NavigationInterface(MAX_SPEED, RADIUS, solver=Infeasible())
    nav.control("orca3", "set")
    command = nav.velocity(crowd_view(), Goal([10, 0, 5]))
    assert not command.feasible and not command.error
    np.testing.assert_allclose(command.velocity, [0.1, 0, 0])


@pytest.mark.parametrize("bad", [np.array([np.nan, 0, 0]), np.array([np.inf, 1, 0])])
def test_a_non_finite_answer_becomes_a_hover_with_one_logged_error(caplog, bad):
    class Broken:
        def new_velocity(self, agent, others, params):
            return Solution(bad, True)

    nav = NavigationInterface(MAX_SPEED, RADIUS, solver=Broken())
    nav.control("orca3", "set")
    with caplog.at_level(logging.ERROR, logger="magna_uav.nai"):
        commands = [nav.velocity(crowd_view(), Goal([10, 0, 5])) for _ in range(3)]
    for command in commands:
        np.testing.assert_array_equal(command.velocity, np.zeros(3))
        assert command.yaw_rate == 0.0 and not command.feasible and "orca3d answered velocity" in command.error
    assert len([r for r in caplog.records if r.levelno == logging.ERROR]) == 1
