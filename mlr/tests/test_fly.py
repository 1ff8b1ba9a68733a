"""mlr.fly: the network's mission, the metrics of a dataset, the comparison, the batches it starts and
how it stops them; and one real run of both batches (one simulation each) through `magna run`.

The corpus missions are read in place from ../shared/ros_magna_corpus (tests.support.CORPUS).
"""
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from magna_common.records import SimulationResult, SummaryRow
from magna_common.storage_tree import RESULT_FILE, SUMMARY_FILE
from magna_uav.nai.inputs import DEFAULT_NEIGHBOR_DIST, input_names, output_names
from magna_uav.recorder import columns, read_csv
from mlr import flight_metrics, nn_mission
from tests.support import CORPUS, ROOT, wait_until

FOUR_CYLINDERS = CORPUS / "Missions" / "Gym" / "2UAVs_2paths_4_Cylinders.json"
CENTRAL_CYLINDER = CORPUS / "Missions" / "Gym" / "2UAVs_2paths_Central_Cylinder.json"
CROSSING = ROOT / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json"
SIMPLE_MISSION = ROOT / "tests" / "missions" / "Test" / "2UAVs_Head_On_Simple.json"
MODEL = "/models/best/model.pt"
WORLD = "Gym/Central_Obstacle_Torus"
MISSION = "Gym/2UAVs_Crossing_ORCA"


def read(path: Path):
    return json.loads(path.read_text())


def nn_parameters(model: str, neighbor_dist: float) -> dict:
    return {"name": "neural_network", "action": "set", "params": ["neighborDist"], "values": [neighbor_dist],
            "text_value": model}


def make_model(folder: Path, max_speed: float = 2.0, neighbor_dist: float | None = None) -> Path:
    """A TorchScript network flying straight to the goal (goal_pose_rel, saturated), with its spec."""
    import torch

    names = input_names("path", 1, 0)

    class TowardsGoal(torch.nn.Module):
        def __init__(self, first: int, speed: float):
            super().__init__()
            self.first, self.speed = first, speed

        def forward(self, x):
            goal = x[:, self.first:self.first + 3]
            norm = torch.linalg.vector_norm(goal, dim=1, keepdim=True)
            return goal * torch.clamp(self.speed / (norm + 1e-6), max=1.0)

    folder.mkdir(parents=True, exist_ok=True)
    model = folder / "model.pt"
    with warnings.catch_warnings():  # torch 2.13 calls TorchScript deprecated; it is the format the NAI flies
        warnings.filterwarnings("ignore", r"`torch\.jit\.\w+` is deprecated", DeprecationWarning)
        torch.jit.save(torch.jit.script(TowardsGoal(names.index("goal_pose_rel.x"), max_speed)), str(model))
    spec = {"role": "path", "n_neighbors": 1, "n_obstacles": 0, "inputs": names, "outputs": output_names(),
            "image": None}
    if neighbor_dist is not None:
        spec["neighbor_dist"] = neighbor_dist
    model.with_suffix(".json").write_text(json.dumps(spec))
    return model


# --- the network's mission ------------------------------------------------------------------------------------

def test_the_default_neighbor_distance_is_the_nais():
    assert nn_mission.DEFAULT_NEIGHBOR_DIST == DEFAULT_NEIGHBOR_DIST


def test_4_cylinders_corpus_mission_flies_the_network_where_it_set_orca(tmp_path):
    original = read(FOUR_CYLINDERS)
    variant, changes = nn_mission.nn_variant(original, MODEL, source=FOUR_CYLINDERS)

    assert original == read(FOUR_CYLINDERS), "the mission given is not modified"
    assert [(c.where, c.state, c.was, c.network_state) for c in changes] == \
        [("State_Machine[3]", "algorithm_control", "orca3 set", "algorithm_control_nn")]
    # the state gives only N_neighbors_aware: the NAI's default distance
    assert changes[0].neighbor_dist == 6.0 and changes[0].neighbor_dist_from == "the default"
    teacher, network = variant["State_Machine"][3:5]
    was = original["State_Machine"][3]
    # the ORCA state keeps its parameters for the teacher, as a configure, and leads to the network's state
    assert teacher["parameters"] == {**was["parameters"], "action": "configure"}
    assert teacher["outcomes"] == {**was["outcomes"], "completed": "algorithm_control_nn"}
    assert network["parameters"] == nn_parameters(MODEL, 6.0)
    assert network["name"] == "algorithm_control_nn" and network["outcomes"] == was["outcomes"]
    assert {k: v for k, v in network.items() if k not in ("name", "parameters")} == \
        {k: v for k, v in was.items() if k not in ("name", "parameters")}  # ids, outcomes kept
    del variant["State_Machine"][4]
    variant["State_Machine"][3] = was
    assert variant == original, "nothing else changes"


def test_central_cylinder_corpus_mission_keeps_its_distance_unless_the_spec_gives_one(tmp_path):
    original = read(CENTRAL_CYLINDER)
    variant, changes = nn_mission.nn_variant(original, MODEL, source=CENTRAL_CYLINDER)
    assert [c.where for c in changes] == ["State_Machine[5]"]
    assert (changes[0].neighbor_dist, changes[0].neighbor_dist_from) == (6.0, "the mission's ORCA neighborDist")
    assert variant["State_Machine"][6]["parameters"] == nn_parameters(MODEL, 6.0)

    from_spec, changes = nn_mission.nn_variant(original, MODEL, neighbor_dist=4.5, source=CENTRAL_CYLINDER,
                                               fallback=True)
    assert (changes[0].neighbor_dist, changes[0].neighbor_dist_from) == (4.5, "the model's spec")
    assert from_spec["State_Machine"][6]["parameters"] == {**nn_parameters(MODEL, 4.5),
                                                           "params": ["neighborDist", "fallback"], "values": [4.5, 1]}
    # a teacher with a wider margin than the mission's: the configure state carries it
    taught, _ = nn_mission.nn_variant(original, MODEL, source=CENTRAL_CYLINDER, teacher={"agent_radius": 0.7})
    params = taught["State_Machine"][5]["parameters"]
    assert params["action"] == "configure" and params["values"][params["params"].index("agent_radius")] == 0.7
    assert params["params"] == original["State_Machine"][5]["parameters"]["params"]
    assert str(changes[0]) == ("State_Machine[5] 'algorithm_control': orca3 set -> orca3 configure (the teacher's "
                               "parameters), then 'algorithm_control_nn': neural_network set, neighborDist 4.5 "
                               "(the model's spec)")


def test_the_variant_is_a_mission_the_ground_station_accepts(tmp_path):
    from magna_gs.mission.loader import load_mission

    variant, changes = nn_mission.nn_variant(read(CROSSING), MODEL, source=CROSSING)
    assert (changes[0].where, changes[0].neighbor_dist) == ("State_Machine[4]", 8.0)  # the mission's own 8 m
    path = nn_mission.write_variant(tmp_path, "Gym", "2UAVs_Crossing_ORCA", variant)
    assert path == tmp_path / "missions" / "Gym" / "2UAVs_Crossing_ORCA_nn.json"
    loaded = load_mission(path)  # MissionError on anything the ground station would refuse
    controls = [(n.parameters.name, n.parameters.action) for n in loaded.mission.nodes()
                if getattr(n.parameters, "name", "") in ("neural_network", "orca3", "orca3d")]
    assert controls == [("orca3d", "configure"), ("neural_network", "set")]
    network = [n.parameters for n in loaded.mission.nodes() if getattr(n.parameters, "name", "") == "neural_network"]
    assert [(c.action, c.params, c.values, c.text_value) for c in network] == [("set", ("neighborDist",), (8.0,),
                                                                                  MODEL)]


def test_states_at_any_depth_are_followed_by_the_network_and_orca_configure_stays():
    configure = {"type": "CBState", "state_type": "algorithm_control", "name": "tune",
                 "parameters": {"name": "orca3d", "action": "configure", "params": ["neighborDist"], "values": [5.0]}}
    nested_set = {"type": "CBState", "state_type": "algorithm_control", "name": "deep",
                  "parameters": {"name": "orca3d", "action": "set"}, "outcomes": {"completed": "next"}}
    inner = {"type": "CBState", "state_type": "algorithm_control", "name": "inner",
             "parameters": {"name": "orca3", "action": "set", "params": ["N_neighbors_aware"], "values": [2]}}
    mission = {"Agents_Config": [], "State_Machine": [
        configure,
        {"type": "Concurrence", "name": "c", "occurrencies": [
            inner,
            {"type": "StateMachine", "name": "s", "occurrencies": [
                nested_set, {"type": "CBState", "state_type": "wait", "name": "next"},
                {"type": "CBState", "state_type": "wait", "name": "deep_nn"}]},
        ]},
        {"type": "CBState", "state_type": "algorithm_control", "name": "plain",
         "parameters": {"name": "simple", "action": "set"}},
    ]}
    variant, changes = nn_mission.nn_variant(mission, MODEL)
    assert [(c.where, c.state, c.network_state) for c in changes] == [
        ("State_Machine[1].occurrencies[0]", "inner", ""),  # side by side in a Concurrence: replaced in place
        ("State_Machine[1].occurrencies[1].occurrencies[0]", "deep", "deep_nn_2")]  # a name not taken
    assert "the teacher keeps ORCA-3D's defaults" in str(changes[0])
    # neither gives a distance: the one the mission's ORCA configure state gives
    assert {(c.neighbor_dist, c.neighbor_dist_from) for c in changes} == {(5.0, "the mission's ORCA neighborDist")}
    machine = variant["State_Machine"]
    assert machine[0] == configure and machine[2] == mission["State_Machine"][2]
    assert machine[1]["occurrencies"][0]["parameters"] == nn_parameters(MODEL, 5.0)
    deep, network = machine[1]["occurrencies"][1]["occurrencies"][:2]
    assert deep["parameters"] == {"name": "orca3d", "action": "configure"}
    assert deep["outcomes"] == {"completed": "deep_nn_2"} and network["outcomes"] == {"completed": "next"}
    assert network["parameters"] == nn_parameters(MODEL, 5.0)
    assert nested_set["parameters"] == {"name": "orca3d", "action": "set"} and len(mission["State_Machine"]) == 3
    # the teacher's own parameters: added to a configure; a Concurrence has no state to carry them
    with pytest.raises(nn_mission.FlyError, match="inside a Concurrence.*teacher's parameters"):
        nn_mission.nn_variant(mission, MODEL, teacher={"agent_radius": 0.7})
    mission["State_Machine"][1]["occurrencies"].pop(0)
    taught, _ = nn_mission.nn_variant(mission, MODEL, teacher={"agent_radius": 0.7})
    assert taught["State_Machine"][1]["occurrencies"][0]["occurrencies"][0]["parameters"] == \
        {"name": "orca3d", "action": "configure", "params": ["agent_radius"], "values": [0.7]}


@pytest.mark.parametrize("mission", [SIMPLE_MISSION, CORPUS / "Missions" / "Gym" / "only_world.json"],
                         ids=["simple", "only_world"])
def test_a_mission_without_orca_is_refused_naming_the_file(mission):
    with pytest.raises(nn_mission.FlyError) as error:
        nn_mission.nn_variant(read(mission), MODEL, source=mission)
    assert str(mission) in str(error.value) and "orca3" in str(error.value)
    if mission == SIMPLE_MISSION:
        assert "simple set at State_Machine[" in str(error.value)


def test_a_relative_model_path_or_a_non_mission_is_refused():
    with pytest.raises(nn_mission.FlyError, match="relative"):
        nn_mission.nn_variant(read(CROSSING), "model.pt")
    with pytest.raises(nn_mission.FlyError, match="x.json: not a mission"):
        nn_mission.nn_variant({"Agents_Config": []}, MODEL, source="x.json")


def test_the_variant_file_is_never_replaced_by_a_different_one_without_overwrite(tmp_path):
    first, _ = nn_mission.nn_variant(read(CROSSING), MODEL)
    second, _ = nn_mission.nn_variant(read(CROSSING), "/other/model.pt")
    path = nn_mission.write_variant(tmp_path, "Gym", "X", first)
    assert read(path) == first
    assert nn_mission.write_variant(tmp_path, "Gym", "X", first) == path  # the same content: kept as it is
    with pytest.raises(nn_mission.FlyError, match="--overwrite"):
        nn_mission.write_variant(tmp_path, "Gym", "X", second)
    assert read(path) == first
    nn_mission.write_variant(tmp_path, "Gym", "X", second, overwrite=True)
    assert read(path) == second
    assert sorted(p.name for p in path.parent.iterdir()) == ["X_nn.json"], "no temporary file left"


# --- metrics on synthetic datasets --------------------------------------------------------------------------

def write_uav_csv(path: Path, uav_id: int, other: int, flight: list[tuple[float, str, str]]) -> None:
    """A recorder CSV by hand: one row per (time, role, outcome); the nearest UAV's gap grows with time (0.1 t - 0.2
    m); every other column unknown."""
    header = columns([other], n_obstacles=0)
    blank = {name: "nan" for name in header}
    blank.update({"uav_id": str(uav_id), "algorithm": "orca3d", "collided_with": "", "feasible": "", "fallback": "",
                  "outcome": "",
                  "collision": "0", "out_of_bounds": "0", "low_battery": "0", "ual_state": "4"})
    lines = [",".join(header)]
    for t, role, outcome in flight:
        row = dict(blank, time=repr(t), role=role, outcome=outcome, nearest_uav_gap=repr(round(0.1 * t - 0.2, 3)))
        lines.append(",".join(row[name] for name in header))
    path.write_text("\n".join(lines) + "\n")


def flight(paths: list[tuple[float, float, str]]) -> list[tuple[float, str, str]]:
    """take-off, then each path role (start, seconds, outcome) at 10 steps per second, then landing."""
    rows = [(0.0, "take_off", ""), (0.5, "take_off", "succeeded")]
    for start, seconds, outcome in paths:
        steps = round(seconds * 10)
        rows += [(start + k / 10, "path", outcome if k == steps else "") for k in range(steps + 1)]
    end = rows[-1][0]
    return rows + [(end + 1.0, "land", ""), (end + 2.0, "land", "succeeded")]


def add_simulation(dataset: Path, m: int, success: bool, collisions: int, uavs: dict[int, list],
                   termination: str = "ground_station", seed: int | None = None) -> None:
    sim = dataset / f"simulation_{m}"
    sim.mkdir(parents=True)
    outcome = termination if termination != "ground_station" else ("completed" if success else "failed")
    result = SimulationResult(id=m, seed=m if seed is None else seed, success=success, outcome=outcome,
                              termination=termination, message="", sim_duration=60.0, wall_time=9.0,
                              collisions=collisions)
    result.write(sim / RESULT_FILE)
    summary = dataset / SUMMARY_FILE
    SummaryRow.write(summary, [*(SummaryRow.read(summary) if summary.exists() else []), SummaryRow.of(result)])
    for uav_id, paths in uavs.items():
        write_uav_csv(sim / f"uav_{uav_id}.csv", uav_id, 3 - uav_id, flight(paths))


def orca_dataset(root: Path) -> Path:
    dataset = root / "orca" / "dataset_1"
    add_simulation(dataset, 1, True, 0, {1: [(1.0, 10.0, "succeeded")], 2: [(1.0, 12.0, "succeeded")]})
    add_simulation(dataset, 2, False, 2, {1: [(1.0, 4.0, "collision")], 2: [(1.0, 4.0, "preempted")]})
    # UAV 1 flies two paths (from the start of the first to the end of the second: 9 s); UAV 2 flies none
    add_simulation(dataset, 3, True, 0, {1: [(5.0, 3.0, "succeeded"), (9.0, 5.0, "succeeded")], 2: []})
    # stopped by Ctrl-C: says nothing about the algorithm, whatever its files hold
    add_simulation(dataset, 4, False, 0, {1: [(1.0, 1.0, "succeeded")]}, termination="interrupted")
    return dataset


def test_the_synthetic_csvs_are_recorder_csvs(tmp_path):
    dataset = orca_dataset(tmp_path)
    header, rows = read_csv(dataset / "simulation_3" / "uav_1.csv")
    assert header == columns([2], 0)
    assert [r["outcome"] for r in rows if r["outcome"]] == ["succeeded"] * 4


def test_batch_metrics_from_a_dataset(tmp_path):
    metrics = flight_metrics.read_batch(orca_dataset(tmp_path), "ORCA-3D")
    assert (metrics.simulations, metrics.left_out, metrics.successes, metrics.collision_free) == (3, 1, 2, 2)
    assert metrics.collision_free_rate == pytest.approx(2 / 3)
    assert metrics.uav_paths == 5  # simulation 1: 2, simulation 2: 2, simulation 3: 1
    assert metrics.times_to_goal == pytest.approx([10.0, 12.0, 9.0])
    assert metrics.mean_time_to_goal == pytest.approx(31 / 3)
    assert metrics.std_time_to_goal == pytest.approx(statistics.stdev([10.0, 12.0, 9.0]))
    assert metrics.seeds == [1, 2, 3]


def test_path_time_to_goal_needs_every_path_role_to_succeed():
    rows = [{"time": t, "role": role, "outcome": outcome} for t, role, outcome in flight(
        [(1.0, 2.0, "succeeded"), (4.0, 2.0, "aborted")])]
    assert flight_metrics.path_time_to_goal(rows) == (True, None)
    unfinished = [dict(r, outcome="") for r in rows if r["role"] == "path"]
    assert flight_metrics.path_time_to_goal(unfinished) == (True, None)
    assert flight_metrics.path_time_to_goal([r for r in rows if r["role"] != "path"]) == (False, None)


def test_a_dataset_without_simulations_is_refused(tmp_path):
    with pytest.raises(nn_mission.FlyError, match="no summary.csv"):
        flight_metrics.read_batch(tmp_path / "nothing", "network")


def test_comparison_table_numbers_and_figure(tmp_path):
    orca = flight_metrics.read_batch(orca_dataset(tmp_path), "ORCA-3D")
    nn_dir = tmp_path / "nn" / "dataset_1"
    add_simulation(nn_dir, 1, True, 0, {1: [(1.0, 11.0, "succeeded")], 2: [(1.0, 13.0, "succeeded")]})
    add_simulation(nn_dir, 2, False, 1, {1: [(1.0, 4.0, "collision")], 2: [(1.0, 4.0, "collision")]})
    add_simulation(nn_dir, 3, False, 3, {1: [(1.0, 4.0, "collision")], 2: []})
    comparison = flight_metrics.Comparison(orca, flight_metrics.read_batch(nn_dir, "network"), WORLD, MISSION, MODEL)
    assert comparison.ratio == pytest.approx(0.5) and comparison.meets_target is False and comparison.same_seeds

    files = flight_metrics.write_comparison(comparison, tmp_path / "out")
    assert [f.name for f in files] == ["comparison.md", "comparison.json", "comparison.png"]
    table = files[0].read_text()
    assert "| collision-free | 2/3 (66.7%) | 1/3 (33.3%) |" in table
    assert "| UAV paths to the goal | 3/5 (60.0%) | 2/5 (40.0%) |" in table
    assert f"| time to goal (s, mean ± std) | 10.3 ± {statistics.stdev([10.0, 12.0, 9.0]):.1f} | 12.0 ± 1.4 |" \
        in table
    assert "**0.500** (target >= 0.95: NOT met)" in table
    assert "1 simulation(s) left out" in table and "same seeds" not in table
    numbers = read(files[1])
    assert numbers["collision_free_ratio"] == pytest.approx(0.5) and numbers["meets_target"] is False
    assert numbers["orca"]["simulations"] == 3 and numbers["network"]["collision_free"] == 1
    assert numbers["network"]["mean_time_to_goal"] == pytest.approx(12.0)
    assert files[2].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [f.name for f in sorted(files)]


def test_several_batches_side_by_side_with_the_minimum_gap_flown_on_paths(tmp_path):
    orca = flight_metrics.read_batch(orca_dataset(tmp_path), "ORCA-3D")
    # the gap is 0.1 t - 0.2 m; paths start at t = 1 (simulations 1, 2) and t = 5 (3); the take-off's -0.2 m at
    # t = 0 is not on a path, and simulation 4 (interrupted) is left out
    assert orca.min_gaps == pytest.approx([-0.1, -0.1, 0.3]) and orca.min_gap == pytest.approx(-0.1)
    rl_dir = tmp_path / "rl" / "dataset_1"
    add_simulation(rl_dir, 1, True, 0, {1: [(3.0, 2.0, "succeeded")], 2: [(4.0, 2.0, "succeeded")]})
    rl = flight_metrics.read_batch(rl_dir, "RL")
    table = flight_metrics.side_by_side([orca, rl], "Gym/Crossing")
    assert "| | ORCA-3D | RL |" in table
    assert "| collision-free | 2/3 (67%) | 1/1 (100%) |" in table
    assert "| minimum gap between UAVs (m) | -0.10 (median -0.10) | 0.10 (median 0.10) |" in table
    assert f"- RL: `{rl_dir}`" in table


def test_comparison_without_a_collision_free_orca_run_or_with_other_seeds(tmp_path):
    orca_dir, nn_dir = tmp_path / "o", tmp_path / "n"
    add_simulation(orca_dir, 1, False, 1, {1: [(1.0, 2.0, "collision")]})
    add_simulation(nn_dir, 1, True, 0, {1: [(1.0, 2.0, "succeeded")]}, seed=8)
    orca, network = flight_metrics.read_batch(orca_dir, "ORCA-3D"), flight_metrics.read_batch(nn_dir, "network")
    comparison = flight_metrics.Comparison(orca, network, WORLD, MISSION, MODEL)
    assert comparison.ratio is None and comparison.meets_target is None and not comparison.same_seeds
    table = comparison.markdown()
    assert "undefined" in table and "not flown with the same seeds" in table
    flight_metrics.draw_comparison(comparison, tmp_path / "c.png")  # no time to goal for ORCA-3D: drawn as n/a


# --- the command, with a stand-in for magna run -------------------------------------------------------------

STUB = """#!/usr/bin/env python3
# Stands in for the magna command: logs each call; with FLY_STUB_HANG waits for SIGINT, then exits 130.
import json, os, signal, sys, time
log = os.environ["FLY_STUB_LOG"]
def write(entry):
    with open(log, "a") as out:
        out.write(json.dumps(entry) + "\\n")
def interrupted(signum, frame):
    write({"signal": signum})
    sys.exit(130)
signal.signal(signal.SIGINT, interrupted)
write({"argv": sys.argv[1:], "pid": os.getpid()})
if os.environ.get("FLY_STUB_HANG"):
    time.sleep(120)
"""


def stub_root(tmp_path: Path) -> Path:
    root = tmp_path / "stub"
    root.mkdir()
    (root / "magna").write_text(STUB)
    (root / "magna").chmod(0o755)
    return root


def start_fly(tmp_path: Path, model: Path, *extra: str, hang: bool = False) -> subprocess.Popen:
    env = dict(os.environ, MAGNA_ROOT=str(stub_root(tmp_path)), FLY_STUB_LOG=str(tmp_path / "calls.jsonl"))
    if hang:
        env["FLY_STUB_HANG"] = "1"
    command = [sys.executable, "-m", "mlr.fly", "--world", WORLD, "--mission", MISSION, "--model", str(model),
               "--data-root", str(tmp_path / "data"), "-o", str(tmp_path / "out"), "--name", "t", *extra]
    return subprocess.Popen(command, cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def calls(tmp_path: Path) -> list[dict]:
    path = tmp_path / "calls.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def option(argv: list[str], name: str) -> list[str]:
    return [argv[i + 1] for i, arg in enumerate(argv) if arg == name]


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    return make_model(tmp_path_factory.mktemp("model"))


def test_both_batches_get_the_same_seeds_and_the_network_mission(tmp_path):
    model = make_model(tmp_path / "model", neighbor_dist=5.0)  # its spec's distance wins over the mission's 8 m
    done = start_fly(tmp_path, model, "--seed", "7", "--n-iter", "3", "--search-path", str(CORPUS))
    _, stderr = done.communicate(timeout=120)
    # the stand-in wrote no data: the batches ran, then the comparison finds no dataset
    assert done.returncode == 2 and "no summary.csv" in stderr, stderr
    orca, nn = (c["argv"] for c in calls(tmp_path))
    out = str((tmp_path / "out").resolve())
    for argv in (orca, nn):
        assert argv[0] == "run"
        assert option(argv, "--seed") == ["7"] and option(argv, "--n-iter") == ["3"]
        assert option(argv, "--world") == [WORLD] and option(argv, "--rtf") == ["max"]
        assert option(argv, "--data-root") == [str((tmp_path / "data").resolve())]
    assert option(orca, "--mission") == [MISSION] and option(orca, "--name") == ["t_orca"]
    assert option(orca, "--search-path") == [str(CORPUS.resolve())]
    assert option(nn, "--mission") == [MISSION + "_nn"] and option(nn, "--name") == ["t_nn"]
    assert option(nn, "--search-path") == [out, str(CORPUS.resolve())]
    variant = read(tmp_path / "out" / "missions" / "Gym" / "2UAVs_Crossing_ORCA_nn.json")
    assert variant["State_Machine"][5]["parameters"] == nn_parameters(str(model), 5.0)


def test_compare_flies_one_orca_batch_and_each_network_with_the_same_seeds(tmp_path, model):
    other = make_model(tmp_path / "other")
    env = dict(os.environ, MAGNA_ROOT=str(stub_root(tmp_path)), FLY_STUB_LOG=str(tmp_path / "calls.jsonl"))
    command = [sys.executable, "-m", "mlr", "compare", "--world", WORLD, "--mission", MISSION,
               "--model", f"sup={model}", "--model", f"rl={other}", "--seed", "7", "--n-iter", "3",
               "--data-root", str(tmp_path / "data"), "-o", str(tmp_path / "out"), "--name", "t"]
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    # the stand-in wrote no data: the batches ran, then the table finds no dataset
    assert done.returncode == 2 and "no summary.csv" in done.stderr, done.stderr
    argvs = [c["argv"] for c in calls(tmp_path)]
    assert [option(a, "--name") for a in argvs] == [["t_orca"], ["t_sup_nn"], ["t_rl_nn"]]
    assert all(option(a, "--seed") == ["7"] and option(a, "--n-iter") == ["3"] for a in argvs)
    for label, path in (("sup", model), ("rl", other)):
        variant = read(tmp_path / "out" / label / "missions" / "Gym" / "2UAVs_Crossing_ORCA_nn.json")
        assert str(path) in json.dumps(variant)

    same = subprocess.run([*command[:8], "--model", f"rl={model}", *command[10:]], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60)
    assert same.returncode == 2 and "a label of its own" in same.stderr, same.stderr


def test_ctrl_c_stops_the_running_batch_and_starts_no_other(tmp_path, model):
    process = start_fly(tmp_path, model, hang=True)
    wait_until(lambda: calls(tmp_path), "the ORCA-3D batch to start", timeout=60)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    log = calls(tmp_path)
    assert len([c for c in log if "argv" in c]) == 1, "the network batch never starts"
    assert {"signal": int(signal.SIGINT)} in log, "the batch got the Ctrl-C"
    assert not Path(f"/proc/{log[0]['pid']}").exists(), "the batch is not left running"
    assert not (tmp_path / "out" / "comparison.md").exists()


def test_bad_input_starts_nothing(tmp_path, model):
    refused = start_fly(tmp_path, model, "--mission", str(SIMPLE_MISSION))
    _, stderr = refused.communicate(timeout=120)
    assert refused.returncode == 2 and str(SIMPLE_MISSION) in stderr
    assert calls(tmp_path) == [] and not (tmp_path / "out").exists() and not (tmp_path / "data").exists()

    # an ORCA-3D dataset that is there already, without --append/--overwrite/--skip-orca
    existing = tmp_path / "again"
    (existing / "data" / "Simulations" / "Gym" / "Central_Obstacle_Torus" / "Gym" / "2UAVs_Crossing_ORCA" / "t_orca"
     / "dataset_1" / "simulation_1").mkdir(parents=True)
    refused = start_fly(existing, model)
    _, stderr = refused.communicate(timeout=120)
    assert refused.returncode == 2 and "t_orca" in stderr and "--skip-orca" in stderr
    assert calls(existing) == []

    skip = tmp_path / "skip"
    skip.mkdir()
    refused = start_fly(skip, model, "--skip-orca")
    _, stderr = refused.communicate(timeout=120)
    assert refused.returncode == 2 and "--skip-orca" in stderr and "holds no simulations" in stderr
    assert calls(skip) == []


# --- both batches for real ----------------------------------------------------------------------------------

@pytest.mark.timeout(900)
def test_fly_one_simulation_each_through_magna_run(tmp_path, model):
    data, out = tmp_path / "data", tmp_path / "out"
    command = [sys.executable, "-m", "mlr.fly", "--world", WORLD, "--mission", MISSION, "--model", str(model),
               "--n-iter", "1", "--rtf", "5", "--no-bag", "--data-root", str(data), "--output", str(out)]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, stdin=subprocess.DEVNULL,
                          env=dict(os.environ, MAGNA_ROOT=str(ROOT)))
    assert done.returncode == 0, f"{done.stdout}\n{done.stderr}"

    base = data / "Simulations" / "Gym" / "Central_Obstacle_Torus" / "Gym"
    orca_sim = base / "2UAVs_Crossing_ORCA" / "fly_orca" / "dataset_1" / "simulation_1"
    nn_sim = base / "2UAVs_Crossing_ORCA_nn" / "fly_nn" / "dataset_1" / "simulation_1"
    results = [read(sim / "result.json") for sim in (orca_sim, nn_sim)]
    for result in results:
        assert result["termination"] == "ground_station", result["message"]
        assert result["leftover_processes_killed"] == []
    assert results[0]["seed"] == results[1]["seed"], "the same random waypoints"
    assert (nn_sim / "mission.json").read_text() == (out / "missions" / "Gym" / "2UAVs_Crossing_ORCA_nn.json") \
        .read_text()

    for sim, algorithm in ((orca_sim, "orca3d"), (nn_sim, "neural_network")):
        for uav in (1, 2):
            _, rows = read_csv(sim / f"uav_{uav}.csv")
            # the last step of a path hands over to the autopilot ("ual"); every other one is the algorithm's
            flown = {r["algorithm"] for r in rows if r["role"] == "path"} - {"ual"}
            assert flown == {algorithm}, (sim, uav, flown)

    numbers = read(out / "comparison.json")
    assert numbers["orca"]["simulations"] == numbers["network"]["simulations"] == 1
    assert numbers["orca"]["collision_free"] == 1 and numbers["orca"]["goals_reached"] == 2
    assert math.isfinite(numbers["orca"]["mean_time_to_goal"])
    assert numbers["same_seeds"] is True
    table = (out / "comparison.md").read_text()
    assert "| simulations | 1 | 1 |" in table and table in done.stdout
    assert (out / "comparison.png").stat().st_size > 0


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-v"]))
