"""`magna replay` refusing bad input: exit status 2, one clear line, nothing started, nothing written."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import genpy
import pytest
import rosbag
from geometry_msgs.msg import PoseStamped

from magna_common.ros_master import RosMaster
from magna_master import cli
from magna_viz.replay import plan as replay
from tests.support import ROOT

MISSION = ROOT / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json"


@pytest.fixture(autouse=True)
def nothing_may_start(monkeypatch):
    """Bad input is refused before any process starts."""
    def refuse(self):
        raise AssertionError("the replay started a ROS master on bad input")

    monkeypatch.setattr(RosMaster, "start", refuse)


def make_sim_dir(folder: Path) -> Path:
    """A small simulation folder: mission.json, result.json and a bag of two UAVs' poses."""
    folder.mkdir(parents=True)
    shutil.copy(MISSION, folder / "mission.json")
    (folder / "result.json").write_text(json.dumps({"hyperparameters": {"world": "Gym"}}))
    with rosbag.Bag(str(folder / "simulation.bag"), "w") as bag:
        for i in range(20):
            for uav in (1, 2):
                msg = PoseStamped()
                msg.header.frame_id = "map"
                msg.header.stamp = genpy.Time.from_sec(1.0 + 0.1 * i)
                msg.pose.position.x, msg.pose.position.z = 0.2 * i, float(uav)
                msg.pose.orientation.w = 1.0
                bag.write(f"/uav_{uav}/ual/pose", msg, msg.header.stamp)
    return folder


def tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def replay_cmd(capsys, *argv) -> tuple[int, str]:
    code = cli.main(["replay", *map(str, argv)])
    return code, capsys.readouterr().err


def test_a_missing_bag_is_refused(tmp_path, capsys):
    code, err = replay_cmd(capsys, tmp_path / "nothing_here", "--headless")
    assert code == 2
    assert err.strip() == f"magna replay: {tmp_path / 'nothing_here'}: no such bag file or simulation folder"
    assert list(tmp_path.iterdir()) == []


def test_a_folder_without_a_bag_is_refused(tmp_path, capsys):
    sim = tmp_path / "simulation_1"
    sim.mkdir()
    code, err = replay_cmd(capsys, sim, "--headless")
    assert code == 2 and "no simulation.bag in this folder" in err
    assert list(sim.iterdir()) == []


def test_a_file_that_is_not_a_bag_is_refused_and_nothing_is_written(tmp_path, capsys):
    sim = make_sim_dir(tmp_path / "sim")
    (sim / "simulation.bag").write_text("not a bag at all\n" * 10)
    before = tree(sim)
    code, err = replay_cmd(capsys, sim / "simulation.bag", "--headless")
    assert code == 2
    assert err.startswith(f"magna replay: {sim / 'simulation.bag'}: not a readable ROS bag")
    assert len(err.strip().splitlines()) == 1
    assert tree(sim) == before and not (sim / "replay").exists()


@pytest.mark.parametrize("existing", ["final.png", "frame_0001.png", "replay.gif"])
def test_existing_outputs_are_kept_without_force(tmp_path, capsys, existing):
    sim = make_sim_dir(tmp_path / "sim")
    (sim / "replay").mkdir()
    (sim / "replay" / existing).write_bytes(b"an earlier replay")
    before = tree(sim)
    code, err = replay_cmd(capsys, sim, "--headless", "--gif")
    assert code == 2
    assert f"{sim / 'replay' / existing} exists; use --force" in err
    assert tree(sim) == before


def test_an_out_folder_that_is_a_file_is_refused(tmp_path, capsys):
    sim = make_sim_dir(tmp_path / "sim")
    (tmp_path / "out").write_text("x")
    code, err = replay_cmd(capsys, sim, "--headless", "-o", tmp_path / "out")
    assert code == 2 and "is not a folder; choose another with -o/--output" in err


def test_a_missing_mission_is_refused(tmp_path, capsys):
    sim = make_sim_dir(tmp_path / "sim")
    (sim / "mission.json").unlink()
    code, err = replay_cmd(capsys, sim, "--headless")
    assert code == 2 and "no mission file" in err and "--mission FILE" in err
    assert not (sim / "replay").exists()


@pytest.mark.parametrize("flag, name", [(["--gif"], "--gif"), (["--every", "2"], "--every"),
                                        (["-o", "x"], "-o/--output"), (["--output", "x"], "-o/--output"),
                                        (["--out", "x"], "-o/--output"), (["--force"], "--force"),
                                        (["--size", "640x480"], "--size")])
def test_headless_options_need_headless(tmp_path, capsys, flag, name):
    sim = make_sim_dir(tmp_path / "sim")
    code, err = replay_cmd(capsys, sim, *flag)
    assert code == 2 and err.splitlines()[-1] == f"magna replay: {name} only applies with --headless (screenshots); " \
                                                 "add --headless"


def test_out_is_the_old_spelling_of_output(capsys):
    from magna_common.cli_vocabulary import deprecation_line

    args = cli.build_parser().parse_args(["replay", "sim", "--headless", "--out", "pictures"])
    assert args.output == Path("pictures")
    assert capsys.readouterr().err.splitlines() == [deprecation_line("magna replay", "--out", "-o/--output")]
    args = cli.build_parser().parse_args(["replay", "sim", "--headless", "--output", "pictures"])
    assert args.output == Path("pictures") and capsys.readouterr().err == ""


def test_the_mission_may_be_a_name_looked_up_as_magna_run_does(tmp_path, capsys):
    from magna_viz.replay_cli import options_from

    sim = tmp_path / "sim"
    args = cli.build_parser().parse_args(["replay", str(sim), "--headless", "--mission", "Gym/2UAVs_Crossing_ORCA"])
    assert options_from(args).mission_file == MISSION
    (tmp_path / "mine" / "missions" / "Gym").mkdir(parents=True)
    mine = tmp_path / "mine" / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json"
    mine.write_text(MISSION.read_text())
    args = cli.build_parser().parse_args(["replay", str(sim), "--headless", "--mission", "Gym/2UAVs_Crossing_ORCA",
                                          "--search-path", str(tmp_path / "mine")])
    assert options_from(args).mission_file == mine
    file_args = cli.build_parser().parse_args(["replay", str(sim), "--headless", "--mission", str(mine)])
    assert options_from(file_args).mission_file == mine


def test_a_mission_name_found_nowhere_lists_where_it_looked(tmp_path, capsys):
    sim = make_sim_dir(tmp_path / "sim")
    code, err = replay_cmd(capsys, sim, "--headless", "--mission", "Gym/No_Such_Mission")
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith("magna replay: --mission Gym/No_Such_Mission: no such mission; looked at ")
    assert str(ROOT / "missions" / "Gym" / "No_Such_Mission.json") in err
    assert not (sim / "replay").exists()


@pytest.mark.parametrize("args, message", [
    (["--speed", "0"], "--speed must be > 0"),
    (["--every", "-1"], "--every must be >= 0"),
    (["--size", "10x10"], "--size 10x10"),
    (["--loop"], "--loop plays the bag forever"),
])
def test_bad_values_are_refused(tmp_path, capsys, args, message):
    sim = make_sim_dir(tmp_path / "sim")
    code, err = replay_cmd(capsys, sim, "--headless", *args)
    assert code == 2 and message in err
    assert not (sim / "replay").exists()


def test_without_a_display_rviz_cannot_open_and_headless_is_suggested(tmp_path, capsys, monkeypatch):
    sim = make_sim_dir(tmp_path / "sim")
    monkeypatch.delenv("DISPLAY", raising=False)
    code, err = replay_cmd(capsys, sim)
    assert code == 2 and "DISPLAY is not set" in err and "--headless" in err


def test_a_good_plan_reads_the_bag_and_picks_the_gym(tmp_path):
    sim = make_sim_dir(tmp_path / "sim")
    plan = replay.make_plan(replay.ReplayOptions(source=sim, headless=True, gif=True))
    assert plan.bag.uav_ids == [1, 2] and plan.uav_ids == [1, 2]
    assert plan.bag.duration == pytest.approx(1.9)
    assert plan.choice.path.name == "gym.rviz" and plan.notes == []
    assert plan.out_dir == sim / "replay"
    assert [p.name for p in plan.outputs()] == ["final.png", "replay.gif"]
    assert plan.bag.flight_box[0] == pytest.approx((0.0, 3.8))
    assert not (sim / "replay").exists()  # planning writes nothing
