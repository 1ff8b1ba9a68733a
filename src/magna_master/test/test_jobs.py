"""`magna run --jobs N`: simulations at once, each on its own master, with one summary and a serial batch's stops."""
import csv
import io
import json
import os
import shlex
import signal
import subprocess
import time
from pathlib import Path

import pytest

from magna_common.processes import pid_alive
from magna_common.storage_tree import StorageKey, existing_simulations
from magna_master import cli
from magna_master.batch import run_batch
from magna_master.batch_config import BatchError

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[3]


def summary_cells(dataset_dir: Path) -> list[dict[str, str]]:
    with open(dataset_dir / "summary.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def stand_in_report(folder: Path) -> dict:
    return json.loads((folder / "stand_in.json").read_text())


def test_two_jobs_run_at_once_each_on_its_own_master(make_config, leak_token, tmp_path):
    # Seeds 1 and 2 each wait until the other has started: they pass only when they run at the same time.
    meet = ("--rendezvous", str(tmp_path / "meet"), "--rendezvous-seeds", "1,2")
    config = make_config(n_iter=4, jobs=2, fail_seeds="3", stand_in_extra=meet)
    out = io.StringIO()
    batch = run_batch(config, progress=False, out=out)

    assert [s.id for s in batch.simulations] == [1, 2, 3, 4]
    assert [(s.termination, s.success) for s in batch.simulations] == [
        ("ground_station", True), ("ground_station", True), ("ground_station", False), ("ground_station", True)]
    reports = {s.id: stand_in_report(s.directory) for s in batch.simulations}
    assert reports[1]["met"] == reports[2]["met"] == [1, 2]
    assert len({r["master_uri"] for r in reports.values()}) == 4  # a master of its own each
    for m, report in reports.items():
        assert report["hyperparameters"]["n_simulation"] == m and report["hyperparameters"]["seed"] == m
        assert not report["stale_ual_ids"]
    rows = summary_cells(config.dataset_dir)
    assert [(r["id"], r["success"], r["outcome"]) for r in rows] == [
        ("1", "True", "succeeded"), ("2", "True", "succeeded"), ("3", "False", "collision"), ("4", "True", "succeeded")]
    assert out.getvalue().count("simulation ") >= 4  # one line per simulation without a bar


def test_one_crash_does_not_stop_the_other_jobs(make_config, leak_token):
    config = make_config(n_iter=4, jobs=2, stand_in_extra=("--crash-seeds", "2"))
    batch = run_batch(config, progress=False, out=io.StringIO())
    assert [(s.id, s.termination) for s in batch.simulations] == [
        (1, "ground_station"), (2, "crashed"), (3, "ground_station"), (4, "ground_station")]
    assert [s.id for s in batch.failed_to_run] == [2]
    assert [r["outcome"] for r in summary_cells(config.dataset_dir)] == ["succeeded", "crashed", "succeeded",
                                                                          "succeeded"]


def test_more_jobs_than_simulations_and_bad_counts(make_config, leak_token, capsys, corpus, tmp_path):
    batch = run_batch(make_config(n_iter=1, jobs=3), progress=False, out=io.StringIO())
    assert [s.success for s in batch.simulations] == [True]
    with pytest.raises(BatchError, match="--jobs must be >= 1"):
        run_batch(make_config(n_iter=1, jobs=0), progress=False, out=io.StringIO())
    with pytest.raises(BatchError, match="one mission at a time"):
        run_batch(make_config(n_iter=1, jobs=2, fleet=Path("fleet.yaml")), progress=False, out=io.StringIO())
    status = cli.main(["run", "--world", "Gym/1Obs_Central_Cylinder", "--mission", "Gym/2UAVs_2paths_Central_Cylinder",
                       "--search-path", str(corpus), "--data-root", str(tmp_path / "cli"), "--jobs", "0"])
    assert status == 2 and "--jobs must be >= 1, got 0" in capsys.readouterr().err
    assert not (tmp_path / "cli").exists()


def test_ctrl_c_stops_every_running_job_and_starts_no_other(corpus, tmp_path, leak_token, stand_in):
    data_root = tmp_path / "data"
    command = shlex.join(stand_in("ok", sleep=60))
    process = subprocess.Popen([str(ROOT / "magna"), "run", "--world", "Gym/1Obs_Central_Cylinder", "--mission",
                                "Gym/2UAVs_2paths_Central_Cylinder", "--search-path", str(corpus), "--data-root",
                                str(data_root), "--n-iter", "4", "--jobs", "2", "--launch-command", command],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    folder = StorageKey("Gym", "1Obs_Central_Cylinder", "Gym", "2UAVs_2paths_Central_Cylinder",
                        "default").dataset_dir(data_root, 1)
    try:
        deadline = time.monotonic() + 60
        while not all((folder / f"simulation_{m}" / "stand_in.json").is_file() for m in (1, 2)):  # both running
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "two simulations did not start"
            time.sleep(0.05)
        running = [stand_in_report(folder / f"simulation_{m}")["pid"] for m in (1, 2)]
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=90)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 130, err
    assert existing_simulations(folder) == [1, 2]  # neither 3 nor 4 started
    assert [(r["id"], r["outcome"]) for r in summary_cells(folder)] == [("1", "interrupted"), ("2", "interrupted")]
    for m in (1, 2):
        marked = json.loads((folder / f"simulation_{m}" / "result.json").read_text())
        assert (marked["termination"], marked["final"]) == ("interrupted", True)
        assert not pid_alive(marked["supervisor_pid"])
    assert not any(pid_alive(pid) for pid in running)
    assert "interrupted" in out
    # leak_token: no supervisor, stand-in or master of either job is left
