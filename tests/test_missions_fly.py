"""Whole simulations through `magna run`: the original ROS-MAGNA pairs fly as they are, the project's
own missions fly to the end their README describes, a collision ends in the mission's safety branch
with the data saved, storage conflicts are refused, no process outlives a batch, and a batch's persistent
stack flies a seed as a cold start does.

Each test starts the real stack (magna_sim, world node, orca3d_server, ground station, UAV
managers) on a private ROS master through the Master; a simulation takes 3-160 s of wall time.
"""
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from magna_uav.recorder import columns
from tests.support import CORPUS, ROOT
from tests.test_project_missions import PAIRS

pytestmark = pytest.mark.timeout(900)

# The pairs of the corpus README that need no UTM. 3UAVs_3paths_4_Cylinders flies in
# Empty_4_Cylinders: the README pairs it with Empty_4_Cylinders_1Obs, which has only two take-off cells.
CORPUS_PAIRS = [
    ("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", 2, True),
    ("Gym/Empty_4_Cylinders", "Gym/1UAVs_1paths_4_Cylinders", 1, True),
    ("Gym/Empty_4_Cylinders", "Gym/2UAVs_2paths_4_Cylinders", 2, True),
    ("Gym/Empty_4_Cylinders", "Gym/3UAVs_3paths_4_Cylinders", 3, True),
    ("Gym/1Obs_Central_Cylinder", "Gym/only_world", 0, True),
    ("Delivery/Delivery", "Delivery/2UAVs_follow_ap_safe", 2, True),
    # without ORCA the follower may touch the delivery UAV: the mission must still end, data saved
    ("Delivery/Delivery", "Delivery/2UAVs_follow_ap", 2, None),
    ("Delivery/Delivery", "Delivery/2UAVs_follow_ad_safe", 2, True),
]


# The project's missions (missions/README.md pairs each with its world). Each flies here to the end its
# README line describes, except those flown elsewhere through the stack their checks need:
FLOWN_ELSEWHERE = {
    "Gym/2UAVs_Crossing_ORCA": "tests/recorded_run.py",  # the recorded run many tests read
    "Gym/Experiment_II_SITL_HIL": "tests/test_mavlink_missions.py",  # its hil UAV needs the fleet's stand-in
    "Gym/Operator_Control": "src/magna_master/test/voice_commands_rostest.py",  # flown by voice, resumed, landed
}
# The roles each UAV flies, in order, one per goal (a role's last row in the CSV carries its outcome), and
# where a mission says so, the height it flies at.
TAKE_OFF, LAND = ["take_off"], ["land"]
PROJECT_ROLES = {
    "Gym/All_Take_Off": {uav: TAKE_OFF + LAND for uav in (1, 2, 3, 4)},  # take off at once, hover, land
    "Gym/Paths_Step_By_Step": {uav: TAKE_OFF + ["path"] * 5 + LAND for uav in (1, 2)},  # a goal per waypoint
    # 1 flies the tube's centre line; 2 follows 1 (agent_ad), 3 holds behind 2 (agent_ap); then the arrival box
    "Delivery/Follower_Queue": {1: TAKE_OFF + ["path"] * 3 + LAND, 2: TAKE_OFF + ["path", "agent_ad", "path"] + LAND,
                                3: TAKE_OFF + ["path", "agent_ap", "path"] + LAND},
    # two legs of two paths each, the recharge stop (land, take off again) between them
    "Gym/Battery_Recharge": {1: (TAKE_OFF + ["path"] * 2 + LAND) * 2},
    # in a batch the operator's button times out: the UAVs hold their stations (basic_move), then land
    "Gym/Safe_Stop": {uav: TAKE_OFF + ["path", "basic_move"] + LAND for uav in (1, 2)},
    # 1 carries the parcel out, lowers to drop it and back up, flies home; 2 films it (agent_ap), then returns
    "Delivery/Filmed_Delivery": {1: TAKE_OFF + ["path", "basic_move", "basic_move", "path"] + LAND,
                                 2: TAKE_OFF + ["agent_ap", "path"] + LAND},
    "SolarPlant/Inspection": {uav: TAKE_OFF + ["path"] + LAND for uav in (1, 2)},  # a zigzag over a field each
}
CRUISE_HEIGHT = {"Delivery/Filmed_Delivery": {1: 6.0, 2: 8.0}, "SolarPlant/Inspection": {1: 8.0, 2: 12.0}}


def test_every_project_mission_is_flown_by_a_test():
    assert set(PAIRS) == set(PROJECT_ROLES) | set(FLOWN_ELSEWHERE), "a mission of missions/README.md nobody flies"
    assert not set(PROJECT_ROLES) & set(FLOWN_ELSEWHERE)
    for mission, test in FLOWN_ELSEWHERE.items():
        assert mission.split("/")[1] in (ROOT / test).read_text(), f"{test} does not fly {mission}"


def magna_run(*args, data_root: Path, check: bool = True, rtf: str = "5") -> subprocess.CompletedProcess:
    # At a fixed 5x real time, not "max": magna_sim's lockstep keeps it from running ahead of a
    # flying UAV manager, but a manager that is not flying (between goals) is not waited for, and
    # the tests' outcome must not depend on how busy the machine is. Speed is bench/mission_batch.py's business.
    command = [str(ROOT / "magna"), "run", "--data-root", str(data_root), "--time-limit", "600", "--rtf", rtf, *args]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, stdin=subprocess.DEVNULL)
    if check:
        assert done.returncode == 0, f"{' '.join(command)}\n{done.stdout}\n{done.stderr}"
    return done


def only_simulation(data_root: Path) -> Path:
    folders = sorted(data_root.glob("Simulations/*/*/*/*/default/dataset_1/simulation_*"))
    assert len(folders) == 1, folders
    return folders[0]


def read_rows(path: Path) -> list[dict]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize(("world", "mission", "n_uavs", "succeeds"), CORPUS_PAIRS,
                         ids=[m.split("/")[1] for _, m, _, _ in CORPUS_PAIRS])
def test_original_missions_fly_as_they_are(tmp_path, world, mission, n_uavs, succeeds):
    magna_run("--search-path", str(CORPUS), "--world", world, "--mission", mission, "--n-iter", "1",
              data_root=tmp_path)
    folder = only_simulation(tmp_path)
    result = json.loads((folder / "result.json").read_text())
    assert result["termination"] == "ground_station", result["message"]
    assert result["outcome"] == "completed", result["message"]
    if succeeds is not None:
        assert result["success"] is succeeds, result["message"]
    assert result["leftover_processes_killed"] == []
    assert (folder / "mission.json").read_text() == (CORPUS / "Missions" / f"{mission}.json").read_text()
    world_record = json.loads((folder / "world.json").read_text())
    assert world_record["parts"], "the world the simulation flew in is recorded"
    assert (folder / "simulation.bag").stat().st_size > 0
    ids = list(range(1, n_uavs + 1))
    for uav_id in ids:
        rows = read_rows(folder / f"uav_{uav_id}.csv")
        assert rows and list(rows[0]) == columns([i for i in ids if i != uav_id])
    summary = read_rows(folder.parent / "summary.csv")
    assert [r["outcome"] for r in summary] == ["completed"]


@pytest.mark.parametrize("mission", sorted(PROJECT_ROLES))
def test_project_missions_fly_to_their_intended_end(tmp_path, mission):
    # rtf 10: a manager between goals is not waited for by the simulator, so not max (see magna_run)
    magna_run("--world", PAIRS[mission], "--mission", mission, "--n-iter", "1", "--no-bag", "--no-report",
              data_root=tmp_path, rtf="10")
    folder = only_simulation(tmp_path)
    result = json.loads((folder / "result.json").read_text())
    assert (result["termination"], result["outcome"], result["success"]) == ("ground_station", "completed", True), \
        result["message"]
    assert result["collisions"] == 0 and result["leftover_processes_killed"] == []
    for uav_id, roles in PROJECT_ROLES[mission].items():
        rows = read_rows(folder / f"uav_{uav_id}.csv")
        ended = [(row["role"], row["outcome"]) for row in rows if row["outcome"]]
        assert ended == [(role, "succeeded") for role in roles], f"UAV {uav_id}"
        heights = [float(row["pos.z"]) for row in rows]
        assert max(heights) > 1.5 and heights[-1] < 0.2, f"UAV {uav_id} took off and landed: {heights[-1]:.2f} m"
        if uav_id in CRUISE_HEIGHT.get(mission, {}):
            assert abs(max(heights) - CRUISE_HEIGHT[mission][uav_id]) < 0.5, f"UAV {uav_id}: {max(heights):.2f} m"


def test_a_collision_ends_in_the_safety_branch_with_the_data_saved(tmp_path):
    mission = ROOT / "tests" / "missions" / "Test" / "2UAVs_Head_On_Simple.json"
    magna_run("--world", "Gym/Central_Obstacle_Torus", "--mission", str(mission), "--n-iter", "1",
              data_root=tmp_path)
    folder = only_simulation(tmp_path)
    result = json.loads((folder / "result.json").read_text())
    assert result["outcome"] == "completed" and result["success"] is False
    assert "collision" in result["message"] and result["collisions"] >= 1
    roles_at_contact = []
    for uav_id in (1, 2):
        rows = read_rows(folder / f"uav_{uav_id}.csv")
        roles = [r["role"] for r in rows]
        # the mission's flow: the crossing, then the safety branch (hover as basic_move, then land)
        assert list(dict.fromkeys(roles)) == ["take_off", "path", "basic_move", "land"], list(dict.fromkeys(roles))
        roles_at_contact.append(next(r["role"] for r in rows if r["collision"] == "1"))
    # the UAV whose evaluator saw the contact first ended the crossing; the other one was preempted
    assert "path" in roles_at_contact, roles_at_contact


def test_an_existing_dataset_is_never_overwritten_without_a_flag(tmp_path):
    mission = ROOT / "tests" / "missions" / "Test" / "2UAVs_Head_On_Simple.json"
    args = ("--world", "Gym/Central_Obstacle_Torus", "--mission", str(mission), "--n-iter", "1", "--no-bag")
    magna_run(*args, data_root=tmp_path)
    first = only_simulation(tmp_path)
    before = (first / "uav_1.csv").read_bytes()
    refused = magna_run(*args, data_root=tmp_path, check=False)
    assert refused.returncode == 2
    assert "--append" in refused.stderr and "--overwrite" in refused.stderr
    assert (first / "uav_1.csv").read_bytes() == before


@pytest.mark.parametrize(("args", "message"), [
    (("--world", "Gym/No_Such_World", "--mission", "Gym/2UAVs_Crossing_ORCA"), "No_Such_World"),
    (("--world", "Gym/Central_Obstacle_Torus", "--mission", "Gym/No_Such_Mission"), "No_Such_Mission"),
])
def test_unknown_worlds_and_missions_are_refused_before_anything_starts(tmp_path, args, message):
    refused = magna_run(*args, data_root=tmp_path, check=False)
    assert refused.returncode == 2
    assert message in refused.stderr
    assert not (tmp_path / "Simulations").exists()


def test_no_process_outlives_a_batch(tmp_path):
    """Every process started for the batch carries the batch's environment; none is left after it."""
    token = f"magna-batch-check-{os.getpid()}"
    env = dict(os.environ, MAGNA_BATCH_CHECK=token)
    command = [str(ROOT / "magna"), "run", "--data-root", str(tmp_path), "--world", "Gym/Central_Obstacle_Torus",
               "--mission", str(ROOT / "tests/missions/Test/2UAVs_Head_On_Simple.json"), "--n-iter", "1",
               "--no-bag"]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, env=env, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    alive = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            if token.encode() in (proc / "environ").read_bytes():
                alive.append(int(proc.name))
        except OSError:
            continue
    assert alive == [], f"processes of the batch still running: {alive}"


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-v"]))


# A warm stack against a cold start, same seed. Two cold starts of one seed are not bit-exact (the
# processes meet the simulated clock at slightly different steps: the lockstep lets time lead a
# manager by up to 0.15 s), so the flights are compared within what cold starts differ by among
# themselves: measured 0.29 m at most between the paths of two cold starts of the crossing, and
# 0.57 s between their durations (2 cores, loaded). The tolerances leave room over that.
PATH_TOLERANCE = 0.6  # m: the farthest any point of one UAV's path is from the other run's path
DURATION_TOLERANCE = 2.0  # simulated s


def path_distance(first: list[dict], second: list[dict]) -> float:
    """The symmetric Hausdorff distance between two recorded paths (time left out)."""
    a = np.array([[float(r["pos.x"]), float(r["pos.y"]), float(r["pos.z"])] for r in first])
    b = np.array([[float(r["pos.x"]), float(r["pos.y"]), float(r["pos.z"])] for r in second])
    gaps = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    return float(max(gaps.min(axis=1).max(), gaps.min(axis=0).max()))


def test_a_warm_stack_flies_a_seed_as_a_cold_start_does(tmp_path):
    pair = ("--world", "Gym/Central_Obstacle_Torus", "--mission", "Gym/2UAVs_Crossing_ORCA")
    magna_run(*pair, "--n-iter", "2", "--seed", "0", data_root=tmp_path / "warm")
    magna_run(*pair, "--n-iter", "1", "--seed", "1", "--cold-start", data_root=tmp_path / "cold")
    dataset = "Simulations/Gym/Central_Obstacle_Torus/Gym/2UAVs_Crossing_ORCA/default/dataset_1"
    first, warm = (tmp_path / "warm" / dataset / f"simulation_{m}" for m in (1, 2))
    cold = tmp_path / "cold" / dataset / "simulation_1"
    results = {name: json.loads((folder / "result.json").read_text())
               for name, folder in (("first", first), ("warm", warm), ("cold", cold))}
    assert results["first"]["stack"] == {"start": "cold", "index": 1}
    assert results["warm"]["stack"] == {"start": "warm", "index": 2}
    assert "stack" not in results["cold"]  # a fresh master and launch: no stack at all
    assert results["warm"]["seed"] == results["cold"]["seed"] == 2
    for key in ("termination", "outcome", "success", "collisions"):
        assert results["warm"][key] == results["cold"][key], key
    assert abs(results["warm"]["sim_duration"] - results["cold"]["sim_duration"]) <= DURATION_TOLERANCE
    assert (warm / "world.json").read_text() == (cold / "world.json").read_text()
    for uav_id in (1, 2):
        warm_rows, cold_rows = (read_rows(folder / f"uav_{uav_id}.csv") for folder in (warm, cold))
        assert list(dict.fromkeys(r["role"] for r in warm_rows)) == list(dict.fromkeys(r["role"] for r in cold_rows))
        assert path_distance(warm_rows, cold_rows) <= PATH_TOLERANCE, uav_id
    # the warm simulation ran on the stack the first one started: only the ground station was started for it
    assert Path(results["warm"]["launch_command"][1]).name == "ground_station"
