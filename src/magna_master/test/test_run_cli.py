"""`magna run` and batch.launch: bad input, conflicts, a whole batch, and Ctrl-C in the middle of one."""
import csv
import json
import os
import shlex
import signal
import subprocess
import time
from pathlib import Path

import pytest

from magna_common.ports import free_port
from magna_common.processes import pid_alive
from magna_common.storage_tree import StorageKey, existing_simulations
from magna_master import cli, storage

ROOT = Path(__file__).resolve().parents[3]
WORLD = "Gym/1Obs_Central_Cylinder"
MISSION = "Gym/2UAVs_2paths_Central_Cylinder"


def summary_cells(dataset_dir: Path) -> list[dict[str, str]]:
    """summary.csv as text cells, as a spreadsheet reads it."""
    with open(dataset_dir / "summary.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def run_args(corpus, data_root, *more):
    return ["run", "--world", WORLD, "--mission", MISSION, "--search-path", str(corpus), "--data-root", str(data_root),
            *more]


def dataset(data_root, name="default", n=1) -> Path:
    return StorageKey("Gym", "1Obs_Central_Cylinder", "Gym", "2UAVs_2paths_Central_Cylinder",
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
    from magna_gs.inputs import resolve_inputs

    inputs = resolve_inputs(str(corpus / "Worlds/Gym/1Obs_Central_Cylinder.json"),
                            str(corpus / "Missions/Gym/2UAVs_2paths_Central_Cylinder.json"))
    assert (inputs.world, inputs.subworld, inputs.mission, inputs.submission) == (
        "Gym", "1Obs_Central_Cylinder", "Gym", "2UAVs_2paths_Central_Cylinder")


def test_lowercase_and_capitalised_trees_are_both_searched(tmp_path, corpus):
    from magna_gs.inputs import resolve_inputs

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


# --- the one vocabulary: --skip-save (old --no-data), --rtf, --search-path ---------------------------------------

def parse_run(*argv):
    return cli.build_parser().parse_args([str(a) for a in argv])


def test_skip_save_saves_nothing_whether_or_not_the_dataset_exists(corpus, tmp_path, capsys):
    from magna_master import run_cli

    config = run_cli.build_config(parse_run(*run_args(corpus, tmp_path / "data", "--skip-save")))
    assert config.save_data is False and config.policy is None
    assert capsys.readouterr().err == ""
    # with a dataset that holds simulations, nothing is asked and nothing is written either
    folder = dataset(tmp_path / "data")
    (folder / "simulation_1").mkdir(parents=True)
    plan = storage.plan_storage(folder, 2, config.policy, config.save_data)
    assert not plan.save and plan.ids == [1, 2] and "--skip-save" in plan.reason


def test_no_data_is_the_old_spelling_of_skip_save(corpus, tmp_path, capsys):
    from magna_common.cli_vocabulary import deprecation_line
    from magna_master import run_cli

    config = run_cli.build_config(parse_run(*run_args(corpus, tmp_path / "data", "--no-data")))
    assert config.save_data is False
    assert capsys.readouterr().err.splitlines() == [deprecation_line("magna run", "--no-data", "--skip-save")]


def test_skip_save_does_not_go_with_a_dataset_policy(corpus, tmp_path, capsys):
    with pytest.raises(SystemExit) as done:
        parse_run(*run_args(corpus, tmp_path / "data", "--skip-save", "--append"))
    assert done.value.code == 2
    assert "--append: not allowed with argument --skip-save" in capsys.readouterr().err


def test_help_uses_the_vocabulary_and_its_examples_name_real_files(capsys):
    with pytest.raises(SystemExit):
        parse_run("run", "--help")
    out = capsys.readouterr().out
    assert "--rtf max|FACTOR" in out and "--search-path DIR" in out and "--skip-save" in out
    assert "--no-data" not in out
    examples = out.split("examples:")[1]
    assert "./magna run " in examples
    for word in examples.replace("\\\n", " ").split():
        if word.startswith(("missions/", "worlds/", "../shared/")):
            assert (ROOT / word).exists(), word


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
def test_the_status_file_follows_the_batch_with_each_simulations_master(corpus, tmp_path, capsys, leak_token,
                                                                         stand_in):
    status_file = tmp_path / "status.json"
    command = shlex.join(stand_in("ok", fail_seeds="7"))
    status = cli.main(run_args(corpus, tmp_path / "data", "--n-iter", "2", "--seed", "5", "--status-file",
                               str(status_file), "--launch-command", command))
    assert status == 0
    written = json.loads(status_file.read_text())
    assert (written["state"], written["exit_status"], written["total"], written["done"], written["succeeded"],
            written["running"]) == ("finished", 0, 2, 2, 1, [])
    assert written["dataset_dir"] == str(dataset(tmp_path / "data"))
    assert [(r["id"], r["success"], r["outcome"]) for r in written["results"]] == [(1, True, "succeeded"),
                                                                                (2, False, "collision")]
    for result in written["results"]:  # the master each simulation ran on, as its ground station saw it
        seen = json.loads((Path(result["directory"]) / "stand_in.json").read_text())
        assert result["master_uri"] == seen["master_uri"]
    assert len({r["master_uri"] for r in written["results"]}) == 2  # a cold start per simulation


def test_a_status_file_in_a_missing_folder_is_refused_before_anything_starts(corpus, tmp_path, capsys):
    status = cli.main(run_args(corpus, tmp_path / "data", "--status-file", str(tmp_path / "nowhere" / "s.json")))
    assert status == 2 and "--status-file" in capsys.readouterr().err
    assert not (tmp_path / "data").exists()


@pytest.mark.ros
def test_a_crashing_ground_station_makes_magna_run_fail(corpus, tmp_path, capsys, leak_token, stand_in):
    status = cli.main(run_args(corpus, tmp_path / "data", "--skip-save",
                               "--launch-command", shlex.join(stand_in("crash"))))
    assert status == 1 and "crashed" in capsys.readouterr().out


@pytest.mark.ros
def test_skip_save_runs_on_an_existing_dataset_and_writes_nothing(corpus, tmp_path, capsys, leak_token, stand_in):
    folder = dataset(tmp_path / "data")
    (folder / "simulation_1").mkdir(parents=True)
    (folder / "simulation_1" / "mine.txt").write_text("kept")
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    status = cli.main(run_args(corpus, tmp_path / "data", "--skip-save", "--n-iter", "2",
                               "--launch-command", shlex.join(stand_in("ok"))))
    out = capsys.readouterr().out
    assert status == 0
    assert [line.split()[:3] for line in out.splitlines()[1:3]] == [["1", "1", "yes"], ["2", "2", "yes"]]
    assert "not saved" in out and "--skip-save" in out
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before


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
    rows = summary_cells(folder)
    assert [(r["id"], r["success"], r["outcome"]) for r in rows] == [
        ("1", "True", "succeeded"), ("2", "True", "succeeded"), ("3", "False", "interrupted")]
    assert existing_simulations(folder) == [1, 2, 3]  # no fourth started
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
    rows = summary_cells(dataset(data_root))
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
    from magna_common.processes import tagged_processes

    # The orphaned supervisor may take its whole budget to end the launch (SIGINT, SIGTERM, SIGKILL, 10 s apart:
    # --shutdown-timeout) and then the master (5 s): 35 s. The guard against a hang must lie past it; a wait of 30 s
    # failed once on a loaded machine.
    budget = 3 * 10 + 5
    deadline = time.monotonic() + 2 * budget
    while tagged_processes("MAGNA_MASTER_TEST_TOKEN", leak_token) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not tagged_processes("MAGNA_MASTER_TEST_TOKEN", leak_token), "the orphaned simulation did not end"
    assert not pid_alive(json.loads(report.read_text())["pid"])
    marked = json.loads((report.parent / "result.json").read_text())
    assert marked["termination"] == "interrupted"
    # leak_token checks that the supervisor, the stand-in and the master are all gone
