"""The ground station's MAVLink UAVs, without ROS: where the map's geo origin comes from, and the bridge's
command line for each kind of fleet entry."""
from magna_gs.mavlink_uavs import bridge_command, resolve_origin
from magna_mavlink.fleet import Fleet, FleetUav
from magna_sim.mavlink_telemetry import PX4_SITL_HOME


def fleet(origin=None, **uavs):
    return Fleet("fleet.yaml", origin, {u.id: u for u in uavs.values()})


def test_the_origin_comes_from_the_fleet_then_the_world_then_px4_sitl():
    three = FleetUav(3, "", "px4", None, 3, True)
    assert resolve_origin(fleet((1.0, 2.0, 3.0), three=three), [4, 5, 6]) == ((1.0, 2.0, 3.0),
                                                                               "origin_geo of fleet.yaml")
    assert resolve_origin(fleet(three=three), [4, 5, 6]) == ((4.0, 5.0, 6.0), "the world's origin_geo")
    origin, where = resolve_origin(fleet(three=three), None)
    assert origin == PX4_SITL_HOME and "PX4 SITL's default home" in where


def test_the_bridge_gets_the_url_ids_autopilot_arming_and_origin():
    real = FleetUav(4, "/dev/ttyUSB0,57600", "ardupilot", None, 9, False)
    command = bridge_command(real, "real", real.url, (37.4, -6.0, 12.0))
    assert command[:4] == ["rosrun", "magna_mavlink", "ual_mavlink", "__name:=uav_4_ual_mavlink"]
    options = dict(zip(command[4::2], command[5::2], strict=False))
    assert options["--id"] == "4" and options["--url"] == "/dev/ttyUSB0,57600" and options["--system-id"] == "9"
    assert options["--autopilot"] == "ardupilot"
    assert options["--arming"] == "pilot"  # a real UAV waits for its safety pilot unless the fleet says otherwise
    at = command.index("--origin-geo")
    assert command[at + 1:at + 4] == ["37.4", "-6.0", "12.0"]
    hil = FleetUav(3, "udpin:0.0.0.0:14542", "px4", None, 3, False)
    command = bridge_command(hil, "hil", hil.url, PX4_SITL_HOME)
    assert command[command.index("--arming") + 1] == "auto"  # SITL and HIL arm over MAVLink
