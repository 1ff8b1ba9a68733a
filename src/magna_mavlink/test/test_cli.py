"""ual_mavlink's settings: the command line wins over private parameters, which win over the defaults; bad values
are refused naming the option and the fix."""
import pytest

from magna_mavlink.cli import OptionError, build_parser, id_from_argv, resolve


def options(argv, params=None):
    return resolve(build_parser().parse_args(argv), params or {})


def test_defaults_and_the_command_line():
    o = options(["--id", "3", "--url", "udpin:0.0.0.0:14542"])
    assert (o.uav_id, o.url, o.system_id, o.autopilot, o.arming, o.origin_geo) == (3, "udpin:0.0.0.0:14542", 3,
                                                                                   "auto", "auto", None)
    assert (o.heartbeat_timeout, o.connect_timeout, o.tf, o.pub_rate) == (2.0, 10.0, True, 30.0)
    assert (o.settings.position_th, o.settings.hold_pose_time, o.settings.uav_id) == (0.33, 1.0, 3)
    o = options(["--id", "3", "--url", "/dev/ttyACM0,57600", "--system-id", "1", "--arming", "pilot",
                 "--autopilot", "ardupilot", "--origin-geo", "37.41", "-6.0", "55", "--heartbeat-timeout", "3",
                 "--no-tf"])
    assert (o.system_id, o.arming, o.settings.arming, o.autopilot, o.origin_geo, o.heartbeat_timeout, o.tf) == (
        1, "pilot", "pilot", "ardupilot", (37.41, -6.0, 55.0), 3.0, False)


def test_private_parameters_and_the_command_line_over_them():
    params = {"id": 4, "url": "udpout:127.0.0.1:14583", "origin_geo": [37.4, -6.0, 0.0], "arming": "pilot",
              "hold_pose_time": 3, "tf": False}
    o = options([], params)
    assert (o.uav_id, o.url, o.origin_geo, o.arming, o.settings.hold_pose_time, o.tf) == (
        4, "udpout:127.0.0.1:14583", (37.4, -6.0, 0.0), "pilot", 3.0, False)
    assert options(["--id", "5", "--arming", "auto"], params).uav_id == 5
    assert options(["--arming", "auto"], params).arming == "auto"
    assert options([], {**params, "origin_geo": "[37.4, -6.0, 1.5]"}).origin_geo == (37.4, -6.0, 1.5)
    assert options([], {**params, "origin_geo": []}).origin_geo is None  # the launch file's default


@pytest.mark.parametrize(("argv", "params", "text"), [
    ([], {}, "no UAV id: give --id N (or _id:=N)"),
    (["--id", "1"], {}, "no connection: give --url URL, e.g. --url udpin:0.0.0.0:14540"),
    (["--id", "0", "--url", "udpin:0.0.0.0:1"], {}, "--id: 0 must be a whole number >= 1"),
    (["--id", "1", "--url", "udp://:14540"], {}, "--url udp://:14540: write the URL as pymavlink does"),
    (["--id", "1", "--url", "udpin:0.0.0.0:1", "--system-id", "300"], {}, "--system-id: 300 must be a whole number "
                                                                          "1..255"),
    (["--id", "1", "--url", "udpin:0.0.0.0:1"], {"arming": "yes"}, "_arming: 'yes'; use auto (simulation, HIL) or "
                                                                   "pilot (real UAVs)"),
    (["--id", "1", "--url", "udpin:0.0.0.0:1", "--origin-geo", "137", "0", "0"], {},
     "--origin-geo: 137.0 0.0 0.0: latitude must"),
    (["--id", "1", "--url", "udpin:0.0.0.0:1", "--connect-timeout", "0"], {}, "--connect-timeout: 0.0 must be a "
                                                                              "positive number"),
    (["--id", "1", "--url", "udpin:0.0.0.0:1"], {"origin_geo": [1, 2]}, "--origin-geo: [1, 2]; give LAT LON ALT"),
])
def test_bad_settings_name_the_option_and_the_fix(argv, params, text):
    with pytest.raises(OptionError) as caught:
        options(argv, params)
    assert str(caught.value).startswith(text), str(caught.value)


def test_the_id_is_read_before_ros_starts_to_name_the_node():
    assert id_from_argv(["--url", "x", "--id", "7"]) == 7
    assert id_from_argv(["_id:=12", "_url:=x"]) == 12
    assert id_from_argv(["--id=3"]) == 3
    assert id_from_argv(["--url", "udpin:0.0.0.0:14540"]) is None
