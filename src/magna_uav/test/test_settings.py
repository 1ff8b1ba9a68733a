"""The UAV manager node's private parameters, read without ROS from a dict: defaults, the mission's
UAVs, and each bad value named."""
import json
from pathlib import Path

import pytest

from magna_uav.settings import SettingsError, read_settings

AGENTS = [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 1]},
          {"ID": 2, "model": "crazyflie", "mode": "sitl", "marker_color": [0, 0, 255, 1]}]


def read(**params):
    return read_settings(lambda name, default: params.get(name.lstrip("~"), default))


def test_the_defaults():
    settings = read(id=2)
    assert settings.uav_id == 2 and [c.id for c in settings.configs] == [2] and settings.own.model == "iris"
    assert (settings.control_rate, settings.low_battery, settings.algorithm, settings.depth) == \
        (10.0, 0.15, "simple", False)
    assert settings.data_dir == Path.home() / ".ros" / "magna" and not settings.flies_networks


def test_without_a_mission_every_uav_flies_the_model_given():
    settings = read(id="1", uav_ids=[1, 2, 3], model="crazyflie", data_dir="~/runs", depth_camera=True,
                    control_rate=20, algorithm="orca3")
    assert [(c.id, c.model) for c in settings.configs] == [(1, "crazyflie"), (2, "crazyflie"), (3, "crazyflie")]
    assert settings.data_dir == Path.home() / "runs" and settings.depth and settings.control_rate == 20.0
    assert settings.algorithm == "orca3"


def test_a_mission_file_gives_every_uav_and_says_whether_networks_fly(tmp_path):
    mission = tmp_path / "mission.json"
    mission.write_text(json.dumps({"Agents_Config": AGENTS, "State_Machine": []}))
    settings = read(id=2, mission_file=str(mission))
    assert [(c.id, c.model) for c in settings.configs] == [(1, "iris"), (2, "crazyflie")]
    assert settings.own.model == "crazyflie" and not settings.flies_networks
    mission.write_text(json.dumps({"Agents_Config": AGENTS, "State_Machine": [{"algorithm": "neural_network"}]}))
    assert read(id=2, mission_file=str(mission)).flies_networks


@pytest.mark.parametrize(("params", "named"), [
    ({}, "~id is missing"),
    ({"id": 3, "uav_ids": [1, 2]}, "~id is 3 but the mission's UAVs are [1, 2]"),
    ({"id": 1, "control_rate": 0.1}, "~control_rate is 0.1"),
    ({"id": 1, "control_rate": 500}, "~control_rate is 500.0"),
    ({"id": 1, "low_battery": 1.0}, "~low_battery is 1.0"),
    ({"id": 1, "model": "no_such_airframe"}, "no_such_airframe"),
    ({"id": 1, "mission_file": "/nonexistent/mission.json"}, "/nonexistent/mission.json"),
    ({"id": "one"}, "~id is 'one': give a whole number"),
    ({"id": 1, "uav_ids": 1}, "~uav_ids is 1: give a list"),
    ({"id": 1, "control_rate": [10]}, "~control_rate is [10]: give a number"),
    ({"id": 1, "data_dir": 3}, "~data_dir is 3: give a path"),
])
def test_a_bad_parameter_is_named(params, named):
    with pytest.raises(SettingsError) as error:
        read(**params)
    assert named in str(error.value)


def test_the_node_parts_import_without_ros():
    import subprocess
    import sys

    code = ("import sys; sys.modules['rospy'] = sys.modules['std_msgs'] = sys.modules['magna_msgs'] = None; "
            "import magna_uav.order_desk, magna_uav.reporter, magna_uav.settings, magna_uav.stepping_clock")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
