"""Launches on one master are independent, and a normal end is quiet.

- world.launch, then simulation.launch on the same master (as the root README does), and the reverse: the
  second comes up whatever the first left on the master (world.launch's ~world/~subworld used to make
  simulation.launch's world node load the world before the mission did: "volume 'Ground_Station' is already
  in part 'main'"); the world node replaces the /magna/world parameters an earlier world left;
- simulation.launch ending with its mission prints no red "REQUIRED process [...] has died!"; an abnormal end
  (a mission file that does not exist) still does.
"""
import json
import os
import signal
import subprocess
from pathlib import Path

import pytest
import yaml

from tests.support import ROOT, WORLD_ONLY

pytestmark = [pytest.mark.ros, pytest.mark.timeout(400)]

TAKE_OFF_CELL = "definition: ['Ground_Station', 'Agents_take_off', 'matrix', '[1,0,0]']"
DEATH = "has died"


class Launch:
    """One roslaunch on the test's master, its output in a file."""

    def __init__(self, master, tmp_path: Path, name: str, *args: str):
        self.master, self.log = master, tmp_path / f"{name}.log"
        with self.log.open("w") as out:
            self.process = master.spawn(["roslaunch", *args], stdout=out, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL, cwd=ROOT)

    def wait(self, timeout: float = 240) -> int:
        return self.process.wait(timeout)

    def interrupt(self) -> int:
        """Ctrl-C, as a user ends a launch."""
        os.killpg(self.process.pid, signal.SIGINT)
        return self.wait(60)

    @property
    def output(self) -> str:
        return self.log.read_text(errors="replace")


def call(master, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(list(args), env=master.env(), capture_output=True, text=True, timeout=timeout)


def world_launch(master, tmp_path, name="world", *args):
    launch = Launch(master, tmp_path, name, "magna_worlds", "world.launch", *args)
    # up when its service answers (rosservice --wait waits for it to appear)
    answer = call(master, "rosservice", "call", "--wait", "/magna/world/get_fspset", TAKE_OFF_CELL)
    assert answer.returncode == 0 and "success: True" in answer.stdout, (answer.stdout, answer.stderr,
                                                                         launch.output[-3000:])
    return launch


def simulation_launch(master, tmp_path, mission_file, name="simulation"):
    return Launch(master, tmp_path, name, "magna_gs", "simulation.launch", f"mission_file:={mission_file}",
                  "world:=Gym", "subworld:=Four_Cylinders", "rtf:=max", "output:=screen", "bag:=false")


@pytest.fixture
def world_only(tmp_path):
    path = tmp_path / "World_Only.json"
    path.write_text(json.dumps(WORLD_ONLY))
    return path


def assert_ran_quietly(launch, returncode):
    output = launch.output
    assert returncode == 0, output[-3000:]
    assert "mission ended completed" in output, output[-3000:]
    assert "already in part" not in output and DEATH not in output, output[-3000:]


def test_simulation_launch_after_world_launch_on_the_same_master(fresh_ros_master, tmp_path, world_only):
    world = world_launch(fresh_ros_master, tmp_path, "world", "world:=Gym", "subworld:=Four_Cylinders", "seed:=1")
    assert world.interrupt() == 0
    assert DEATH not in world.output
    simulation = simulation_launch(fresh_ros_master, tmp_path, world_only)
    assert_ran_quietly(simulation, simulation.wait())


def test_world_launch_after_simulation_launch_on_the_same_master(fresh_ros_master, tmp_path, world_only):
    simulation = simulation_launch(fresh_ros_master, tmp_path, world_only)
    assert_ran_quietly(simulation, simulation.wait())
    world = world_launch(fresh_ros_master, tmp_path, "world", "world:=Gym", "subworld:=Four_Cylinders", "seed:=1")
    assert world.interrupt() == 0
    assert DEATH not in world.output and "ERROR" not in world.output, world.output[-3000:]


def test_simulation_launch_twice_on_the_same_master(fresh_ros_master, tmp_path, world_only):
    for name in ("first", "second"):
        simulation = simulation_launch(fresh_ros_master, tmp_path, world_only, name)
        assert_ran_quietly(simulation, simulation.wait())


def test_the_world_node_replaces_the_world_parameters_an_earlier_world_left(fresh_ros_master, tmp_path):
    # a world file without world_boundaries: the node makes up the box around its geometries, which never
    # replaces boundaries a file gave, so an earlier world's must be gone
    world = json.loads((ROOT / "worlds" / "Gym" / "Four_Cylinders.json").read_text())
    del world["scenario"]["world_boundaries"]
    world_file = tmp_path / "No_Boundaries.json"
    world_file.write_text(json.dumps(world))
    stale = [[100.0, 101.0], [100.0, 101.0], [100.0, 101.0]]
    assert call(fresh_ros_master, "rosparam", "set", "/magna/world/boundaries", json.dumps(stale)).returncode == 0
    assert call(fresh_ros_master, "rosparam", "set", "/magna/world/origin_geo", "[37.0, -6.0, 0.0]").returncode == 0
    launch = world_launch(fresh_ros_master, tmp_path, "world", f"world_file:={world_file}")
    boundaries = yaml.safe_load(call(fresh_ros_master, "rosparam", "get", "/magna/world/boundaries").stdout)
    origin = call(fresh_ros_master, "rosparam", "get", "/magna/world/origin_geo")
    assert launch.interrupt() == 0
    assert boundaries != stale and all(low < high for low, high in boundaries), boundaries
    assert origin.returncode != 0  # this world has none


def test_a_ground_station_that_fails_is_still_reported_by_roslaunch(fresh_ros_master, tmp_path):
    simulation = simulation_launch(fresh_ros_master, tmp_path, tmp_path / "missing.json")
    simulation.wait()
    output = simulation.output
    assert "REQUIRED process [ground_station" in output and DEATH in output, output[-3000:]


def test_a_node_the_ground_station_starts_gets_no_parameters_of_an_earlier_run(rospy_node):
    from magna_gs.ros_node import clear_private_params

    rospy_node.set_param("/uav_7_manager/data_dir", "/tmp/an_earlier_simulation")
    rospy_node.set_param("/uav_7_manager/control_rate", 50.0)
    clear_private_params("uav_7_manager")
    assert not rospy_node.has_param("/uav_7_manager")
    clear_private_params("uav_7_manager")  # nothing there: nothing to do


def test_a_node_not_started_by_roslaunch_does_not_end_anything():
    from magna_common.processes import end_parent_launch, parent_roslaunch

    assert parent_roslaunch() is None  # pytest's parent is a shell
    assert end_parent_launch(timeout=0.1) is False
