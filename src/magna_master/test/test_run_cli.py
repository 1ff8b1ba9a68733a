"""`magna run` and batch.launch: bad input, conflicts, a whole batch, and Ctrl-C in the middle of one."""
import json
import os
import shlex
import signal
import subprocess
import time
from pathlib import Path

import pytest

from magna_master import cli, storage
from magna_master.ros_master import free_port
from magna_master.supervisor import pid_alive

ROOT = Path(__file__).resolve().parents[3]
WORLD = "Gym/1Obs_Central_Cylinder"
MISSION = "Gym/2UAVs_2paths_Central_Cylinder"


def run_args(corpus, data_root, *more):
    return ["run", "--world", WORLD, "--mission", MISSION, "--search-path", str(corpus), "--data-root", str(data_root),
            *more]


def dataset(data_root, name="default", n=1) -> Path:
    return storage.StorageKey("Gym", "1Obs_Central_Cylinder", "Gym", "2UAVs_2paths_Central_Cylinder",
                              name).dataset_dir(data_root, n)


# --- bad input: one clear line, exit 2, nothing started or written ------------------------------------------------

def test_an_unknown_world_names_the_places_searched(corpus, tmp_path, capsys):
    status = cli.main(["run", "--world", "Gym/No_Such_World", "--mission", MISSION, "--search-path", str(corpus),
                       "--data-root", str(tmp_path / "data")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith("magna run: world Gym/No_Such_World not found; looked at ")
    assert str(corpus / "Worlds" / "Gym" / "No_Such_World.json") in err
    assert str(ROOT / "worlds" / "Gym" / "No_Such_World.json") in err
    assert "--search-path" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "data").exists()


def test_an_unknown_mission_names_the_places_searched(corpus, tmp_path, capsys):
    status = cli.main(["run", "--world", WORLD, "--mission", "Gym/No_Such_Mission", "--search-path", str(corpus),
                       "--data-root", str(tmp_path / "data")])
    err = capsys.readouterr().err
    assert status == 2
    assert "Gym/No_Such_Mission" in err and str(corpus / "Missions" / "Gym" / "No_Such_Mission.json") in err
    assert str(ROOT / "missions") in err
    assert not (tmp_path / "data").exists()


@pytest.mark.parametrize(("args", "message"), [
    (["--world", "Gym"], "expected WORLD/SUBWORLD"),
    (["--rtf", "fast"], "--rtf 'fast'"),
    (["--rtf", "-1"], "a factor > 0"),
    (["--n-iter", "0"], "--n-iter must be >= 1"),
    (["--name", "a/b"], "cannot name a folder"),
    (["--time-limit=-5"], "--time-limit must be >= 0"),
])
def test_bad_options_are_usage_errors(corpus, tmp_path, capsys, args, message):
    status = cli.main(run_args(corpus, tmp_path / "data", *args))  # a repeated option: the last one counts
    assert status == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "data").exists()


def test_a_missing_search_folder_is_a_usage_error(tmp_path, capsys):
    status = cli.main(["run", "--world", WORLD, "--mission", MISSION, "--search-path", str(tmp_path / "nope")])
    assert status == 2 and "no such folder" in capsys.readouterr().err


def test_a_bad_world_file_is_refused_before_anything_starts(tmp_path, corpus, capsys):
    (tmp_path / "worlds" / "Bad").mkdir(parents=True)
    (tmp_path / "worlds" / "Bad" / "Broken.json").write_text('{"scenario": {"volumes": 3}}')
    status = cli.main(["run", "--world", "Bad/Broken", "--mission", MISSION, "--search-path", str(tmp_path),
                       "--search-path", str(corpus), "--data-root", str(tmp_path / "data")])
    err = capsys.readouterr().err
    assert status == 2 and "Broken.json" in err and "scenario" in err
    assert not (tmp_path / "data").exists()


def test_world_and_mission_may_be_given_as_files(corpus):
    from magna_master.batch import resolve_inputs

    inputs = resolve_inputs(str(corpus / "Worlds/Gym/1Obs_Central_Cylinder.json"),
                            str(corpus / "Missions/Gym/2UAVs_2paths_Central_Cylinder.json"))
    assert (inputs.world, inputs.subworld, inputs.mission, inputs.submission) == (
        "Gym", "1Obs_Central_Cylinder", "Gym", "2UAVs_2paths_Central_Cylinder")


def test_lowercase_and_capitalised_trees_are_both_searched(tmp_path, corpus):
    from magna_master.batch import resolve_inputs

    tree = tmp_path / "mine"
    (tree / "worlds" / "Gym").mkdir(parents=True)
    (tree / "missions" / "Gym").mkdir(parents=True)
    (tree / "worlds" / "Gym" / "Copy.json").write_text((corpus / "Worlds/Gym/1Obs_Central_Cylinder.json").read_text())
    (tree / "missions" / "Gym" / "Copy.json").write_text(
        (corpus / "Missions/Gym/2UAVs_2paths_Central_Cylinder.json").read_text())
    inputs = resolve_inputs("Gym/Copy", "Gym/Copy", [tree])
    assert inputs.world_file == (tree / "worlds/Gym/Copy.json").resolve()
    assert inputs.mission_file == (tree / "missions/Gym/Copy.json").resolve()
    assert inputs.worlds_path == (tree / "worlds").resolve()
    inputs = resolve_inputs(WORLD, MISSION, [tree, corpus])  # the capitalised corpus, after the first folder
    assert inputs.world_file == (corpus / "Worlds/Gym/1Obs_Central_Cylinder.json").resolve()


# --- whole batches through the command line ---------------------------------------------------------------------

@pytest.mark.ros
def test_magna_run_prints_the_table_and_where_the_data_is(corpus, tmp_path, capsys, leak_token, stand_in):
    command = shlex.join(stand_in("ok", fail_seeds="7"))
    status = cli.main(run_args(corpus, tmp_path / "data", "--n-iter", "2", "--seed", "5",
                               "--launch-command", command))
    out = capsys.readouterr().out
    assert status == 0
    lines = out.splitlines()
    assert lines[0].split() == ["id", "seed", "success", "outcome", "sim", "s", "wall", "s", "collisions", "message"]
    assert lines[1].split()[:4] == ["1", "6", "yes", "succeeded"]
    assert lines[2].split()[:4] == ["2", "7", "no", "collision"]
    assert f"data:    {dataset(tmp_path / 'data')}" in out and "bags:    2 in" in out

    # Again without a policy, not on a terminal: stops before starting anything.
    before = sorted(p.name for p in dataset(tmp_path / "data").iterdir())
    status = cli.main(run_args(corpus, tmp_path / "data", "--launch-command", command))
    err = capsys.readouterr().err
    assert status == 2 and "--append" in err and "--overwrite" in err and "--skip-save" in err
    assert sorted(p.name for p in dataset(tmp_path / "data").iterdir()) == before


@pytest.mark.ros
def test_a_crashing_ground_station_makes_magna_run_fail(corpus, tmp_path, capsys, leak_token, stand_in):
    status = cli.main(run_args(corpus, tmp_path / "data", "--no-data",
                               "--launch-command", shlex.join(stand_in("crash"))))
    assert status == 1 and "crashed" in capsys.readouterr().out


@pytest.mark.ros
def test_ctrl_c_keeps_finished_simulations_and_marks_the_running_one(corpus, tmp_path, leak_token, stand_in):
    data_root = tmp_path / "data"
    command = shlex.join(stand_in("ok", sleep=0.3) + ["--sleep-seed", "3", "--long-sleep", "60"])
    process = subprocess.Popen([str(ROOT / "magna"), *run_args(corpus, data_root, "--n-iter", "5",
                                                               "--launch-command", command)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        folder = dataset(data_root)
        deadline = time.monotonic() + 60
        while not (folder / "simulation_3" / "stand_in.json").is_file():  # the third is running
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "the third simulation did not start"
            time.sleep(0.05)
        running = json.loads((folder / "simulation_3" / "stand_in.json").read_text())["pid"]
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 130, err
    assert "interrupted" in out and "stopping the running simulation" in err
    rows = storage.read_summary(folder)
    assert [(r["id"], r["success"], r["outcome"]) for r in rows] == [
        ("1", "True", "succeeded"), ("2", "True", "succeeded"), ("3", "False", "interrupted")]
    assert storage.existing_simulations(folder) == [1, 2, 3]  # no fourth started
    for m in (1, 2):
        assert json.loads((folder / f"simulation_{m}" / "result.json").read_text())["termination"] == "ground_station"
        assert (folder / f"simulation_{m}" / "uav_1.csv").is_file()
    marked = json.loads((folder / "simulation_3" / "result.json").read_text())
    assert (marked["termination"], marked["success"], marked["final"]) == ("interrupted", False, True)
    assert not pid_alive(running) and not pid_alive(marked["supervisor_pid"])


@pytest.mark.ros
def test_batch_launch_runs_the_same_batch(corpus, tmp_path, leak_token, stand_in):
    data_root = tmp_path / "data"
    command = shlex.join(stand_in("ok"))
    port = free_port()
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}/", "ROS_LOG_DIR": str(tmp_path / "roslog")}
    out = subprocess.run(["roslaunch", "-p", str(port), "magna_master", "batch.launch", f"world:={WORLD}",
                          f"mission:={MISSION}", "n_iter:=2", f"search_path:={corpus}", f"data_root:={data_root}",
                          "bag:=false", "seed:=10", f"launch_command:={command}"],
                         env=env, capture_output=True, text=True, timeout=180, start_new_session=True)
    assert out.returncode == 0, out.stdout + out.stderr
    rows = storage.read_summary(dataset(data_root))
    assert [(r["id"], r["success"]) for r in rows] == [("1", "True"), ("2", "True")]
    simulation = dataset(data_root) / "simulation_2"
    assert not (simulation / "simulation.bag").exists()
    assert json.loads((simulation / "result.json").read_text())["seed"] == 12
    assert "2 of 2 simulation(s) run, 2 succeeded" in out.stdout


def test_the_node_drops_ros_remappings(monkeypatch):
    from magna_master import run_cli

    seen = []
    monkeypatch.setattr(cli, "main", lambda argv: seen.append(argv) or 0)
    assert run_cli.node_main(["--world", "A/B", "__name:=magna_batch", "__log:=/tmp/x.log"]) == 0
    assert seen == [["run", "--world", "A/B"]]


def test_run_is_a_magna_command():
    assert ("run", "magna_master.run_cli") in cli.COMMANDS


@pytest.mark.ros
def test_a_killed_batch_leaves_no_process_behind(corpus, tmp_path, leak_token, stand_in):
    """SIGKILL gives the batch no chance to clean up: its supervisor (told by the kernel) does it."""
    command = shlex.join(stand_in("ok", sleep=60))
    process = subprocess.Popen([str(ROOT / "magna"), *run_args(corpus, tmp_path / "data", "--launch-command", command)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    report = dataset(tmp_path / "data") / "simulation_1" / "stand_in.json"
    deadline = time.monotonic() + 60
    while not report.is_file():
        assert process.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    from magna_master.supervisor import tagged_processes

    deadline = time.monotonic() + 30
    while tagged_processes("MAGNA_MASTER_TEST_TOKEN", leak_token) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not pid_alive(json.loads(report.read_text())["pid"])
    marked = json.loads((report.parent / "result.json").read_text())
    assert marked["termination"] == "interrupted"
    # leak_token checks that the supervisor, the stand-in and the master are all gone
