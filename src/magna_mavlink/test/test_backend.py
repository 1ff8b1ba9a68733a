"""The UAL behaviour over MAVLink against a scripted PX4 (and ArduPilot Copter) over real UDP, on the wall clock:
state sequence, guards and NaN refusals, the set-point stream and its velocity timeout, take-off, waypoints,
land, home, a pilot's take-over, a lost HEARTBEAT, and arming by ual_mavlink or by the safety pilot."""
import math

import numpy as np
import pytest

from magna_common import geo
from magna_mavlink import autopilot as ap
from magna_mavlink.backend import CommandRefused
from magna_mavlink.commands import POSITION_AND_YAW, VELOCITY_AND_YAW_RATE
from magna_mavlink.link import mavlink
from magna_mavlink.ual_state import (
    FLYING_AUTO,
    FLYING_MANUAL,
    LANDED_ARMED,
    LANDED_DISARMED,
    LANDING,
    NAMES,
    TAKING_OFF,
    UNINITIALIZED,
)
from tests.support import wait_until

NAN = float("nan")


def state_is(flight, *states):
    return lambda: flight.backend.state in states


def landed_and_armed(flight):
    wait_until(state_is(flight, LANDED_ARMED), "LANDED_ARMED (ual_mavlink arms it)")


def flying(flight, height=1.0):
    landed_and_armed(flight)
    flight.backend.take_off(height, blocking=True)
    assert flight.backend.state == FLYING_AUTO


def sent(flight, kind):
    """The set-points the autopilot got, as (type_mask, message) of one kind: 'position' or 'velocity'."""
    mask = POSITION_AND_YAW if kind == "position" else VELOCITY_AND_YAW_RATE
    with flight.fake.lock:
        return [msg for _, msg in flight.fake.set_points if msg.type_mask == mask]


def test_the_state_sequence_of_a_flight(flight):
    f = flight()
    seen = []

    def record():
        if not seen or seen[-1] != f.backend.state:
            seen.append(f.backend.state)
        return False

    landed_and_armed(f)
    assert f.fake.armed and f.fake.mode == "OFFBOARD"  # arming auto: it armed, in the set-point mode
    f.backend.take_off(1.5, blocking=False)
    wait_until(lambda: record() or f.backend.state == FLYING_AUTO, "FLYING_AUTO")
    assert seen[0] in (LANDED_ARMED, TAKING_OFF) and seen[-2:] == [TAKING_OFF, FLYING_AUTO], [NAMES[s] for s in seen]
    assert f.backend.telemetry.position[2] == pytest.approx(1.5, abs=0.33 / 2)
    f.backend.land(blocking=False)
    seen.clear()
    wait_until(lambda: record() or f.backend.state in (LANDED_ARMED, LANDED_DISARMED), "landed")
    assert seen[0] in (FLYING_AUTO, LANDING) and LANDING in seen, [NAMES[s] for s in seen]
    assert f.fake.mode == "AUTO.LAND" and f.backend.telemetry.position[2] < 0.1


def test_a_disarm_on_the_ground_as_the_climb_begins_is_armed_again_and_the_take_off_flies(flight):
    """PX4 disarms a UAV left armed on the ground for COM_DISARM_PRFLT s. ual_mavlink (arming auto) armed it
    on connecting, so a take-off that comes just as that time runs out meets the disarm before it leaves the
    ground: it arms again and climbs, instead of failing with "was disarmed"."""
    f = flight()
    landed_and_armed(f)
    f.fake.disarm_when_told_to_climb = True
    f.backend.take_off(1.0, blocking=True)
    assert not f.fake.disarm_when_told_to_climb  # the disarm did happen, on the first climbing set-point
    assert f.backend.state == FLYING_AUTO and f.fake.armed
    assert f.backend.telemetry.position[2] == pytest.approx(1.0, abs=0.165)


def test_guards_and_nan_refusals_say_why(flight):
    f = flight()
    landed_and_armed(f)
    backend = f.backend
    for call, text in [
        (lambda: backend.land(True), "land refused: UAV 3 is LANDED_ARMED; land needs FLYING_AUTO"),
        (lambda: backend.go_to("map", (1, 1, 1), 0.0, True), "go_to_waypoint refused: UAV 3 is LANDED_ARMED; "
                                                             "go_to_waypoint needs FLYING_AUTO"),
        (lambda: backend.set_velocity((1, 0, 0), 0.0), "set_velocity refused: UAV 3 is LANDED_ARMED"),
        (lambda: backend.set_pose("map", (1, 0, 1), 0.0), "set_pose refused"),
        (lambda: backend.recover_from_manual(), "recover_from_manual refused: UAV 3 is LANDED_ARMED; "
                                                "recover_from_manual needs FLYING_MANUAL"),
        (lambda: backend.take_off(NAN, True), "height: nan is not a finite number"),
        (lambda: backend.take_off(-1.0, True), "take_off: height must be positive, got -1.0"),
    ]:
        with pytest.raises(CommandRefused, match="^" + text.replace("(", "\\(").replace(")", "\\)")):
            call()
    backend.take_off(1.0, blocking=True)
    for call, text in [
        (lambda: backend.take_off(1.0, True), "take_off refused: UAV 3 is FLYING_AUTO; take_off needs LANDED_ARMED"),
        (lambda: backend.go_to("map", (NAN, 0, 1), 0.0, True), "waypoint.pose.position: [nan, 0.0, 1.0] is not three"),
        (lambda: backend.go_to("map", (0, 0, 1), math.inf, True), "waypoint orientation (yaw): inf is not a finite"),
        (lambda: backend.go_to("odom", (0, 0, 1), 0.0, True), "header.frame_id 'odom' is not known here; use 'map' "
                                                              "or 'uav_3_home'"),
        (lambda: backend.set_pose("map", (0, NAN, 1), 0.0), "set_pose position: [0.0, nan, 1.0]"),
        (lambda: backend.set_velocity((0, 0, NAN), 0.0), "set_velocity linear: [0.0, 0.0, nan]"),
        (lambda: backend.set_velocity((0, 0, 0), NAN), "set_velocity angular.z: nan"),
        (lambda: backend.go_to_geo(NAN, 0.0, 0.0, True), "waypoint: latitude/longitude/altitude [nan, 0.0, 0.0] "
                                                         "must be finite numbers"),
    ]:
        with pytest.raises(CommandRefused, match="^" + text.replace("(", "\\(").replace(")", "\\)")
                           .replace("[", "\\[").replace("]", "\\]")):
            call()
    held = sent(f, "position")[-1]
    assert (held.x, held.y, held.z) == pytest.approx((0.0, 0.0, -1.0), abs=1e-6)  # the refusals changed nothing


def test_the_set_point_stream_in_ned_and_the_velocity_timeout(flight):
    f = flight()
    landed_and_armed(f)
    assert sent(f, "position"), "a hold where it stands is streamed on the ground (OFFBOARD can start)"
    flying(f, 1.0)
    f.backend.go_to("map", (2.0, 1.0, 1.5), math.pi / 2, blocking=True)  # 2 m east, 1 m north, facing north
    point = sent(f, "position")[-1]
    assert (point.x, point.y, point.z, point.yaw) == pytest.approx((1.0, 2.0, -1.5, 0.0), abs=1e-6)
    assert point.coordinate_frame == mavlink.MAV_FRAME_LOCAL_NED and point.target_system == 3
    before = len(sent(f, "velocity"))
    f.backend.set_velocity((0.5, 0.0, 0.2), 0.3)  # east and up, turning anticlockwise
    wait_until(lambda: len(sent(f, "velocity")) > before, "a velocity set-point")
    velocity = sent(f, "velocity")[-1]
    assert (velocity.vx, velocity.vy, velocity.vz, velocity.yaw_rate) == pytest.approx((0.0, 0.5, -0.2, -0.3))
    # Not renewed: within the timeout (0.5 s) it becomes a hold where the vehicle was then.
    wait_until(lambda: f.fake.last_set_point().type_mask == POSITION_AND_YAW, "a hold after the velocity timeout")
    hold = f.fake.last_set_point()
    assert hold.y > 2.0 and hold.x == pytest.approx(1.0, abs=0.05)  # it had moved east; it holds there


def test_take_off_go_to_home_frame_geo_waypoint_and_land(flight):
    f = flight(origin_geo=(37.41, -6.0, 10.0))  # the fake's local origin is the map origin
    flying(f, 2.0)
    assert f.backend.telemetry.position[2] == pytest.approx(2.0, abs=0.165)
    f.backend.set_home(set_z=False)
    assert f.fake.home_commands[-1].param1 == 0  # keeps home's altitude: the position given
    f.backend.go_to("uav_3_home", (1.0, 0.0, 1.0), 0.0, blocking=True)
    assert np.allclose(f.backend.telemetry.position, (1.0, 0.0, 1.0), atol=0.165)
    lat, lon, alt = geo.enu_to_geodetic([-1.0, 2.0, 1.5], (37.41, -6.0, 10.0))
    f.backend.go_to_geo(lat, lon, alt, blocking=True)
    assert np.allclose(f.backend.telemetry.position, (-1.0, 2.0, 1.5), atol=0.165)
    f.backend.set_home(set_z=True)
    assert f.fake.home_commands[-1].param1 == 1  # where it is now, altitude and all
    f.backend.land(blocking=True)
    assert f.backend.state in (LANDED_ARMED, LANDED_DISARMED)


def test_a_newer_command_interrupts_a_blocking_waypoint(flight):
    import threading

    f = flight()
    flying(f, 1.0)
    errors = []

    def far():
        try:
            f.backend.go_to("map", (30.0, 0.0, 1.0), 0.0, blocking=True)
        except CommandRefused as err:
            errors.append(str(err))

    thread = threading.Thread(target=far)
    thread.start()
    wait_until(lambda: f.backend.telemetry.position[0] > 0.5, "moving toward the far waypoint")
    f.backend.set_pose("map", (0.0, 0.0, 1.0), 0.0)
    thread.join(timeout=10)
    assert errors == ["go_to_waypoint interrupted: a newer command replaced it before it finished"]


def test_a_pilots_take_over_shows_as_flying_manual_until_recovered(flight):
    f = flight()
    flying(f, 1.0)
    f.fake.pilot_selects("POSCTL")
    wait_until(state_is(f, FLYING_MANUAL), "FLYING_MANUAL")
    with pytest.raises(CommandRefused, match="go_to_waypoint refused: UAV 3 is FLYING_MANUAL"):
        f.backend.go_to("map", (1, 1, 1), 0.0, True)
    f.backend.recover_from_manual()
    assert f.fake.mode == "OFFBOARD"
    wait_until(state_is(f, FLYING_AUTO), "FLYING_AUTO again")


def test_a_pilot_who_selects_offboard_in_flight_gives_the_ual_the_uav_back(flight):
    f = flight(arming="pilot")
    f.fake.armed = True
    wait_until(state_is(f, LANDED_ARMED), "LANDED_ARMED by the pilot")
    f.fake.pilot_selects("OFFBOARD")
    f.backend.take_off(1.0, blocking=True)
    f.fake.pilot_selects("POSCTL")
    wait_until(state_is(f, FLYING_MANUAL), "FLYING_MANUAL")
    f.fake.pilot_selects("OFFBOARD")  # the stream held where the UAV was: it holds there
    wait_until(state_is(f, FLYING_AUTO), "FLYING_AUTO")
    f.backend.go_to("map", (1.0, -1.0, 1.5), 0.0, blocking=True)
    assert np.allclose(f.backend.telemetry.position, (1.0, -1.0, 1.5), atol=0.165)


def test_a_lost_heartbeat_is_said_and_makes_the_uav_uninitialized(flight):
    f = flight()
    flying(f, 1.0)
    assert f.backend.link_problem == ""
    f.fake.heartbeat = False
    # The position (1.0 s timeout too) lapses a tick before the link, as every message refreshes the link:
    # UNINITIALIZED alone can come before the link problem is said.
    lost = f"no heartbeat from {f.url} for 1.0 s (nor any other message)"
    wait_until(lambda: f.backend.link_problem == lost and f.backend.state == UNINITIALIZED,
               "the lost link said, and UNINITIALIZED")
    with pytest.raises(CommandRefused, match="land refused: UAV 3 is UNINITIALIZED"):
        f.backend.land(True)
    f.fake.heartbeat = True
    wait_until(state_is(f, FLYING_AUTO), "FLYING_AUTO when the HEARTBEAT is back")
    assert f.backend.link_problem == ""


def test_lost_heartbeats_with_telemetry_still_coming_are_not_a_lost_link(flight):
    import time

    f = flight()
    flying(f, 1.0)
    f.fake.heartbeats = False  # as through a radio that loses HEARTBEATs now and then
    end = time.monotonic() + 3 * f.backend.settings.heartbeat_timeout
    while time.monotonic() < end:  # three heartbeat timeouts without a HEARTBEAT
        assert f.backend.link_problem == "" and f.backend.state == FLYING_AUTO
        time.sleep(0.05)


def test_a_heartbeat_lost_during_a_blocking_call_fails_it_with_the_link(flight):
    import threading

    # A cut link silences the position too. With equal timeouts either could run out first (the last message
    # before the cut may be a HEARTBEAT or LOCAL_POSITION_NED); a longer position timeout makes it the link.
    f = flight(position_timeout=2.0)
    flying(f, 1.0)
    errors = []
    thread = threading.Thread(target=lambda: _catch(errors, lambda: f.backend.go_to("map", (40, 0, 1), 0.0, True)))
    thread.start()
    f.fake.heartbeat = False
    thread.join(timeout=10)
    assert errors == [f"go_to_waypoint interrupted: no heartbeat from {f.url} for 1.0 s (nor any other message)"]


def test_a_position_lost_during_a_blocking_call_fails_it_saying_so(flight):
    import threading

    f = flight()
    flying(f, 1.0)
    errors = []
    thread = threading.Thread(target=lambda: _catch(errors, lambda: f.backend.go_to("map", (40, 0, 1), 0.0, True)))
    thread.start()
    f.fake.send_telemetry = False  # HEARTBEATs still come: the link is alive, the position is not
    thread.join(timeout=10)
    assert errors == [f"go_to_waypoint interrupted: UAV 3 is UNINITIALIZED (no position from {f.url} for 1.0 s)"]
    assert f.backend.link_problem == ""


def _catch(errors, call):
    try:
        call()
    except CommandRefused as err:
        errors.append(str(err))


def test_arming_pilot_never_arms_and_take_off_waits_for_the_pilots_switch(flight):
    import threading

    f = flight(arming="pilot")
    wait_until(state_is(f, LANDED_DISARMED), "LANDED_DISARMED")
    with pytest.raises(CommandRefused, match="take_off refused: UAV 3 is LANDED_DISARMED; take_off needs LANDED_ARMED"):
        f.backend.take_off(1.0, True)
    f.fake.armed = True  # the safety pilot arms
    wait_until(state_is(f, LANDED_ARMED), "LANDED_ARMED by the pilot")
    thread = threading.Thread(target=lambda: f.backend.take_off(1.0, blocking=True))
    thread.start()
    wait_until(lambda: f.backend.state == TAKING_OFF, "TAKING_OFF, waiting for the pilot")
    assert f.fake.mode == "POSCTL" and f.fake.position[2] == 0.0
    f.fake.pilot_selects("OFFBOARD")  # the stream already holds it where it stands
    thread.join(timeout=20)
    assert f.backend.state == FLYING_AUTO
    assert not [c for c in f.fake.commands if c.command in (mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                                                             mavlink.MAV_CMD_DO_SET_MODE)]


def test_ardupilot_copter_takes_off_with_nav_takeoff_in_guided_and_lands_in_land(flight):
    f = flight(autopilot=ap.ARDUPILOT)
    landed_and_armed(f)
    assert f.fake.mode == "GUIDED"
    f.backend.take_off(1.0, blocking=True)
    takeoffs = [c for c in f.fake.commands if c.command == mavlink.MAV_CMD_NAV_TAKEOFF]
    assert [c.param7 for c in takeoffs] == [1.0]
    assert f.backend.telemetry.position[2] == pytest.approx(1.0, abs=0.165)
    f.backend.land(blocking=True)
    assert f.fake.mode == "LAND"
