"""ORCA-3D solved again from an input vector alone (mlr.relabel): it is ORCA-3D's answer to the scene, so the
teacher's samples can be relabelled with another margin without flying again, when the obstacles allow it."""
import json

import numpy as np
import pytest

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.world_view import AgentState, Obstacle, WorldView
from mlr import relabel
from mlr.config import RunConfig
from mlr.pickler import PicklerError, Samples, find_simulations

ORCA = (["N_neighbors_aware", "timeHorizon", "agent_radius", "neighborDist"], [2, 5.0, 0.5, 6.0])
RUN = RunConfig("Gym", "w", "Gym", "m", n_neighbors=1, n_obstacles=2, neighbor_dist=6.0)


def scenes(count: int, seed: int = 7):
    """Random scenes where ORCA-3D has to act: a UAV, a neighbour and three balls of one size around."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        own = rng.uniform(-5, 5, 3)
        view = WorldView(1)
        view.update_agent(AgentState(1, own, velocity=rng.uniform(-1.5, 1.5, 3), safety_radius=0.3))
        view.update_agent(AgentState(2, own + rng.uniform(-3, 3, 3), velocity=rng.uniform(-1.5, 1.5, 3),
                                     safety_radius=0.3))
        view.set_obstacles([Obstacle(f"b{k}", own + rng.uniform(-3, 3, 3), 0.25) for k in range(3)])
        yield view, Goal(own + rng.uniform(-8, 8, 3))


def orca(params) -> NavigationInterface:
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    nav.control("orca3d", "set", *params)
    return nav


def test_orca_from_the_input_vector_alone_is_orca3ds_answer_to_the_scene():
    setup = relabel.TeacherSetup(ORCA, 0.25, 0.3, 2.0)
    nav, teacher = relabel.teacher_nai(setup), orca(ORCA)
    acted = 0
    for view, goal in scenes(60):
        x = build_inputs(view, goal, "path", 1, 2, 6.0)
        recomputed, preferred = relabel.orca_from_inputs(x, RUN, setup, nav)
        answer = teacher.velocity(view, goal).velocity
        np.testing.assert_allclose(recomputed, answer, atol=1e-9)
        acted += np.linalg.norm(answer - preferred) > 0.2
    assert acted > 10, "the scenes make ORCA-3D act, so the check means something"


def test_relabelling_with_a_wider_margin_gives_orca3ds_answers_with_that_margin():
    pairs = list(scenes(40, seed=3))
    x = np.array([build_inputs(view, goal, "path", 1, 2, 6.0) for view, goal in pairs])
    recorded = np.array([orca(ORCA).velocity(view, goal).velocity for view, goal in pairs])
    samples = Samples(x, recorded, np.full(len(x), 2.0), np.zeros(len(x), dtype=int), np.arange(len(x)), ["scenes"])
    wider = relabel.with_param(relabel.TeacherSetup(ORCA, 0.25, 0.3, 2.0), "agent_radius", 0.7)
    assert wider.orca_params == (ORCA[0], [2, 5.0, 0.7, 6.0])
    out = relabel.relabelled(samples, RUN, wider)
    want = np.array([orca(wider.orca_params).velocity(view, goal).velocity for view, goal in pairs])
    np.testing.assert_allclose(out.y, want, atol=1e-9)
    assert np.sum(np.linalg.norm(out.y - recorded, axis=1) > 0.05) > 5, "the wider margin changes answers"
    assert np.array_equal(out.x, x) and np.array_equal(samples.y, recorded), "inputs kept, samples not modified"


def test_relabelling_is_refused_when_the_vector_cannot_say_an_obstacles_size():
    view, goal = next(scenes(1))
    x = build_inputs(view, goal, "path", 1, 2, 6.0).reshape(1, -1)
    samples = Samples(x, np.zeros((1, 3)), np.full(1, 2.0), np.zeros(1, dtype=int), np.zeros(1, dtype=int), ["s"])
    with pytest.raises(PicklerError, match="obstacles are not spheres of one size"):
        relabel.relabelled(samples, RUN, relabel.TeacherSetup(ORCA, None, 0.3, 2.0))


def test_the_teacher_setup_comes_from_the_simulations_mission_and_gaps(recorded_run):
    run = RunConfig(recorded_run.world, recorded_run.subworld, recorded_run.mission, recorded_run.submission,
                    name=recorded_run.name, data_root=str(recorded_run.data_root), n_neighbors=1, n_obstacles=2)
    sims, _ = find_simulations(run.selection)
    setup = relabel.teacher_setup(sims[0], run)
    mission = json.loads((recorded_run.sim_dir / "mission.json").read_text())
    orca_state = next(s["parameters"] for s in mission["State_Machine"] if s.get("state_type") == "algorithm_control")
    assert setup.orca_params == (orca_state["params"], orca_state["values"]) and setup.max_speed == 2.0
    assert setup.obstacle_radius is None  # spheres and cylinders of several sizes: no one radius
