"""One real simulation recorded once per test session, for every test that reads a bag and CSVs.

`recorded_run` (root conftest.py) flies the project's mission Gym/2UAVs_Crossing_ORCA (two iris
UAVs cross with ORCA-3D; take-off, path, landing) in the world Gym/Central_Obstacle_Torus through
the whole stack (`magna run`), at a fixed 5x real time (as tests/test_missions_fly.py runs
missions: results must not depend on how busy the machine is). About 20 s of wall time. mlr
reads its steps, magna_viz replays its bag and draws its plots and report.
"""
from __future__ import annotations

import json
import os
import subprocess
from dataclasses import dataclass
from pathlib import Path

from tests.support import ROOT


@dataclass(frozen=True)
class RecordedRun:
    """One recorded simulation: where it is and the selection that finds it."""

    data_root: Path
    sim_dir: Path  # .../dataset_1/simulation_1: uav_<id>.csv, simulation.bag, mission.json, world.json, result.json
    world: str = "Gym"
    subworld: str = "Central_Obstacle_Torus"
    mission: str = "Gym"
    submission: str = "2UAVs_Crossing_ORCA"
    name: str = "test"
    dataset: int = 1
    uav_ids: tuple[int, ...] = (1, 2)

    def selection(self):
        from mlr.pickler import Selection

        return Selection(self.data_root, self.world, self.subworld, self.mission, self.submission, self.name,
                         (self.dataset,))


def _processes_with(token: str) -> list[int]:
    """Processes whose environment holds `token`: what a batch started and left behind."""
    alive = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                if token.encode() in (proc / "environ").read_bytes():
                    alive.append(int(proc.name))
            except OSError:
                continue
    return alive


def record_run(data_root: Path) -> RecordedRun:
    """Fly the simulation into `data_root` and check it ended well and left no process behind."""
    run = RecordedRun(data_root=data_root, sim_dir=Path())
    # Every process of the batch inherits this token, so any one left running afterwards is found.
    token = f"magna-recorded-run-{os.getpid()}"
    command = [str(ROOT / "magna"), "run", "--world", f"{run.world}/{run.subworld}",
               "--mission", f"{run.mission}/{run.submission}", "--n-iter", "1", "--rtf", "5",
               "--data-root", str(run.data_root), "--name", run.name, "--dataset", str(run.dataset)]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, stdin=subprocess.DEVNULL,
                          env=dict(os.environ, MAGNA_RECORDED_RUN_TOKEN=token), timeout=900)
    assert done.returncode == 0, f"{' '.join(command)}\n{done.stdout}\n{done.stderr}"
    assert _processes_with(token) == [], "processes of the recorded run are still running"
    sims = sorted(run.selection().dataset_dirs()[0].glob("simulation_*"))
    assert len(sims) == 1, sims
    result = json.loads((sims[0] / "result.json").read_text())
    assert result["success"] is True, result.get("message")
    assert result["leftover_processes_killed"] == []
    return RecordedRun(run.data_root, sims[0])
