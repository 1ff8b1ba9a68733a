"""Whole simulations through `magna run`: the original ROS-MAGNA pairs fly as they are, a collision
ends in the mission's safety branch with the data saved, storage conflicts are refused, and no
process outlives a batch.

Each test starts the real stack (magna_sim, world node, orca3d_server, ground station, UAV
managers) on a private ROS master through the Master; a simulation takes 3-160 s of wall time.
"""
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from magna_uav.recorder import columns
from tests.support import CORPUS, ROOT

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
