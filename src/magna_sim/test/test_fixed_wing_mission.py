"""A plane flies a whole mission through the real stack (`magna run` at rtf max): a climb-out take-off,
a circuit of about 1.3 km through four waypoints reached on their loiter circles, and a landing that ends
LANDED_ARMED. The test waits for the batch to end (its own time limit guards it), not on a wall time."""
import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from magna_common.airframes import load_airframe

pytestmark = pytest.mark.timeout(900)

ROOT = Path(__file__).resolve().parents[3]
FILES = Path(__file__).resolve().parent / "fixed_wing_mission"  # Worlds/Test/Airfield, Missions/Test/1Plane_Circuit
LANDED_ARMED = 2


def test_a_plane_flies_a_circuit_mission_to_success(tmp_path):
    command = [str(ROOT / "magna"), "run", "--search-path", str(FILES), "--world", "Test/Airfield",
               "--mission", "Test/1Plane_Circuit", "--n-iter", "1", "--rtf", "max", "--no-report",
               "--data-root", str(tmp_path), "--time-limit", "600"]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"{' '.join(command)}\n{done.stdout}\n{done.stderr}"
    (folder,) = tmp_path.glob("Simulations/Test/Airfield/Test/1Plane_Circuit/default/dataset_1/simulation_*")
    result = json.loads((folder / "result.json").read_text())
    assert result["outcome"] == "completed" and result["success"] is True, result["message"]
    assert result["collisions"] == 0

    with (folder / "uav_1.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert list(dict.fromkeys(r["role"] for r in rows)) == ["take_off", "path", "land"]
    assert [r["outcome"] for r in rows if r["outcome"]] == ["succeeded"] * 3
    position = np.array([[float(r[f"pos.{a}"]) for a in "xyz"] for r in rows])
    speed = np.linalg.norm(np.array([[float(r[f"vel.{a}"]) for a in "xyz"] for r in rows]), axis=1)
    fw = load_airframe("plane").fixed_wing
    airborne = position[:, 2] > 0.5
    assert speed[airborne].min() >= fw.stall_speed, "a plane in the air never flies below stall"
    cruising = np.array([r["role"] == "path" for r in rows])
    assert np.median(speed[cruising]) == pytest.approx(fw.cruise_speed, rel=0.05)
    assert np.linalg.norm(np.diff(position, axis=0), axis=1).sum() > 1000.0
    assert int(rows[-1]["ual_state"]) == LANDED_ARMED and position[-1, 2] < 0.05
    assert float(rows[-1]["battery"]) > 0.9  # a kilometre and a half is a small part of a plane's battery
