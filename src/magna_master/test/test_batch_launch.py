"""batch.launch ends with its batch: quietly when the batch ran to its end, with roslaunch's red
"REQUIRED process [...] has died!" when it did not (here: a mission that does not exist)."""
import json
import subprocess

import pytest

from tests.support import ROOT, WORLD_ONLY

pytestmark = [pytest.mark.ros, pytest.mark.timeout(400)]



def batch_launch(master, tmp_path, mission: str) -> tuple[int, str]:
    missions = tmp_path / "search" / "missions" / "Test"
    missions.mkdir(parents=True)
    (missions / "World_Only.json").write_text(json.dumps(WORLD_ONLY))
    log = tmp_path / "batch.log"
    with log.open("w") as out:
        launch = master.spawn(["roslaunch", "magna_master", "batch.launch", "world:=Gym/Four_Cylinders",
                               f"mission:={mission}", f"search_path:={tmp_path / 'search'}",
                               f"data_root:={tmp_path / 'data'}", "bag:=false"],
                              stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, cwd=ROOT)
        returncode = launch.wait(300)
    return returncode, log.read_text(errors="replace")


def test_a_batch_that_ran_to_its_end_ends_its_launch_quietly(fresh_ros_master, tmp_path):
    returncode, output = batch_launch(fresh_ros_master, tmp_path, "Test/World_Only")
    assert returncode == 0, output[-3000:]
    assert "1 of 1 simulation(s) run, 1 succeeded" in output, output[-3000:]
    assert "has died" not in output, output[-3000:]


def test_a_batch_that_fails_is_still_reported_by_roslaunch(fresh_ros_master, tmp_path):
    _, output = batch_launch(fresh_ros_master, tmp_path, "Test/No_Such_Mission")
    assert "REQUIRED process [magna_batch" in output and "has died" in output, output[-3000:]
