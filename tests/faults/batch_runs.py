"""Running `magna run` on the real stack for the fault tests of the batch (signals, a full disk, endurance).

The mission is tests/missions/Test/1UAV_Short_Hop.json (one UAV takes off to 1.5 m and lands, about
6 simulated seconds) in worlds/Gym/Four_Cylinders.json, at --rtf max: a whole simulation, launch to
clean-up, in about 10 wall seconds. Every process a batch starts inherits FAULT_TOKEN_ENV, so the
tests find any that outlives it.
"""
from __future__ import annotations

import csv
import hashlib
import json
import os
import signal
import subprocess
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.processes import tagged_processes
from magna_common.storage_tree import (
    LOGS_DIR,
    MISSION_FILE,
    RESULT_FILE,
    SUMMARY_FILE,
    existing_simulations,
    simulation_dir,
)
from tests.support import ROOT

WORLD = ROOT / "worlds" / "Gym" / "Four_Cylinders.json"
SHORT_MISSION = ROOT / "tests" / "missions" / "Test" / "1UAV_Short_Hop.json"
FAULT_TOKEN_ENV = "MAGNA_FAULT_TEST_TOKEN"
# The phases of a simulation a batch can be interrupted in, each with the file in the simulation's folder that
# shows it has begun: launch (the supervisor started roslaunch), flight (the ground station copied the
# mission), finishing (result.json written, the launch coming down). The signal tests and
# bench/interrupt_latency.py signal a batch there.
PHASE_FILES = {"launch": Path(LOGS_DIR) / "launch.log", "flight": Path(MISSION_FILE), "finishing": Path(RESULT_FILE)}


def dataset_dir(data_root: Path) -> Path:
    """Where a batch of the short mission saves its dataset 1 (the storage tree of magna_common)."""
    from magna_common.storage_tree import StorageKey

    return StorageKey("Gym", "Four_Cylinders", "Test", "1UAV_Short_Hop", "default").dataset_dir(data_root, 1)


@dataclass
class MagnaRun:
    """One `magna run` of the short mission in a session of its own; its output goes to files."""

    data_root: Path
    log_dir: Path
    args: tuple[str, ...] = ()
    token: str = field(default_factory=lambda: uuid.uuid4().hex)
    process: subprocess.Popen | None = None

    def start(self) -> MagnaRun:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        argv = [str(ROOT / "magna"), "run", "--world", str(WORLD), "--mission", str(SHORT_MISSION),
                "--data-root", str(self.data_root), "--rtf", "max", *self.args]
        env = {**os.environ, FAULT_TOKEN_ENV: self.token}
        with open(self.log_dir / "stdout.txt", "w") as out, open(self.log_dir / "stderr.txt", "w") as err:
            self.process = subprocess.Popen(argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=env,
                                            cwd=ROOT, start_new_session=True)
        return self

    @property
    def pid(self) -> int:
        assert self.process is not None
        return self.process.pid

    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def wait(self, timeout: float) -> int:
        assert self.process is not None
        return self.process.wait(timeout)

    def output(self) -> str:
        return "\n".join((self.log_dir / name).read_text(errors="replace") for name in ("stdout.txt", "stderr.txt")
                         if (self.log_dir / name).is_file())

    def alive(self) -> list[tuple[int, str]]:
        """Processes started by this run (at any depth) that are still alive."""
        return tagged_processes(FAULT_TOKEN_ENV, self.token, exclude={os.getpid()})

    def wait_for_no_process(self, timeout: float = 10.0) -> list[tuple[int, str]]:
        """The processes of this run still alive after up to `timeout` s (those ending are given that long)."""
        deadline = time.monotonic() + timeout
        left = self.alive()
        while left and time.monotonic() < deadline:
            time.sleep(0.05)
            left = self.alive()
        return left

    def kill_everything(self) -> None:
        """Clean-up after a failed assertion: SIGKILL the run and every process it started."""
        if self.running():
            os.killpg(self.pid, signal.SIGKILL)
            self.process.wait()
        for pid, _command in self.alive():
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def wait_for(predicate, what: str, run: MagnaRun, timeout: float = 180.0, poll: float = 0.02) -> None:
    """Wait until `predicate()` holds; fail naming `what` (with the run's output) if the run ends first."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if not run.running():
            if predicate():
                return
            raise AssertionError(f"magna run ended (status {run.process.returncode}) before {what}:\n"
                                 f"{run.output()[-3000:]}")
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}:\n{run.output()[-3000:]}")
        time.sleep(poll)


def summary_rows(dataset: Path) -> list[dict[str, str]]:
    """summary.csv as text cells (none when it does not exist)."""
    path = dataset / SUMMARY_FILE
    if not path.is_file():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def summary_ids(dataset: Path) -> list[int]:
    return [int(row["id"]) for row in summary_rows(dataset)]


def result_of(dataset: Path, m: int) -> dict | None:
    path = simulation_dir(dataset, m) / "result.json"
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def folder_digest(folder: Path) -> dict[str, str]:
    """Every file under `folder` (relative path) with the sha256 of its content."""
    digest = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file():
            digest[str(path.relative_to(folder))] = hashlib.sha256(path.read_bytes()).hexdigest()
    return digest


def temporary_files(dataset: Path) -> list[Path]:
    """Files an atomic write or a recorder leaves only when interrupted half-way: none may stay."""
    return sorted(p for p in dataset.rglob("*") if p.name.endswith((".tmp", ".active")))


def check_dataset(dataset: Path) -> dict[int, dict]:
    """What holds after every batch, interrupted or not; returns each simulation's result.json.

    Every simulation folder has a final result.json and exactly one summary row that agrees with it,
    the ids run 1..N without a gap, and no half-written file is left.
    """
    ids = existing_simulations(dataset)
    assert ids == list(range(1, len(ids) + 1)), f"simulation folders are not numbered 1..N: {ids}"
    rows = summary_rows(dataset)
    assert [int(r["id"]) for r in rows] == ids, f"summary.csv rows {[r['id'] for r in rows]} != folders {ids}"
    results = {}
    for row in rows:
        m = int(row["id"])
        result = result_of(dataset, m)
        assert result is not None, f"simulation_{m} has no readable result.json"
        assert result["final"] is True, f"simulation_{m}: result.json is not final: {result}"
        assert (row["success"], row["outcome"]) == (str(result["success"]), result["outcome"]), (row, result)
        results[m] = result
    assert not temporary_files(dataset), temporary_files(dataset)
    return results


def append_one_simulation(data_root: Path, log_dir: Path, *args: str) -> dict[int, dict]:
    """`magna run --n-iter 1 --append` on the dataset after a fault: it must run to its end, exit 0 and leave no
    process; returns check_dataset's results (the appended simulation is the last)."""
    run = MagnaRun(data_root, log_dir, ("--n-iter", "1", "--append", "--no-report", *args))
    try:
        status = run.start().wait(timeout=300)
        left = run.wait_for_no_process()
    finally:
        run.kill_everything()
    assert status == 0, run.output()[-3000:]
    assert not left, left
    return check_dataset(dataset_dir(data_root))
