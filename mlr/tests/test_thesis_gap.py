"""The thesis comparison's measurements (mlr.thesis_gap): ORCA-3D solved again from an input vector alone is
ORCA-3D's answer to the scene, the original's accuracy measure, and the analysis on a recorded run."""
import dataclasses
import json

import numpy as np
import pytest

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.world_view import AgentState, Obstacle, WorldView
from mlr import thesis_gap
from mlr.config import RunConfig
from mlr.pickler import find_simulations

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.*` is deprecated:DeprecationWarning")
ORCA = (["N_neighbors_aware", "timeHorizon", "agent_radius", "neighborDist"], [2, 5.0, 0.5, 6.0])


def test_orca_from_the_input_vector_alone_is_orca3ds_answer_to_the_scene():
    rng = np.random.default_rng(7)
    run = RunConfig("Gym", "w", "Gym", "m", n_neighbors=1, n_obstacles=2, neighbor_dist=6.0)
    setup = thesis_gap.TeacherSetup(ORCA, 0.25, 0.3, 2.0)
    nav = thesis_gap.teacher_nai(setup)
    orca = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    orca.control("orca3d", "set", *ORCA)
    acted = 0
    for _ in range(60):
        own = rng.uniform(-5, 5, 3)
        view = WorldView(1)
        view.update_agent(AgentState(1, own, velocity=rng.uniform(-1.5, 1.5, 3), safety_radius=0.3))
        view.update_agent(AgentState(2, own + rng.uniform(-3, 3, 3), velocity=rng.uniform(-1.5, 1.5, 3),
                                     safety_radius=0.3))
        view.set_obstacles([Obstacle(f"b{k}", own + rng.uniform(-3, 3, 3), 0.25) for k in range(3)])
        goal = Goal(own + rng.uniform(-8, 8, 3))
        x = build_inputs(view, goal, "path", 1, 2, 6.0)
        recomputed, preferred = thesis_gap.orca_from_inputs(x, run, setup, nav)
        answer = orca.velocity(view, goal).velocity
        np.testing.assert_allclose(recomputed, answer, atol=1e-9)
        acted += np.linalg.norm(answer - preferred) > 0.2
    assert acted > 10, "the scenes make ORCA-3D act, so the check means something"


def test_argmax_agreement_is_the_originals_measure():
    labels = np.array([[1.0, 0.5, 0.0], [0.0, -1.0, 0.2], [0.1, 0.2, 0.3]])
    assert thesis_gap.argmax_agreement(np.array([[2.0, 0.0, 0.0], [0.0, -2.0, 0.1], [0.3, 0.2, 0.1]]), labels) \
        == pytest.approx(2 / 3)  # the second: -1 is not the largest; 0.2 is, and 0.1 is the prediction's largest


def test_the_analysis_on_a_recorded_run_measures_and_writes_its_table(tmp_path, recorded_run):
    run = RunConfig(recorded_run.world, recorded_run.subworld, recorded_run.mission, recorded_run.submission,
                    name=recorded_run.name, data_root=str(recorded_run.data_root), n_neighbors=1, n_obstacles=2,
                    steps=150, eval_every=50, batch_size=64)
    sims, _ = find_simulations(run.selection)
    setup = thesis_gap.teacher_setup(sims[0], run)
    mission = json.loads((recorded_run.sim_dir / "mission.json").read_text())
    orca = next(s["parameters"] for s in mission["State_Machine"] if s.get("state_type") == "algorithm_control")
    assert setup.orca_params == (orca["params"], orca["values"]) and setup.max_speed == 2.0
    assert setup.obstacle_radius is None  # spheres and cylinders of several sizes: no one radius
    findings = thesis_gap.analyse(dataclasses.replace(run), tmp_path / "analysis", progress=False,
                                  log=lambda message: None)
    assert findings["avoidance_share"] + findings["preferred_velocity_accuracy"] == pytest.approx(1.0)
    assert 0.0 <= findings["labels_reproduced_from_inputs"] <= 1.0
    assert list(findings["trainings"]) == ["max-abs, 100%", "standard, 100%", "max-abs, 25%", "max-abs, 50%"]
    sizes = [t["train_samples"] for t in findings["trainings"].values()]
    assert sizes[0] == sizes[1] and sizes[2] < sizes[3] < sizes[0]
    assert json.loads((tmp_path / "analysis" / "analysis.json").read_text()) == findings
    table = (tmp_path / "analysis" / "analysis.md").read_text()
    assert "reproduces from the input vector alone" in table and "argmax agreement" in table
