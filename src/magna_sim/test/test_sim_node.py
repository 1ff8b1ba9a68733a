"""The node as users start it: --help, bad parameters, and the hand-flying tool against a live sim."""
import math
import subprocess

import pytest

from tests.support import wait_until


def test_node_help_lists_the_parameters():
    out = subprocess.run(["rosrun", "magna_sim", "sim", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    for text in ("/uav_{id}/ual/", "~real_time_factor", "~flight_model", "sim.launch uavs:=3"):
        assert text in out.stdout


def test_fly_help_shows_examples():
    out = subprocess.run(["rosrun", "magna_sim", "fly", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "fly --id 1 take_off 2" in out.stdout


def test_bad_parameters_stop_the_node_with_a_named_field(fresh_ros_master, tmp_path):
    node = fresh_ros_master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=1", "_model:=zeppelin"],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output, _ = node.communicate(timeout=60)
    assert node.returncode == 2
    assert "airframe: " in output and "zeppelin.json: no such airframe" in output


@pytest.fixture
def sim(fresh_ros_master):
    import rosgraph

    fresh_ros_master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    node = fresh_ros_master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=2", "_real_time_factor:=5"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    master = rosgraph.Master("/test", master_uri=fresh_ros_master.uri)
    wait_until(lambda: master.hasParam("/ual_ids") and len(master.getParam("/ual_ids")) == 2, "two UAL ids",
               timeout=60)
    yield fresh_ros_master
    assert node.poll() is None, "the sim died during the test"


def fly(master, *args):
    out = subprocess.run(["rosrun", "magna_sim", "fly", *args], capture_output=True, text=True, timeout=120,
                         env=master.env())
    return out.returncode, out.stdout + out.stderr


def printed_position(text):
    return tuple(float(v) for v in text.split("(")[1].split(")")[0].split(","))


def test_fly_a_uav_by_hand(sim):
    assert fly(sim, "--id", "2", "state")[1].strip().startswith("uav 2: LANDED_ARMED at (0.00, 1.00, 0.00)")
    code, text = fly(sim, "--id", "2", "take_off", "2")
    assert code == 0 and "uav 2: FLYING_AUTO" in text
    code, text = fly(sim, "--id", "2", "go_to", "3", "1", "2.5", "--yaw", "90")
    assert code == 0 and "FLYING_AUTO" in text
    assert math.dist(printed_position(text), (3.0, 1.0, 2.5)) < 0.33  # UAL's "reached" threshold
    code, text = fly(sim, "--id", "2", "velocity", "0", "0.5", "0", "--duration", "2")
    assert code == 0
    assert 1.6 < printed_position(text)[1] < 2.4  # about 1 m further along y
    code, text = fly(sim, "--id", "2", "land")
    assert code == 0 and "uav 2: LANDED_ARMED" in text


def test_fly_refusals_are_clear(sim):
    code, text = fly(sim, "--id", "7", "state")
    assert code == 1 and "no UAL server for UAV 7; /ual_ids = [1, 2]" in text
    code, text = fly(sim, "--id", "1", "land")
    assert code == 1 and "land refused: UAV 1 is LANDED_ARMED; land needs FLYING_AUTO" in text
