"""What the telemetry says in ROS terms: NED to ENU, the FRD attitude as FLU in ENU, modes and arming, the map
frame placed through a geo origin, battery, and an autopilot the UAL cannot fly."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from magna_common import geo
from magna_mavlink import autopilot as ap
from magna_mavlink.link import mavlink
from magna_mavlink.ual_state import IN_AIR, LANDED_UNDEFINED, ON_GROUND
from magna_mavlink.vehicle_state import VehicleState

ORIGIN = (37.41, -6.0, 10.0)  # the map's


def heartbeat(mode="OFFBOARD", armed=True, autopilot=ap.MAV_AUTOPILOT_PX4):
    name = ap.PX4 if autopilot == ap.MAV_AUTOPILOT_PX4 else ap.ARDUPILOT
    base, custom = ap.encode_mode(name, mode)
    return mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_QUADROTOR, autopilot,
                                             base | (ap.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0), custom, 4, 3)


def local(x, y, z, vx=0.0, vy=0.0, vz=0.0, ms=1000):
    return mavlink.MAVLink_local_position_ned_message(ms, x, y, z, vx, vy, vz)


def global_at(lat, lon, alt, ms=1000):
    return mavlink.MAVLink_global_position_int_message(ms, round(lat * 1e7), round(lon * 1e7), round(alt * 1e3),
                                                       0, 0, 0, 0, 0)


def test_positions_and_velocities_come_in_enu_and_the_attitude_as_flu_in_enu():
    state = VehicleState()
    state.update(local(1.0, 2.0, -3.0, 0.5, 0.0, -1.0), now=5.0)  # 1 m north, 2 m east, 3 m up
    state.update(mavlink.MAVLink_attitude_message(1000, 0.0, 0.0, 0.0, 0.1, 0.2, 0.3), now=5.0)  # facing north
    t = state.snapshot()
    assert np.allclose(t.position, (2.0, 1.0, 3.0)) and np.allclose(t.velocity, (0.0, 0.5, 1.0))
    assert t.yaw == pytest.approx(math.pi / 2)  # ENU: north is 90 degrees
    assert np.allclose(t.angular_velocity, (0.1, -0.2, -0.3))
    assert t.position_valid(5.5) and not t.position_valid(6.5)  # a second without LOCAL_POSITION_NED: lost


def test_heartbeats_give_the_mode_and_arming_and_extended_state_the_landed_state():
    state = VehicleState()
    assert state.snapshot().landed_state == LANDED_UNDEFINED and not state.snapshot().follows_set_points
    state.update(heartbeat("OFFBOARD", armed=True), now=1.0)
    state.update(mavlink.MAVLink_extended_sys_state_message(0, IN_AIR), now=1.0)
    t = state.snapshot()
    assert (t.autopilot, t.mode.name, t.armed, t.follows_set_points, t.heartbeat_time) == ("px4", "OFFBOARD", True,
                                                                                            True, 1.0)
    assert t.landed_state == IN_AIR
    state.update(heartbeat("GUIDED", armed=False, autopilot=ap.MAV_AUTOPILOT_ARDUPILOTMEGA), now=2.0)
    assert state.snapshot().mode.name == "GUIDED" and state.snapshot().follows_set_points


def test_an_autopilot_the_ual_cannot_fly_is_said_and_a_forced_one_is_believed():
    state = VehicleState()
    state.update(mavlink.MAVLink_heartbeat_message(2, 0, 0, 0, 3, 3), now=1.0)  # MAV_AUTOPILOT_GENERIC
    assert state.snapshot().autopilot is None and "HEARTBEAT.autopilot 0 is neither PX4" in state.autopilot_error
    forced = VehicleState(autopilot="px4")
    forced.update(mavlink.MAVLink_heartbeat_message(2, 0, 1, 6 << 16, 3, 3), now=1.0)
    assert forced.snapshot().mode.name == "OFFBOARD"


def test_without_a_geo_origin_the_map_is_the_autopilots_local_frame_and_home_gives_the_geo_reference():
    state = VehicleState()
    state.update(local(0.0, 0.0, 0.0), now=0.0)
    assert state.snapshot().position_valid(0.0)
    home = geo.enu_to_geodetic([4.0, 3.0, 0.0], ORIGIN)
    state.update(mavlink.MAVLink_home_position_message(round(home[0] * 1e7), round(home[1] * 1e7),
                                                       round(home[2] * 1e3), 3.0, 4.0, 0.0, [1, 0, 0, 0],
                                                       0, 0, 0), now=0.0)  # home 3 m north, 4 m east of the origin
    reference_geo, reference_map = state.snapshot().geo_reference()
    assert np.allclose(reference_map, 0.0)
    assert np.allclose(geo.geodetic_to_enu(*reference_geo, ORIGIN), 0.0, atol=0.01)


def test_with_a_geo_origin_the_local_origin_is_placed_in_the_map_from_a_still_global_and_local_pair():
    state = VehicleState(origin_geo=ORIGIN)
    vehicle_map = np.array([10.0, -5.0, 0.0])  # where the vehicle stands in the map; its local origin is there too
    state.update(local(0.0, 0.0, 0.0, ms=2000), now=1.0)
    assert not state.snapshot().position_valid(1.0)  # no map offset yet
    state.update(global_at(*geo.enu_to_geodetic(vehicle_map, ORIGIN), ms=2500), now=1.0)  # not the same instant
    assert state.snapshot().map_offset is None
    state.update(global_at(*geo.enu_to_geodetic(vehicle_map, ORIGIN), ms=2020), now=1.0)
    t = state.snapshot()
    assert t.position_valid(1.0) and np.allclose(t.position, vehicle_map, atol=0.02)
    state.update(local(2.0, 1.0, -1.0, ms=3000), now=2.0)  # 2 m north, 1 m east, 1 m up of its start
    t = state.snapshot()
    assert np.allclose(t.position, vehicle_map + (1.0, 2.0, 1.0), atol=0.02)
    assert np.allclose(t.map_to_local_ned(t.position), (2.0, 1.0, -1.0), atol=1e-9)


def test_a_moving_vehicle_does_not_place_the_origin_and_gps_global_origin_does():
    state = VehicleState(origin_geo=ORIGIN)
    state.update(local(0.0, 0.0, -2.0, vx=3.0, ms=1000), now=0.0)
    state.update(global_at(*ORIGIN, ms=1000), now=0.0)
    assert state.snapshot().map_offset is None  # 3 m/s: the two may be apart in time
    origin = geo.enu_to_geodetic([0.0, 2.0, 0.0], ORIGIN)
    state.update(mavlink.MAVLink_gps_global_origin_message(round(origin[0] * 1e7), round(origin[1] * 1e7),
                                                           round(origin[2] * 1e3)), now=0.0)
    assert np.allclose(state.snapshot().map_offset, (0.0, 2.0, 0.0), atol=0.02)


def test_battery_from_sys_status():
    state = VehicleState()
    state.update(mavlink.MAVLink_sys_status_message(0, 0, 0, 0, 12600, -1, 73, 0, 0, 0, 0, 0, 0), now=0.0)
    assert (state.snapshot().battery, state.snapshot().voltage) == (0.73, 12.6)
    state.update(mavlink.MAVLink_sys_status_message(0, 0, 0, 0, 0xFFFF, -1, -1, 0, 0, 0, 0, 0, 0), now=0.0)
    assert math.isnan(state.snapshot().battery) and math.isnan(state.snapshot().voltage)


def test_the_attitude_matches_the_frames_table():
    state = VehicleState()
    state.update(mavlink.MAVLink_attitude_message(0, math.radians(20), 0.0, 0.0, 0, 0, 0), now=0.0)  # facing north
    flu_in_enu = Rotation.from_quat(state.snapshot().orientation).as_euler("ZYX", degrees=True)
    assert np.allclose(flu_in_enu, (90.0, 0.0, 20.0))  # right wing down in FRD is left wing up in FLU


def test_extended_sys_state_on_ground():
    state = VehicleState()
    state.update(mavlink.MAVLink_extended_sys_state_message(0, ON_GROUND), now=0.0)
    assert state.snapshot().landed_state == ON_GROUND


def test_the_first_message_and_whether_a_landed_state_came_are_kept():
    state = VehicleState()
    state.update(heartbeat("OFFBOARD", armed=True), now=4.0)
    state.update(local(0.0, 0.0, 0.0), now=4.5)
    t = state.snapshot()
    assert (t.first_heard_time, t.heard_time, t.landed_state_heard) == (4.0, 4.5, False)
    state.update(mavlink.MAVLink_extended_sys_state_message(0, ON_GROUND), now=5.0)
    t = state.snapshot()
    assert (t.first_heard_time, t.landed_state_heard, t.landed_state) == (4.0, True, ON_GROUND)
