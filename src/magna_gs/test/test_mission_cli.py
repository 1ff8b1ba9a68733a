"""`magna mission check|draw`: the summary of real missions, one line per problem and exit 2, pictures."""
import json
import subprocess

import pytest

from magna_master import cli
from tests.support import CORPUS, ROOT


def magna(capsys, *argv):
    """Run `magna ARGV...` in this process: (exit status, stdout, stderr)."""
    try:
        status = cli.main([str(a) for a in argv])
    except SystemExit as done:  # argparse: --help, usage errors
        status = done.code
    out = capsys.readouterr()
    return status, out.out, out.err


def test_check_a_legacy_corpus_mission_by_name_against_its_world(capsys):
    status, out, err = magna(capsys, "mission", "check", "Delivery/2UAVs_follow_ad_safe", "--world",
                             "Delivery/Delivery", "--search-path", CORPUS)
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0] == f"file        {CORPUS}/Missions/Delivery/2UAVs_follow_ad_safe.json"
    assert lines[1] == "schema      legacy parts migrated to the current schema: 24 change(s)"
    assert "  UAVs_Config -> Agents_Config" in lines
    assert "  State_Machine[5].occurrencies[1].occurrencies[1].state_type: follow_uav_ad -> follow_agent_ad" in lines
    assert "agents      2: 1 (iris, sitl), 2 (iris, sitl)" in lines
    assert "states      10 written at the top level, 36 after expansion" in lines
    assert "  SimpleActionState 20 (basic_move 2, follow_agent_ad 1, follow_path 7, land 4, save_csv 2, take_off 4)" \
        in lines
    assert "  CBState 7 (spawn_agents 1, wait 5, world_config 1)" in lines
    assert "  StateMachine 4" in lines and "  Concurrence 5" in lines
    assert "outcomes    completed, failed, preempted" in lines
    assert lines[-1] == f"world       {CORPUS}/Worlds/Delivery/Delivery.json (seed 0): 14 pose definition(s) resolve"
    warnings = err.splitlines()
    assert "warnings    4 (on stderr)" in lines and len(warnings) == 4
    assert all(w.startswith(f"magna mission: warning: {CORPUS}/Missions/Delivery/2UAVs_follow_ad_safe.json: "
                            "State_Machine[5]") for w in warnings)


def test_check_a_current_mission_file_without_a_world(capsys, write_mission, base_mission):
    path = write_mission(base_mission)
    status, out, err = magna(capsys, "mission", "check", path)
    assert status == 0 and err == ""
    assert "schema      current (nothing to migrate)" in out.splitlines()
    assert not any(line.startswith("world") for line in out.splitlines())


def test_a_bad_mission_prints_one_line_per_problem_and_exits_2(capsys, write_mission, base_mission):
    base_mission["State_Machine"][1]["outcomes"]["completed"] = "1_fligth"
    base_mission["State_Machine"][1]["occurrencies"][0]["parameters"]["height"] = 0
    path = write_mission(base_mission)
    status, out, err = magna(capsys, "mission", "check", path)
    assert status == 2 and out == ""
    assert err.splitlines() == [
        f"magna mission: {path}: State_Machine[1].occurrencies[0].parameters.height: expected a height above the "
        "take-off point in m, > 0, got 0",
        f"magna mission: {path}: State_Machine[1].outcomes.completed: no state named '1_fligth'; states here: spawn, "
        "1_take_off, 1_flight, 1_land; or end the mission with completed or failed"]


def test_world_problems_come_after_the_summary_and_exit_2(capsys):
    status, out, err = magna(capsys, "mission", "check", "Gym/3UAVs_3paths_4_Cylinders", "--world",
                             "Gym/Empty_4_Cylinders_1Obs", "--search-path", CORPUS)
    assert status == 2
    assert out.splitlines()[-1].endswith("Empty_4_Cylinders_1Obs.json (seed 0): 1 problem(s) (on stderr)")
    assert err.splitlines()[-1] == (
        f"magna mission: {CORPUS}/Missions/Gym/3UAVs_3paths_4_Cylinders.json: State_Machine[2].parameters."
        "initial_poses[2][3]: GS4_Agents_take_off has no cell [2, 0, 0]; its cells run up to [1, 0, 0] (from 0; "
        "density may leave some out)")
    status, out, _ = magna(capsys, "mission", "check", "Gym/3UAVs_3paths_4_Cylinders", "--world",
                           "Gym/Empty_4_Cylinders", "--search-path", CORPUS)
    assert status == 0 and "9 pose definition(s) resolve" in out


@pytest.mark.parametrize("argv,message", [
    (["Gym/Nothing"], "magna mission: Gym/Nothing: no such mission; looked at "),
    (["Gym/only_world", "--world", "Gym/Nowhere"], "magna mission: --world Gym/Nowhere: no such file, nor a world "
                                                   "WORLD/SUBWORLD of that name; looked at "),
])
def test_names_that_are_nowhere(capsys, argv, message):
    status, out, err = magna(capsys, "mission", "check", *argv, "--search-path", CORPUS)
    assert status == 2 and out == ""
    assert err.startswith(message) and len(err.splitlines()) == 1


def test_draw_writes_a_png_and_refuses_to_overwrite_without_force(capsys, tmp_path):
    picture = tmp_path / "mission.png"
    argv = ["mission", "draw", "Gym/2UAVs_2paths_Central_Cylinder", "--search-path", CORPUS, "-o", picture]
    status, out, err = magna(capsys, *argv)
    assert status == 0, err
    assert out.strip() == str(picture)
    data = picture.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10000
    status, out, err = magna(capsys, *argv)
    assert status == 2 and out == ""
    assert err == f"magna mission: {picture} already exists; pass --force to replace it\n"
    assert picture.read_bytes() == data
    status, _, err = magna(capsys, *argv, "--force", "--title", "again")
    assert status == 0 and picture.read_bytes() != data


def test_draw_dot_holds_every_expanded_state(capsys, tmp_path):
    dot = tmp_path / "mission.dot"
    status, _, err = magna(capsys, "mission", "draw", "Delivery/2UAVs_follow_ap", "--search-path", CORPUS, "-o", dot)
    assert status == 0, err
    text = dot.read_text()
    for label in ("/MISSION/1_flight/2_flight/2_follow_uav_1", "/MISSION/1_hovering/1_hover", "/MISSION/spawn_UAVs",
                  "/MISSION/1_all_land/2_land"):
        assert f'"{label}"' in text


@pytest.mark.parametrize("output,message", [
    ("mission.jpg", "unknown picture format '.jpg'; name it *.png, *.svg, *.pdf or *.dot"),
    ("missing/mission.png", "does not exist; create it first"),
])
def test_draw_refuses_bad_outputs_before_any_work(capsys, tmp_path, output, message):
    status, _, err = magna(capsys, "mission", "draw", "Gym/only_world", "--search-path", CORPUS, "-o",
                           tmp_path / output)
    assert status == 2 and message in err
    assert list(tmp_path.iterdir()) == []


def test_draw_a_bad_mission_writes_nothing(capsys, tmp_path, write_mission, base_mission):
    base_mission["State_Machine"][0]["type"] = "Concurrency"
    path = write_mission(base_mission)
    picture = tmp_path / "out.png"
    status, _, err = magna(capsys, "mission", "draw", path, "-o", picture)
    assert status == 2 and "State_Machine[0].type: unknown type 'Concurrency'" in err
    assert not picture.exists()


def test_the_magna_command_runs_it(write_mission, base_mission):
    good = write_mission(base_mission, "Test/Good")
    ok = subprocess.run([str(ROOT / "magna"), "mission", "check", str(good)], capture_output=True, text=True,
                        timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert "outcomes    completed, failed, preempted" in ok.stdout
    base_mission["Agents_Config"][0]["ID"] = "one"
    bad = write_mission(json.dumps(base_mission), "Test/Bad")
    failed = subprocess.run([str(ROOT / "magna"), "mission", "check", str(bad)], capture_output=True, text=True,
                            timeout=120)
    assert failed.returncode == 2 and failed.stdout == ""
    assert failed.stderr.splitlines() == [f"magna mission: {bad}: Agents_Config[0].ID: expected a whole number 0 or "
                                          "more, got 'one'"]


def test_help_lists_the_actions_with_examples(capsys):
    for argv in (["mission", "--help"], ["mission", "check", "--help"], ["mission", "draw", "--help"]):
        status, out, _ = magna(capsys, *argv)
        assert status == 0 and "examples:" in out
        examples = out.split("examples:")[1]
        assert "./magna mission " in examples
        for word in examples.replace("\\\n", " ").split():  # every file an example names exists
            if word.startswith(("missions/", "worlds/", "../shared/")):
                assert (ROOT / word).exists(), word


# --- the names `magna run` takes, with --search-path -----------------------------------------------------------

def test_project_mission_and_world_by_name(capsys):
    status, out, err = magna(capsys, "mission", "check", "Gym/2UAVs_Crossing_ORCA", "--world",
                             "Gym/Central_Obstacle_Torus")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0] == f"file        {ROOT / 'missions' / 'Gym' / '2UAVs_Crossing_ORCA.json'}"
    assert lines[-1].startswith(f"world       {ROOT / 'worlds' / 'Gym' / 'Central_Obstacle_Torus.json'} (seed 0): ")


def test_a_lowercase_tree_is_searched_as_magna_run_does(capsys, tmp_path):
    (tmp_path / "missions" / "Gym").mkdir(parents=True)
    (tmp_path / "worlds" / "Gym").mkdir(parents=True)
    (tmp_path / "missions" / "Gym" / "Mine.json").write_text(
        (CORPUS / "Missions" / "Gym" / "2UAVs_2paths_Central_Cylinder.json").read_text())
    (tmp_path / "worlds" / "Gym" / "Mine.json").write_text(
        (CORPUS / "Worlds" / "Gym" / "1Obs_Central_Cylinder.json").read_text())
    status, out, err = magna(capsys, "mission", "check", "Gym/Mine", "--world", "Gym/Mine", "--search-path", tmp_path)
    assert status == 0, err
    assert out.splitlines()[0] == f"file        {tmp_path / 'missions' / 'Gym' / 'Mine.json'}"
    assert out.splitlines()[-1].startswith(f"world       {tmp_path / 'worlds' / 'Gym' / 'Mine.json'} (seed 0): ")


def test_a_missing_search_path_folder_is_a_usage_error(capsys, tmp_path):
    for action in (["check"], ["draw", "-o", tmp_path / "m.png"]):
        status, out, err = magna(capsys, "mission", *action, "Gym/2UAVs_Crossing_ORCA", "--search-path",
                                 tmp_path / "nope")
        assert status == 2 and out == ""
        assert err.startswith(f"magna mission: --search-path {tmp_path / 'nope'}: no such folder")
    assert list(tmp_path.iterdir()) == []


def test_draw_needs_an_output(capsys):
    status, _, err = magna(capsys, "mission", "draw", "Gym/2UAVs_Crossing_ORCA")
    assert status == 2 and "-o/--output" in err


def test_strict_check_refuses_a_warning_with_exit_2(capsys, write_mission, base_mission):
    base_mission["State_Machine"][1]["occurrencies"][0]["ids"] = [1, 2, 3]  # UAV 3 is not configured
    path = write_mission(base_mission)
    status, out, err = magna(capsys, "mission", "check", path)
    assert status == 0 and f"magna mission: warning: {path}: State_Machine[1].occurrencies[0].ids: UAV 3" in err
    status, out, err = magna(capsys, "mission", "check", path, "--strict")
    assert status == 2 and out == ""
    assert err.splitlines() == [f"magna mission: {w} [refused: strict mode turns warnings into errors]"
                                for w in [line.removeprefix("magna mission: warning: ") for line in
                                          magna(capsys, "mission", "check", path)[2].splitlines()]]
