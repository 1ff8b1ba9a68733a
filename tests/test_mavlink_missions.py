"""Missions that mix simulated and MAVLink UAVs, through `magna run --fleet` (issue 24).

Experiment II of the thesis: UAVs 1 and 2 are `sitl` (magna_sim's UAL), UAV 3 is `hil` and flies
over MAVLink: magna_sim's PX4-like vehicle stands in for its autopilot and the ground station
reaches it through a ual_mavlink bridge. The mission flies paths, a follower and ORCA-3D between
all three, and is recorded like any other. The same mission through a bad radio (20 % loss, 50 ms)
still succeeds; with the link cut for 5 s it takes its safety branch, saying why; a vehicle that is
not there stops the mission before anything takes off, naming its URL. No process is left behind.

The faults are wall-clock faults (the proxy's delay, the cut's 5 s), so those missions run at real time and
take about a minute each; the plain one runs as fast as the stand-in's set-point stream allows.
"""
import csv
import json
import subprocess
from pathlib import Path

import pytest

from magna_common.ports import free_udp_ports
from tests.support import ROOT

pytestmark = pytest.mark.timeout(600)

WORLD = "Gym/Central_Obstacle_Torus"
MISSION = "Gym/Experiment_II_SITL_HIL"
FLEETS = ROOT / "fleets"


def magna_run(fleet: Path, data_root: Path, rtf: str = "1", report: bool = False) -> subprocess.CompletedProcess:
    command = [str(ROOT / "magna"), "run", "--world", WORLD, "--mission", MISSION, "--fleet", str(fleet),
               "--data-root", str(data_root), "--time-limit", "300", "--rtf", rtf, *([] if report else ["--no-report"])]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"{' '.join(command)}\n{done.stdout}\n{done.stderr}"
    return done


def the_simulation(data_root: Path) -> tuple[Path, dict]:
    folders = sorted(data_root.glob("Simulations/*/*/*/*/default/dataset_1/simulation_*"))
    assert len(folders) == 1, folders
    return folders[0], json.loads((folders[0] / "result.json").read_text())


def rows(path: Path) -> list[dict]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


def highest(folder: Path, uav_id: int) -> float:
    return max(float(row["pos.z"]) for row in rows(folder / f"uav_{uav_id}.csv"))


def test_experiment_ii_flies_sitl_and_hil_uavs_together_and_records_them(tmp_path):
    # A stand-in flies in simulated time, so this one may go faster than real time (magna_sim's lockstep
    # keeps the simulation within reach of ual_mavlink's set-point stream).
    magna_run(FLEETS / "stand_in_hil.yaml", tmp_path, rtf="max", report=True)
    folder, result = the_simulation(tmp_path)
    assert result["success"] is True and result["outcome"] == "completed", result["message"]
    assert result["leftover_processes_killed"] == []
    for uav_id in (1, 2, 3):  # the MAVLink UAV is recorded like the simulated ones
        assert highest(folder, uav_id) > 2.5, f"UAV {uav_id} flew"
    # The simulated UAVs' managers see the MAVLink UAV (their evaluator measures its gap from this view),
    # and its manager sees them.
    for uav_id, other in ((1, 3), (2, 3), (3, 1)):
        seen = [float(row[f"uav{other}.pos.z"]) for row in rows(folder / f"uav_{uav_id}.csv")]
        assert max(seen) > 2.5, f"UAV {uav_id} saw UAV {other} fly"
    assert (folder / "simulation.bag").stat().st_size > 0
    assert (folder / "report.html").stat().st_size > 0  # the report reads a mixed mission as any other


def test_through_a_lossy_slow_link_the_mission_still_succeeds(tmp_path):
    magna_run(FLEETS / "stand_in_lossy_link.yaml", tmp_path)
    folder, result = the_simulation(tmp_path)
    assert result["success"] is True and result["outcome"] == "completed", result["message"]
    assert highest(folder, 3) > 2.5
    assert result["leftover_processes_killed"] == []


def test_a_link_cut_for_5_s_takes_the_safety_branch_and_says_why(tmp_path):
    magna_run(FLEETS / "stand_in_link_cut.yaml", tmp_path)
    folder, result = the_simulation(tmp_path)
    assert result["success"] is False and result["outcome"] == "failed", result["message"]
    assert "UAV 3 link_lost" in result["message"]
    for uav_id in (1, 2):  # the safety branch landed the simulated UAVs
        assert float(rows(folder / f"uav_{uav_id}.csv")[-1]["pos.z"]) < 0.5
    assert result["leftover_processes_killed"] == []


def test_a_vehicle_that_is_not_there_stops_the_mission_before_take_off(tmp_path):
    port = free_udp_ports(1)[0]
    fleet = tmp_path / "fleet.yaml"
    fleet.write_text(f"uavs: {{3: {{url: 'udpin:127.0.0.1:{port}', autopilot: px4}}}}\n")
    magna_run(fleet, tmp_path / "data")
    folder, result = the_simulation(tmp_path / "data")
    assert result["success"] is False, result["message"]
    assert f"UAV 3 (hil): no vehicle at udpin:127.0.0.1:{port}" in result["message"]
    assert "magna doctor --mavlink" in result["message"]
    for uav_id in (1, 2):  # nothing took off
        path = folder / f"uav_{uav_id}.csv"
        assert not path.exists() or highest(folder, uav_id) < 0.5
    assert result["leftover_processes_killed"] == []
