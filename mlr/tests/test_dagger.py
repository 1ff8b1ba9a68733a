"""DAgger (`magna learn dagger`): the config, the relabelling against ORCA-3D itself, one short iteration end
to end through the whole stack, and going on where a run stopped."""
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from magna_common.airframes import load_airframe
from magna_common.records import WorldRecord
from magna_uav.nai.goal import Goal
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.recorder import read_csv
from magna_uav.world_view import AgentState, WorldView
from mlr import dagger
from mlr.pickler import PicklerError, Teacher, find_simulations, pickle_simulations
from tests.support import ROOT

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.*` is deprecated:DeprecationWarning")


def training_config(folder: Path, run, data_root: Path, **changes) -> Path:
    values = {"world": run.world, "subworld": run.subworld, "mission": run.mission, "submission": run.submission,
              "name": run.name, "data_root": str(data_root), "n_neighbors": 1, "n_obstacles": 2, "steps": 300,
              "eval_every": 100, "batch_size": 64, "hidden_layers": [[16, 16], [8]]} | changes
    path = folder / "train.json"
    path.write_text(json.dumps(values))
    return path


def dagger_config(folder: Path, **values) -> Path:
    path = folder / "small.yaml"
    path.write_text(json.dumps({"train": "train.json", "select": {"hidden_layers": [16, 16]}} | values))
    return path


# --- the config -----------------------------------------------------------------------------------------------

def test_a_config_narrows_the_training_sweep_to_one_run(tmp_path, recorded_run):
    training_config(tmp_path, recorded_run, tmp_path / "data")
    config = dagger.load_config(dagger_config(tmp_path, iterations=2, flights=3), {"steps": 50})
    assert config.name == "small" and config.run.hidden_layers == (16, 16) and config.run.steps == 50
    assert (config.iterations, config.flights, config.evaluation_flights, config.fallback) == (2, 3, 20, False)
    assert config.world == "Gym/Central_Obstacle_Torus" and config.mission == "Gym/2UAVs_Crossing_ORCA"
    # the flights of each iteration, and the evaluation's, never share a seed
    seeds = [set(range(config.seed(k) + 1, config.seed(k) + config.flights + 1)) for k in (1, 2)]
    seeds.append(set(range(config.evaluation_seed + 1, config.evaluation_seed + config.evaluation_flights + 1)))
    assert sum(map(len, seeds)) == len(set().union(*seeds))
    assert config.teacher_agent_radius is None
    wider = dagger.load_config(dagger_config(tmp_path, teacher_agent_radius=0.7))
    assert wider.teacher_agent_radius == 0.7 and wider.fingerprint() != config.fingerprint()


def test_a_teacher_margin_needs_obstacles_the_input_vector_can_size(tmp_path, recorded_run):
    # the crossing's obstacles are spheres and cylinders of several sizes: its samples cannot be relabelled
    data = tmp_path / "data"
    shutil.copytree(recorded_run.sim_dir.parent, data / recorded_run.sim_dir.parent.relative_to(recorded_run.data_root))
    training_config(tmp_path, recorded_run, data)
    config = dagger.load_config(dagger_config(tmp_path, teacher_agent_radius=0.7))
    assert len(dagger.teacher_samples(config.run, lambda message: None)) > 100  # the recorded labels, as they are
    with pytest.raises(PicklerError, match="obstacles are not spheres of one size"):
        dagger.teacher_samples(config.run, lambda message: None, config.teacher_agent_radius)


@pytest.mark.parametrize("values,message", [
    ({"select": {}}, "sweeps hidden_layers (2 runs): give select with one value for each"),
    ({"iterations": -1}, "iterations is -1: give a whole number >= 0"),
    ({"flights": 101}, "flights is 101: give a whole number of simulations per iteration, 1..100"),
    ({"fallback": "yes"}, "fallback is 'yes': give true or false"),
    ({"teacher_agent_radius": 0}, "teacher_agent_radius is 0: give a radius in metres > 0"),
    ({"flight": 3}, "unknown key 'flight': known keys are train, select"),
    ({"train": "missing.yaml"}, "train missing.yaml: .*missing.yaml: cannot read the config"),
    ({"select": {"hidden_layers": [16, 16], "algorithm": "neural_network", "label": "teacher"}},
     "must learn ORCA-3D's own flights with an mlp"),
])
def test_bad_configs_are_refused_naming_the_file_and_key(tmp_path, recorded_run, values, message):
    training_config(tmp_path, recorded_run, tmp_path / "data")
    pattern = ".*".join(re.escape(part) for part in message.split(".*"))  # ".*" in a message: anything there
    with pytest.raises(dagger.DaggerError, match=rf"small\.yaml: .*{pattern}"):
        dagger.load_config(dagger_config(tmp_path, **values))


# --- one iteration through the whole stack ----------------------------------------------------------------------

def world_obstacles(sim: Path):
    """The obstacles the UAV managers had: the simulation's world resolved again, as the world node publishes it."""
    from magna_uav.ros_data import obstacles_from_markers
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import load_world
    from magna_worlds.markers import world_markers

    record = WorldRecord.read(sim / "world.json")
    resolved = [resolve_world(load_world(Path(part.source), []), part.seed) for part in record.parts.values()]
    return obstacles_from_markers(world_markers(resolved))


def orca_from_the_row(row: dict, other: int, obstacles, safety_radius: float, orca_values) -> np.ndarray:
    """ORCA-3D's answer, by the numpy reference, to the state a recorder row holds."""
    def xyz(prefix: str) -> np.ndarray:
        return np.array([row[f"{prefix}.{a}"] for a in "xyz"])

    view = WorldView(row["uav_id"])
    view.update_agent(AgentState(row["uav_id"], xyz("pos"), np.array([row[f"ori.{a}"] for a in "xyzw"]), xyz("vel"),
                                 safety_radius=safety_radius))
    if np.isfinite(row[f"uav{other}.pos.x"]):
        view.update_agent(AgentState(other, xyz(f"uav{other}.pos"), velocity=xyz(f"uav{other}.vel"),
                                     safety_radius=safety_radius))
    view.set_obstacles(obstacles)
    nav = NavigationInterface(2.0, safety_radius, solver=ReferenceSolver())
    nav.control("orca3d", "set", *orca_values)
    return nav.velocity(view, Goal(xyz("goal"))).velocity


@pytest.mark.timeout(1200)
def test_one_dagger_iteration_end_to_end_then_it_goes_on_where_it_stopped(tmp_path, recorded_run):
    # the teacher's flights: the session's recorded crossing, copied so this test's batches land beside it alone
    data = tmp_path / "data"
    dataset = recorded_run.sim_dir.parent
    shutil.copytree(dataset, data / dataset.relative_to(recorded_run.data_root))
    training_config(tmp_path, recorded_run, data)
    config = dagger_config(tmp_path, iterations=1, flights=1, evaluation_flights=1)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "mlr", "dagger", str(config), "--rtf", "5", "--quiet", "-o", str(out)]

    def dagger_run():
        return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, stdin=subprocess.DEVNULL,
                              env=dict(os.environ, MAGNA_ROOT=str(ROOT)))

    done = dagger_run()
    assert done.returncode == 0, f"{done.stdout}\n{done.stderr}"
    results = json.loads((out / "results.json").read_text())
    first, second = results["iterations"]
    assert first["accuracy"]["relabelled_samples"] == 0 < second["accuracy"]["relabelled_samples"]
    assert second["accuracy"]["samples"] == first["accuracy"]["samples"] + second["accuracy"]["relabelled_samples"]
    assert first["flights"]["simulations"] == 1 and first["flights"]["seeds"] == [2101]  # network 0, unseen seed
    assert second["flights"] is None  # the last network's flights are the evaluation's
    assert results["evaluation"]["orca"]["simulations"] == results["evaluation"]["network"]["simulations"] == 1
    assert results["evaluation"]["network"]["seeds"] == [1001]
    for name in ("results.md", "dagger.png", "iter_00/net.pt", "iter_01/net.pt", "iter_01/net.json"):
        assert (out / name).is_file(), name
    table = (out / "results.md").read_text()
    assert "| 0 |" in table and "| 1 |" in table and "Ratio of collision-free rates" in table
    assert json.loads((out / "iter_01" / "net.json").read_text())["about"]["iteration"] == 1
    # the evaluation names the very network it flew, so a later one is flown again, not taken for it
    evaluated = json.loads((out / "evaluation" / "comparison.json").read_text())["model_sha256"]
    assert evaluated == hashlib.sha256((out / "iter_01" / "net.pt").read_bytes()).hexdigest()

    # the relabelling: every step the network flew carries ORCA-3D's answer to the very state the row records
    flown = data / "Simulations" / "Gym" / "Central_Obstacle_Torus" / "Gym" / "2UAVs_Crossing_ORCA_nn" \
        / "dagger_small_01_nn" / "dataset_1" / "simulation_1"
    mission = json.loads((flown / "mission.json").read_text())
    orca_state = next(s for s in mission["State_Machine"] if s.get("name") == "orca3d")
    assert orca_state["parameters"]["action"] == "configure"  # the teacher keeps the mission's parameters
    orca_values = (orca_state["parameters"]["params"], orca_state["parameters"]["values"])
    obstacles = world_obstacles(flown)
    safety_radius = load_airframe("iris").safety_radius
    checked = 0
    for uav, other in ((1, 2), (2, 1)):
        _, rows = read_csv(flown / f"uav_{uav}.csv")
        network = [row for row in rows if row["algorithm"] == "neural_network"]
        assert len(network) > 20 and all(row["fallback"] == 0 for row in network)
        for row in network[::5]:
            teacher = [row[f"teacher_vel.{a}"] for a in "xyz"]
            np.testing.assert_allclose(teacher, orca_from_the_row(row, other, obstacles, safety_radius, orca_values),
                                       atol=1e-6)
            checked += 1
        assert all(np.isnan(row["teacher_vel.x"]) for row in rows if row["algorithm"] != "neural_network")
    assert checked > 10
    # ... and those answers are the labels of iteration 1's samples
    sims, _ = find_simulations(dagger.relabelled_selection(dagger.load_config(config), 1, data), failures=True)
    relabelled = pickle_simulations(sims, Teacher("path", "neural_network", 1, 2, label="teacher"))
    assert len(relabelled) == second["accuracy"]["relabelled_samples"]
    _, rows = read_csv(Path(relabelled.sources[0]))
    for k in np.flatnonzero(relabelled.origin == 0)[:50]:
        assert list(relabelled.y[k]) == [rows[relabelled.step[k]][f"teacher_vel.{a}"] for a in "xyz"]

    # run again: everything is there, nothing is flown or trained again
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file() and p.name in ("net.pt", "flights.json")}
    again = dagger_run()
    assert again.returncode == 0, again.stderr
    assert "flown before" in again.stderr and "trained before" in again.stderr and "flies" not in again.stderr
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    assert json.loads((out / "results.json").read_text())["iterations"] == results["iterations"]

    # stopped after iteration 1's flights, before its training: only the training is done again
    (out / "iter_01" / "net.pt").unlink()
    resumed = dagger_run()
    assert resumed.returncode == 0, resumed.stderr
    assert "iteration 1: flown before" in resumed.stderr and "iteration 0: trained before" in resumed.stderr
    assert "flies" not in resumed.stderr and (out / "iter_01" / "net.pt").is_file()
    assert len(list(flown.parent.glob("simulation_*"))) == 1, "no flight again"

    # another config in the same folder is refused, not mixed in
    other = dagger_config(tmp_path, iterations=1, flights=2, evaluation_flights=1)
    refused = subprocess.run([sys.executable, "-m", "mlr", "dagger", str(other), "-o", str(out)], cwd=ROOT,
                             capture_output=True, text=True, stdin=subprocess.DEVNULL)
    assert refused.returncode == 2 and "made with another config" in refused.stderr and "--force" in refused.stderr
