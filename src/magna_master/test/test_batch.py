"""The batch loop end to end: private masters, supervisors and a stand-in ground station (stand_in_gs.py)."""
import csv
import io
import json
import sys
from pathlib import Path

import pytest

from magna_common.processes import pid_alive
from magna_common.storage_tree import existing_simulations
from magna_master import storage
from magna_master.batch import Batch, run_batch
from magna_master.batch_config import BatchConfig, hyperparameters, launch_command
from magna_master.batch_summary import format_summary

pytestmark = pytest.mark.ros


def stand_in_report(folder: Path) -> dict:
    return json.loads((folder / "stand_in.json").read_text())


def summary_cells(dataset_dir: Path) -> list[dict[str, str]]:
    """summary.csv as text cells, as a spreadsheet reads it."""
    with open(dataset_dir / "summary.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def all_pids(simulation) -> list[int]:
    """Every process a simulation is known to have had: supervisor, launch, the stand-in and its children."""
    pids = [simulation.supervisor_pid, simulation.launch_pid]
    if simulation.directory is not None and (simulation.directory / "stand_in.json").is_file():
        report = stand_in_report(simulation.directory)
        pids += [report["pid"], *report["children"]]
    return pids


def test_a_batch_runs_each_simulation_on_its_own_master_and_saves_it(make_config, leak_token):
    out = io.StringIO()
    config = make_config(n_iter=3, fail_seeds="2", seed=0)
    batch = run_batch(config, progress=True, out=out)

    assert not batch.interrupted
    assert [s.id for s in batch.simulations] == [1, 2, 3]
    assert [s.seed for s in batch.simulations] == [1, 2, 3]  # seed S+m
    assert [s.success for s in batch.simulations] == [True, False, True]
    assert batch.successes == 2 and batch.sim_time == pytest.approx(11 + 12 + 13)
    assert batch.speed > 0 and batch.failed_to_run == []
    dataset = config.dataset_dir
    assert batch.dataset_dir == dataset
    masters = set()
    for simulation in batch.simulations:
        folder = dataset / f"simulation_{simulation.id}"
        assert simulation.directory == folder
        for name in ("world.json", "mission.json", "uav_1.csv", "uav_2.csv", "simulation.bag", "result.json"):
            assert (folder / name).is_file(), name
        result = json.loads((folder / "result.json").read_text())
        assert result["termination"] == "ground_station" and result["final"]
        # the ground station's critical events, carried by its report (magna_msgs/CriticalEvent)
        assert result["critical_events"] == ([{"uav": 2, "event": "collision", "sim_time": 4.5, "detail": "UAV 1"}]
                                             if simulation.id == 2 else [])
        assert result["files"] == ["mission.json", "simulation.bag", "stand_in.json", "uav_1.csv", "uav_2.csv",
                                   "world.json"]
        report = stand_in_report(folder)
        # The ground station saw this simulation's hyperparameters and nothing left by the previous one.
        assert report["hyperparameters"] == {
            "world": "Gym", "subworld": "1Obs_Central_Cylinder", "mission": "Gym",
            "submission": "2UAVs_2paths_Central_Cylinder", "n_dataset": 1, "n_simulation": simulation.id,
            "N_iter": 3, "sm_view": False, "save_data": True, "save_bag": True, "rviz": False,
            "seed": simulation.seed}
        assert not report["stale_ual_ids"] and not report["stale_marker"]
        assert report["acknowledged"] is True
        argv = report["argv"]
        assert argv[argv.index("--data-dir") + 1] == str(folder)
        assert argv[argv.index("--mission-file") + 1] == str(config.inputs.mission_file)
        assert argv[argv.index("--worlds-path") + 1] == str(config.inputs.world_file.parent.parent)
        masters.add(report["master_uri"])
        for pid in all_pids(simulation):
            assert not pid_alive(pid)
    assert len(masters) == 3

    with open(dataset / "summary.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["id"], r["success"], r["outcome"], r["collisions"]) for r in rows] == [
        ("1", "True", "succeeded", "0"), ("2", "False", "collision", "1"), ("3", "True", "succeeded", "0")]
    assert [float(r["duration"]) for r in rows] == [11.0, 12.0, 13.0]

    bar = out.getvalue()
    assert "3/3" in bar and "ok 2/3" in bar and "sim/wall" in bar
    table = format_summary(batch)
    assert str(dataset) in table and "bags:    3" in table and "collision between 1 and 2" in table


def test_without_bags_and_without_data(make_config, leak_token, tmp_path, stand_in):
    no_bag = run_batch(make_config(n_iter=1, bag=False), progress=False, out=io.StringIO())
    folder = no_bag.simulations[0].directory
    assert (folder / "uav_1.csv").is_file() and not (folder / "simulation.bag").exists()
    assert stand_in_report(folder)["hyperparameters"]["save_bag"] is False
    assert "bags:    none (--no-bag)" in format_summary(no_bag)

    reports = tmp_path / "reports"
    command = stand_in("ok", extra=["--report", str(reports / "seed_{seed}.json")])
    config = make_config(n_iter=2, save_data=False, launch_command=command, data_root=tmp_path / "nodata")
    batch = run_batch(config, progress=False, out=io.StringIO())
    assert [s.success for s in batch.simulations] == [True, True]
    assert not (tmp_path / "nodata").exists()  # nothing written at all
    assert batch.dataset_dir is None and all(s.directory is None for s in batch.simulations)
    for seed in (1, 2):
        report = json.loads((reports / f"seed_{seed}.json").read_text())
        assert report["hyperparameters"]["save_data"] is False
        argv = report["argv"]
        assert argv[argv.index("--data-dir") + 1] == "" and argv[argv.index("--save-data") + 1] == "false"
    assert "not saved" in format_summary(batch)


def snapshot(root: Path) -> dict:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None) for p in sorted(root.rglob("*"))}


def test_conflicts_append_overwrite_skip_save_and_abort(make_config, leak_token):
    first = run_batch(make_config(n_iter=2), progress=False, out=io.StringIO())
    dataset = first.dataset_dir
    root = dataset.parents[6]

    before = snapshot(root)
    with pytest.raises(storage.StorageConflict, match="--append.*--overwrite.*--skip-save"):
        run_batch(make_config(n_iter=1), progress=False, out=io.StringIO())
    assert snapshot(root) == before  # abort: nothing started, nothing written

    skipped = run_batch(make_config(n_iter=1, policy=storage.SKIP_SAVE), progress=False, out=io.StringIO())
    assert skipped.simulations[0].success and not skipped.plan.save
    assert snapshot(root) == before  # skip-save: ran, wrote nothing

    appended = run_batch(make_config(n_iter=2, policy=storage.APPEND), progress=False, out=io.StringIO())
    assert [(s.id, s.seed) for s in appended.simulations] == [(3, 3), (4, 4)]
    assert [r["id"] for r in summary_cells(dataset)] == ["1", "2", "3", "4"]
    for m in (1, 2):  # untouched
        assert (dataset / f"simulation_{m}" / "result.json").read_bytes() == before[
            str((dataset / f"simulation_{m}" / "result.json").relative_to(root))]

    kept = (dataset / "simulation_2" / "result.json").read_bytes()
    old_1 = json.loads((dataset / "simulation_1" / "result.json").read_text())
    overwritten = run_batch(make_config(n_iter=1, policy=storage.OVERWRITE, fail_seeds="1"), progress=False,
                            out=io.StringIO())
    assert [s.id for s in overwritten.simulations] == [1]
    new_1 = json.loads((dataset / "simulation_1" / "result.json").read_text())
    assert new_1["started_at"] != old_1["started_at"] and new_1["outcome"] == "collision"
    assert (dataset / "simulation_2" / "result.json").read_bytes() == kept
    assert existing_simulations(dataset) == [1, 2, 3, 4]
    rows = {r["id"]: r for r in summary_cells(dataset)}
    assert list(rows) == ["1", "2", "3", "4"] and rows["1"]["outcome"] == "collision"


def test_a_ground_station_that_runs_out_of_time_is_stopped(make_config, leak_token):
    stoppable = run_batch(make_config("stoppable", n_iter=1, time_limit=1.0), progress=False, out=io.StringIO())
    result = stoppable.simulations[0]
    assert (result.termination, result.outcome, result.success) == ("time_limit", "preempted", False)
    assert result.gs_stop_called and result.sim_duration == 3.0
    assert stand_in_report(result.directory)["stopped"] is True

    hung = run_batch(make_config("hang", n_iter=1, time_limit=1.0, stop_grace=0.5, name="hung"), progress=False,
                     out=io.StringIO())
    result = hung.simulations[0]
    assert (result.termination, result.outcome, result.success) == ("time_limit", "time_limit", False)
    assert "is not served" in result.message and "did not call" in result.message
    for pid in all_pids(result):
        assert not pid_alive(pid)
    row = summary_cells(hung.dataset_dir)[0]
    assert (row["success"], row["outcome"]) == ("False", "time_limit")


def test_a_ground_station_deaf_to_signals_is_killed(make_config, leak_token):
    batch = run_batch(make_config("deaf", n_iter=1, time_limit=1.0, stop_grace=0.2, shutdown_timeout=0.5),
                      progress=False, out=io.StringIO())
    result = batch.simulations[0]
    assert result.termination == "time_limit"
    for pid in all_pids(result):
        assert not pid_alive(pid)


def test_a_crash_is_reported_and_the_batch_goes_on(make_config, leak_token):
    batch = run_batch(make_config("crash", n_iter=2), progress=False, out=io.StringIO())
    assert [s.termination for s in batch.simulations] == ["crashed", "crashed"]
    assert batch.failed_to_run == batch.simulations
    result = batch.simulations[0]
    assert not result.success and "status 3" in result.message and "something broke" in result.message
    assert "launch.log" in result.message
    assert (result.directory / "logs" / "launch.log").read_text().strip() == "stand-in: something broke"
    assert [r["outcome"] for r in summary_cells(batch.dataset_dir)] == ["crashed", "crashed"]


def test_processes_that_left_the_launch_group_are_killed(make_config, leak_token):
    batch = run_batch(make_config("orphan", n_iter=1), progress=False, out=io.StringIO())
    result = batch.simulations[0]
    orphan = stand_in_report(result.directory)["children"][0]
    assert not pid_alive(orphan)
    assert any(entry.startswith(f"{orphan} ") for entry in result.leftover_processes_killed)


def test_a_lingering_ground_station_is_ended_after_the_settle_time(make_config, leak_token):
    batch = run_batch(make_config("linger", n_iter=1, settle=0.5), progress=False, out=io.StringIO())
    result = batch.simulations[0]
    assert result.success and result.termination == "ground_station"
    assert not pid_alive(stand_in_report(result.directory)["pid"])


def test_hyperparameters_and_the_default_launch_command(batch_inputs):
    config = BatchConfig(inputs=batch_inputs, n_iter=4, seed=10, n_dataset=2, rtf="max", bag=False)
    plan = storage.StoragePlan(Path("/data/dataset_2"), [1, 2, 3, 4])
    assert hyperparameters(config, 3, plan).to_param() == {
        "world": "Gym", "subworld": "1Obs_Central_Cylinder", "mission": "Gym",
        "submission": "2UAVs_2paths_Central_Cylinder", "n_dataset": 2, "n_simulation": 3, "N_iter": 4,
        "sm_view": False, "save_data": True, "save_bag": False, "rviz": False, "seed": 13}
    argv = launch_command(config, 3, Path("/data/dataset_2/simulation_3"), plan)
    assert argv[:5] == ["roslaunch", "--sigint-timeout=5", "--sigterm-timeout=2", "magna_gs", "simulation.launch"]
    assert argv[5:] == [f"mission_file:={batch_inputs.mission_file}", "world:=Gym", "subworld:=1Obs_Central_Cylinder",
                        f"worlds_path:={batch_inputs.world_file.parent.parent}",
                        "data_dir:=/data/dataset_2/simulation_3", "rtf:=max", "seed:=13", "bag:=false",
                        "save_data:=true", "output:=log", "button_timeout:=10", "managers:=host"]
    no_data = storage.StoragePlan(None, [1], reason="off")
    argv = launch_command(config, 1, None, no_data)
    assert "data_dir:=" in argv and "save_data:=false" in argv and "bag:=false" in argv
    assert not any(a.startswith("utm_plan:=") for a in argv)
    with_plan = BatchConfig(inputs=batch_inputs, utm_plan=Path("/plans/gauss.json"))
    assert launch_command(with_plan, 1, None, no_data)[-1] == "utm_plan:=/plans/gauss.json"
    assert not any(a.startswith("battery_floor:=") for a in argv)
    sitl_battery = BatchConfig(inputs=batch_inputs, battery_floor=50.0)
    assert launch_command(sitl_battery, 1, None, no_data)[-1] == "battery_floor:=50"


def fake_supervisor_batch(config, script):
    """A Batch whose supervisor is `python -c script` (the second level of clean-up is the batch's)."""

    class FakeSupervisor(Batch):
        supervisor_margin = 1.0

        def supervisor_argv(self, result_path, logs, data_dir, extra, command):
            return [sys.executable, "-c", script]

    return FakeSupervisor(config, progress=False, out=io.StringIO())


def test_a_hung_supervisor_is_killed_and_the_result_says_so(make_config, leak_token):
    deaf = ("import signal, subprocess, sys, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
            "signal.signal(signal.SIGTERM, signal.SIG_IGN); "
            "subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(600)'], start_new_session=True); "
            "time.sleep(600)")
    config = make_config(n_iter=1, time_limit=0.5, stop_grace=0.1, settle=0.1, shutdown_timeout=0.1)
    batch = fake_supervisor_batch(config, deaf).run()
    result = batch.simulations[0]
    assert (result.termination, result.success) == ("supervisor_failed", False)
    assert "hung and was killed" in result.message
    # Its child, in a session of its own, carried the simulation's token and was found by it.
    assert len(result.leftover_processes_killed) == 1
    assert summary_cells(batch.dataset_dir)[0]["outcome"] == "supervisor_failed"


def test_a_supervisor_that_dies_without_a_result_is_reported(make_config, leak_token):
    batch = fake_supervisor_batch(make_config(n_iter=1), "raise SystemExit(7)").run()
    result = batch.simulations[0]
    assert result.termination == "supervisor_failed" and "exited with status 7" in result.message
    assert json.loads((result.directory / "result.json").read_text())["termination"] == "supervisor_failed"
