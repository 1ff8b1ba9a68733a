"""magna_sim's PX4-like MAVLink vehicle, driven in simulated time with pymavlink messages (no sockets).

Every message goes through MAVLink 2 encoding both ways, as over a link, so a field the vehicle
fills wrongly fails here and not in a client.
"""
import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from magna_common import geo
from magna_mavlink import autopilot
from magna_sim.mavlink_telemetry import PX4_SITL_HOME
from magna_sim.mavlink_vehicle import MavlinkVehicle
from magna_sim.ual_logic import UalState
from magna_sim.world import SimWorld

NAN = math.nan
ACCEPTED, REJECTED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_TEMPORARILY_REJECTED
DENIED, UNSUPPORTED = mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_UNSUPPORTED
VELOCITY_ONLY = 1 | 2 | 4 | 64 | 128 | 256 | 2048  # ignore position, accelerations and yaw rate
POSITION_ONLY = 8 | 16 | 32 | 64 | 128 | 256 | 2048


class Link:
    """One simulated UAV and its MAVLink vehicle, talked to as a ground station (system 255) would."""

    def __init__(self, with_ual=False, battery=None, position=(0.0, 0.0, 0.0)):
        self.world = SimWorld(physics_rate=100.0)
        self.uav = self.world.spawn_uav("uav_1", 1, "iris", "light", position)
        self.ual = self.world.ual[1] if with_ual else None
        self.vehicle = MavlinkVehicle(self.uav, 1, PX4_SITL_HOME, now=0.0, ual=self.ual, battery=battery)
        self._gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self._from_gcs = mavlink.MAVLink(None)
        self._autopilot = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self._from_autopilot = mavlink.MAVLink(None)
        self.log: list[tuple[float, object]] = []  # (sim time, message) the vehicle sent

    @property
    def now(self) -> float:
        return self.world.time

    def _received(self, messages) -> list:
        out = []
        for message in messages:
            (parsed,) = self._from_autopilot.parse_buffer(message.pack(self._autopilot))
            out.append(parsed)
            self.log.append((self.now, parsed))
        return out

    def send(self, message) -> list:
        (parsed,) = self._from_gcs.parse_buffer(message.pack(self._gcs))
        return self._received(self.vehicle.handle(parsed, self.now))

    def command(self, command, *params, target=1) -> list:
        params = list(params) + [NAN] * (7 - len(params))
        return self.send(mavlink.MAVLink_command_long_message(target, 1, command, 0, *params))

    def result(self, command, *params) -> int:
        answers = self.command(command, *params)
        (ack,) = [m for m in answers if m.get_type() == "COMMAND_ACK"]
        assert ack.command == command and (ack.target_system, ack.target_component) == (255, 190)
        return ack.result

    def set_mode(self, name) -> int:
        base, custom = autopilot.encode_mode(autopilot.PX4, name)
        return self.result(mavlink.MAV_CMD_DO_SET_MODE, base, (custom >> 16) & 0xFF, (custom >> 24) & 0xFF)

    def setpoint(self, type_mask, x=0.0, y=0.0, z=0.0, vx=0.0, vy=0.0, vz=0.0, yaw=0.0, yaw_rate=0.0,
                 frame=mavlink.MAV_FRAME_LOCAL_NED) -> list:
        return self.send(mavlink.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, frame, type_mask, x, y, z, vx, vy, vz, 0, 0, 0, yaw, yaw_rate))

    def run(self, seconds, every=None, each=None) -> None:
        """Step the world for `seconds` of simulated time, calling `each()` every `every` s."""
        end, next_call = self.now + seconds, self.now
        while self.now < end - 1e-9:
            if each is not None and self.now >= next_call - 1e-9:
                each()
                next_call += every
            self.world.step()
            self._received(self.vehicle.tick(self.now))

    def run_until(self, condition, what, limit=60.0) -> float:
        end = self.now + limit
        while not condition():
            assert self.now < end, f"no {what} within {limit} s of simulated time"
            self.world.step()
            self._received(self.vehicle.tick(self.now))
        return self.now

    def sent(self, kind, since=0.0) -> list:
        return [m for t, m in self.log if m.get_type() == kind and t >= since]

    def last(self, kind):
        return self.sent(kind)[-1]

    def mode(self) -> str:
        heartbeat = self.last("HEARTBEAT")
        return autopilot.decode_mode(heartbeat.autopilot, heartbeat.base_mode, heartbeat.custom_mode).name

    def armed(self) -> bool:
        return bool(self.last("HEARTBEAT").base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def take_off(self) -> None:
        assert self.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ACCEPTED
        assert self.result(mavlink.MAV_CMD_NAV_TAKEOFF) == ACCEPTED
        self.run_until(lambda: self.vehicle.mode == "AUTO.LOITER", "end of take-off")
        self.run(2.0)  # settle in the hold


@pytest.fixture
def link():
    link = Link()
    link.run(0.05)
    yield link
    link.world.close()


# --- identity and health ------------------------------------------------------------------------------------
def test_heartbeat_says_px4_quadrotor_in_hold_disarmed_and_sys_status_is_healthy(link):
    heartbeat = link.last("HEARTBEAT")
    assert (heartbeat.type, heartbeat.autopilot) == (mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4)
    assert heartbeat.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert (link.mode(), link.armed()) == ("AUTO.LOITER", False)
    status = link.last("SYS_STATUS")
    needed = (mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
              | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG | mavlink.MAV_SYS_STATUS_SENSOR_GPS
              | mavlink.MAV_SYS_STATUS_PREARM_CHECK)
    assert status.onboard_control_sensors_present & needed == needed
    assert status.onboard_control_sensors_health & needed == needed
    assert link.last("EXTENDED_SYS_STATE").landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND
    assert link.last("GPS_RAW_INT").fix_type == mavlink.GPS_FIX_TYPE_3D_FIX


def test_battery_is_reported_when_the_sim_gives_one():
    link = Link(battery=lambda: (12.3, 0.8))
    link.run(0.05)
    assert link.last("SYS_STATUS").voltage_battery == 12300 and link.last("SYS_STATUS").battery_remaining == 80
    assert link.last("BATTERY_STATUS").battery_remaining == 80
    assert Link().vehicle.streams.interval_us(mavlink.MAVLINK_MSG_ID_BATTERY_STATUS) == -1  # none without one


# --- arming, take-off, landing ------------------------------------------------------------------------------
def test_arm_takes_off_to_mis_takeoff_alt_then_holds(link):
    assert link.result(mavlink.MAV_CMD_NAV_TAKEOFF) == REJECTED  # disarmed
    answers = link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert [m.get_type() for m in answers][:2] == ["COMMAND_ACK", "HEARTBEAT"]  # the change is said at once
    assert link.armed() and link.last("HOME_POSITION")
    assert link.result(mavlink.MAV_CMD_NAV_TAKEOFF) == ACCEPTED
    assert link.mode() == "AUTO.TAKEOFF"
    link.run_until(lambda: link.vehicle.mode == "AUTO.LOITER", "end of take-off")
    assert link.uav.position[2] == pytest.approx(2.5, abs=0.15)
    states = [m.landed_state for m in link.sent("EXTENDED_SYS_STATE")]
    assert states[0] == mavlink.MAV_LANDED_STATE_ON_GROUND
    assert mavlink.MAV_LANDED_STATE_TAKEOFF in states
    link.run(3.0)
    assert link.last("EXTENDED_SYS_STATE").landed_state == mavlink.MAV_LANDED_STATE_IN_AIR
    assert link.uav.position == pytest.approx([0.0, 0.0, 2.5], abs=0.15)
    assert link.last("LOCAL_POSITION_NED").z == pytest.approx(-2.5, abs=0.15)


def test_takeoff_altitude_follows_the_parameter_and_an_amsl_param7(link):
    link.send(mavlink.MAVLink_param_set_message(1, 1, b"MIS_TAKEOFF_ALT", 4.0, mavlink.MAV_PARAM_TYPE_REAL32))
    link.take_off()
    assert link.uav.position[2] == pytest.approx(4.0, abs=0.15)
    second = Link()
    second.run(0.05)
    assert second.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ACCEPTED
    assert second.result(mavlink.MAV_CMD_NAV_TAKEOFF, NAN, NAN, NAN, NAN, NAN, NAN, PX4_SITL_HOME[2] + 6.0) == ACCEPTED
    second.run_until(lambda: second.vehicle.mode == "AUTO.LOITER", "end of take-off")
    assert second.uav.position[2] == pytest.approx(6.0, abs=0.15)


def test_land_then_auto_disarm_after_com_disarm_land(link):
    link.take_off()
    assert link.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0) == DENIED  # not in the air
    assert link.result(mavlink.MAV_CMD_NAV_LAND) == ACCEPTED
    assert link.mode() == "AUTO.LAND"
    landed = link.run_until(lambda: link.vehicle.on_ground, "touch-down")
    assert link.uav.position[2] < 0.05 and link.armed()
    disarmed = link.run_until(lambda: not link.vehicle.armed, "auto-disarm")
    assert disarmed - landed == pytest.approx(2.0, abs=0.02)  # COM_DISARM_LAND
    assert not link.armed() and link.last("EXTENDED_SYS_STATE").landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND
    texts = [m.text for m in link.sent("STATUSTEXT")]
    assert "Landing detected" in texts and "Disarmed: on the ground for 2 s (COM_DISARM_LAND)" in texts
    # Armed again, a finished landing waits for orders in HOLD.
    assert link.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ACCEPTED and link.mode() == "AUTO.LOITER"


def test_armed_without_taking_off_disarms_after_com_disarm_prflt(link):
    link.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    armed = link.now
    disarmed = link.run_until(lambda: not link.vehicle.armed, "pre-flight auto-disarm", limit=20.0)
    assert disarmed - armed == pytest.approx(10.0, abs=0.02)


def test_force_disarm_in_the_air(link):
    link.take_off()
    assert link.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196) == ACCEPTED
    assert not link.armed()


# --- OFFBOARD -----------------------------------------------------------------------------------------------
def test_offboard_is_refused_without_a_recent_set_point(link):
    link.take_off()
    assert link.set_mode("OFFBOARD") == REJECTED
    assert link.mode() == "AUTO.LOITER"
    assert "Switching to OFFBOARD denied: no set-points" in [m.text for m in link.sent("STATUSTEXT")]
    link.setpoint(VELOCITY_ONLY)
    link.run(0.6)
    assert link.set_mode("OFFBOARD") == REJECTED  # 0.6 s old: no stream
    link.setpoint(VELOCITY_ONLY)
    assert link.set_mode("OFFBOARD") == ACCEPTED and link.mode() == "OFFBOARD"


def test_offboard_lost_after_com_of_loss_t_holds_where_it_is(link):
    link.take_off()

    def stream():
        link.setpoint(VELOCITY_ONLY, vx=1.0)

    stream()
    assert link.set_mode("OFFBOARD") == ACCEPTED
    link.run(3.0, every=0.5, each=stream)  # gaps of 0.5 s are a stream still
    assert link.vehicle.mode == "OFFBOARD"
    last = link.now - 0.5  # the last set-point (run ended just before the next)
    left = link.run_until(lambda: link.vehicle.mode != "OFFBOARD", "offboard loss")
    assert left - last == pytest.approx(1.0, abs=0.02)  # COM_OF_LOSS_T
    assert link.mode() == "AUTO.LOITER"
    assert any("Offboard set-points lost" in m.text for m in link.sent("STATUSTEXT"))
    link.run(4.0)
    held = link.uav.position.copy()
    link.run(2.0)
    assert link.uav.position == pytest.approx(held, abs=0.05) and np.linalg.norm(link.uav.velocity) < 0.05


def test_com_of_loss_t_is_a_parameter(link):
    link.send(mavlink.MAVLink_param_set_message(1, 1, b"COM_OF_LOSS_T", 3.0, mavlink.MAV_PARAM_TYPE_REAL32))
    link.take_off()
    link.setpoint(VELOCITY_ONLY)
    link.set_mode("OFFBOARD")
    sent = link.now
    left = link.run_until(lambda: link.vehicle.mode != "OFFBOARD", "offboard loss")
    assert left - sent == pytest.approx(3.0, abs=0.02)


def test_ned_velocity_east_moves_the_vehicle_east_in_enu(link):
    """NED +y (east) is ENU +x: the sim's map x grows, y and z stay."""
    link.take_off()
    start = link.uav.position.copy()
    link.setpoint(VELOCITY_ONLY, vy=1.0)
    link.set_mode("OFFBOARD")
    link.run(4.0, every=0.1, each=lambda: link.setpoint(VELOCITY_ONLY, vy=1.0))
    moved = link.uav.position - start
    assert moved[0] > 3.0 and abs(moved[1]) < 0.05 and abs(moved[2]) < 0.05
    assert link.uav.velocity[0] == pytest.approx(1.0, abs=0.05)
    local = link.last("LOCAL_POSITION_NED")
    assert local.vy == pytest.approx(1.0, abs=0.05) and abs(local.vx) < 0.05


def test_ned_position_and_yaw_become_enu(link):
    link.take_off()
    link.setpoint(POSITION_ONLY, x=3.0, y=-2.0, z=-4.0, yaw=0.0)  # 3 m north, 2 m west, 4 m up, facing north
    link.set_mode("OFFBOARD")
    link.run(10.0, every=0.1, each=lambda: link.setpoint(POSITION_ONLY, x=3.0, y=-2.0, z=-4.0, yaw=0.0))
    assert link.uav.position == pytest.approx([-2.0, 3.0, 4.0], abs=0.05)
    assert link.uav.yaw == pytest.approx(math.pi / 2, abs=0.02)  # facing north: ENU yaw 90 deg
    assert link.last("ATTITUDE").yaw == pytest.approx(0.0, abs=0.02)  # NED yaw 0


def test_type_mask_mixes_velocity_and_position_axes(link):
    """Velocity north with the altitude held by position (z given, x and y ignored), yaw by rate."""
    link.take_off()
    mask = 1 | 2 | 32 | 64 | 128 | 256 | 1024  # x, y, vz, accelerations and yaw ignored

    def stream():
        link.setpoint(mask, z=-3.0, vx=0.5, yaw_rate=0.3)

    stream()
    link.set_mode("OFFBOARD")
    yaw0 = link.uav.yaw
    link.run(4.0, every=0.1, each=stream)
    assert link.uav.position[2] == pytest.approx(3.0, abs=0.1)  # climbed to z = -3 NED
    assert link.uav.velocity[1] == pytest.approx(0.5, abs=0.05)  # north is ENU +y
    turned = (link.uav.yaw - yaw0 + math.pi) % (2 * math.pi) - math.pi
    assert turned < -0.5  # NED yaw rate +0.3 (clockwise) turns the ENU heading negative


def test_body_frame_velocity_follows_the_heading(link):
    link.take_off()  # faces east (ENU yaw 0 at spawn): forward is east
    def forward():
        link.setpoint(VELOCITY_ONLY | 1024, vx=1.0, frame=mavlink.MAV_FRAME_BODY_NED)  # heading left alone

    forward()
    link.set_mode("OFFBOARD")
    link.run(2.0, every=0.1, each=forward)
    assert link.uav.velocity[0] == pytest.approx(1.0, abs=0.05) and abs(link.uav.velocity[1]) < 0.05


def test_offboard_on_the_ground_then_arm_climbs(link):
    link.setpoint(VELOCITY_ONLY, vz=-1.0)
    assert link.set_mode("OFFBOARD") == ACCEPTED
    link.result(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    link.run(2.0, every=0.1, each=lambda: link.setpoint(VELOCITY_ONLY, vz=-1.0))
    assert link.uav.position[2] > 1.5 and not link.vehicle.on_ground


def test_global_set_point(link):
    link.take_off()
    lat, lon, alt = geo.enu_to_geodetic([4.0, 5.0, 3.0], PX4_SITL_HOME)

    def stream():
        link.send(mavlink.MAVLink_set_position_target_global_int_message(
            0, 1, 1, mavlink.MAV_FRAME_GLOBAL_INT, POSITION_ONLY | 1024, int(round(lat * 1e7)),
            int(round(lon * 1e7)), alt, 0, 0, 0, 0, 0, 0, 0, 0))

    stream()
    link.set_mode("OFFBOARD")
    link.run(12.0, every=0.1, each=stream)
    assert link.uav.position == pytest.approx([4.0, 5.0, 3.0], abs=0.05)


# --- reposition, home, modes --------------------------------------------------------------------------------
def test_reposition_holds_at_a_global_position(link):
    lat, lon, alt = geo.enu_to_geodetic([0.0, 10.0, 4.0], PX4_SITL_HOME)  # 10 m north, 4 m up
    reposition = mavlink.MAVLink_command_int_message(1, 1, mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_CMD_DO_REPOSITION,
                                                     0, 0, -1, 1, 0, 0, int(round(lat * 1e7)),
                                                     int(round(lon * 1e7)), alt)
    (ack,) = link.send(reposition)[:1]
    assert ack.result == REJECTED  # on the ground
    link.take_off()
    assert link.send(reposition)[0].result == ACCEPTED
    link.run(15.0)
    assert link.uav.position == pytest.approx([0.0, 10.0, 4.0], abs=0.05)
    assert link.mode() == "AUTO.LOITER"
    # Relative to home, by COMMAND_LONG (degrees), with a heading: 3 m above home, facing north.
    assert link.result(mavlink.MAV_CMD_DO_REPOSITION, -1, 1, 0, 0.0, lat, lon, NAN) == ACCEPTED
    relative = mavlink.MAVLink_command_int_message(1, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                                   mavlink.MAV_CMD_DO_REPOSITION, 0, 0, -1, 1, 0, 0,
                                                   2**31 - 1, 2**31 - 1, 3.0)
    assert link.send(relative)[0].result == ACCEPTED
    link.run(10.0)
    assert link.uav.position == pytest.approx([0.0, 10.0, 3.0], abs=0.05)
    assert link.uav.yaw == pytest.approx(math.pi / 2, abs=0.02)


def test_set_home_and_home_position(link):
    link.take_off()
    assert link.result(mavlink.MAV_CMD_DO_SET_HOME, 1) == ACCEPTED
    home = link.last("HOME_POSITION")
    assert home.z == pytest.approx(-2.5, abs=0.15)
    lat, lon, alt = geo.enu_to_geodetic([1.0, 2.0, 0.0], PX4_SITL_HOME)
    assert link.result(mavlink.MAV_CMD_DO_SET_HOME, 0, NAN, NAN, NAN, lat, lon, alt) == ACCEPTED
    home = link.last("HOME_POSITION")  # COMMAND_LONG's float32 degrees are good to about half a metre
    assert (home.x, home.y, home.z) == pytest.approx((2.0, 1.0, 0.0), abs=0.5)
    precise = mavlink.MAVLink_command_int_message(1, 1, mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_CMD_DO_SET_HOME,
                                                  0, 0, 0, NAN, NAN, NAN, int(round(lat * 1e7)),
                                                  int(round(lon * 1e7)), alt)
    assert link.send(precise)[0].result == ACCEPTED
    home = link.last("HOME_POSITION")
    assert (home.x, home.y, home.z) == pytest.approx((2.0, 1.0, 0.0), abs=0.01)
    link.run(0.2)
    assert link.last("GLOBAL_POSITION_INT").relative_alt == pytest.approx(2500, abs=150)


def test_hold_modes_and_unsimulated_modes(link):
    link.take_off()
    assert link.set_mode("POSCTL") == ACCEPTED and link.mode() == "POSCTL"
    assert link.set_mode("AUTO.MISSION") == DENIED
    assert link.set_mode("AUTO.RTL") == DENIED
    assert link.mode() == "POSCTL"
    assert link.result(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_AUTO_ARMED, 0, 0) == DENIED  # not custom
    assert link.set_mode("AUTO.LAND") == ACCEPTED
    link.run_until(lambda: link.vehicle.on_ground, "touch-down")


# --- protocol services --------------------------------------------------------------------------------------
def test_autopilot_version_on_request_and_unknown_commands(link):
    for answers in (link.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION),
                    link.command(mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1)):
        assert [m.get_type() for m in answers] == ["COMMAND_ACK", "AUTOPILOT_VERSION"]
        capabilities = answers[1].capabilities
        for bit in (mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2, mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
                    mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT, mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
                    mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED):
            assert capabilities & bit
        assert bytes(answers[1].flight_custom_version) == b"magnasim"
    answers = link.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
    assert [m.get_type() for m in answers] == ["COMMAND_ACK", "HOME_POSITION"]
    assert link.result(mavlink.MAV_CMD_REQUEST_MESSAGE, 9999) == UNSUPPORTED
    assert link.result(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH) == UNSUPPORTED
    assert link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, target=7) == []  # another system's command


def test_message_intervals(link):
    def rate(msg_id, kind):
        start = link.now
        link.run(2.0)
        return len(link.sent(kind, since=start + 1e-9)) / 2.0

    local = mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED
    assert rate(local, "LOCAL_POSITION_NED") == pytest.approx(30.0, abs=1.0)
    assert link.result(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, local, 100_000) == ACCEPTED
    assert rate(local, "LOCAL_POSITION_NED") == pytest.approx(10.0, abs=0.5)
    (ack, interval) = link.command(mavlink.MAV_CMD_GET_MESSAGE_INTERVAL, local)
    assert (interval.message_id, interval.interval_us) == (local, 100_000)
    assert link.result(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, local, -1) == ACCEPTED
    assert rate(local, "LOCAL_POSITION_NED") == 0
    assert link.result(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, local, 0) == ACCEPTED  # back to the default
    assert rate(local, "LOCAL_POSITION_NED") == pytest.approx(30.0, abs=1.0)
    assert rate(None, "HEARTBEAT") == pytest.approx(1.0, abs=0.5)
    assert link.result(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 9999, 100_000) == UNSUPPORTED


def test_parameters_list_read_and_set(link):
    answers = link.send(mavlink.MAVLink_param_request_list_message(1, 1))
    names = [m.param_id for m in answers]
    assert {"MIS_TAKEOFF_ALT", "COM_OF_LOSS_T", "COM_DISARM_LAND", "NAV_RCL_ACT", "COM_RCL_EXCEPT",
            "MPC_XY_VEL_MAX"} <= set(names)
    assert [m.param_index for m in answers] == list(range(len(answers)))
    assert {m.param_count for m in answers} == {len(answers)}
    (value,) = link.send(mavlink.MAVLink_param_request_read_message(1, 1, b"COM_OF_LOSS_T", -1))
    assert (value.param_value, value.param_type) == (1.0, mavlink.MAV_PARAM_TYPE_REAL32)
    (by_index,) = link.send(mavlink.MAVLink_param_request_read_message(1, 1, b"", names.index("MPC_XY_VEL_MAX")))
    assert by_index.param_id == "MPC_XY_VEL_MAX" and by_index.param_value == 10.0  # iris's limit
    # Integers travel bytewise, as PX4 sends them.
    (rcl,) = link.send(mavlink.MAVLink_param_request_read_message(1, 1, b"COM_RCL_EXCEPT", -1))
    assert rcl.param_type == mavlink.MAV_PARAM_TYPE_INT32
    assert np.float32(rcl.param_value).tobytes() == (4).to_bytes(4, "little")
    bytewise_7 = np.frombuffer((7).to_bytes(4, "little"), dtype="<f4")[0]
    (changed,) = link.send(mavlink.MAVLink_param_set_message(1, 1, b"COM_RCL_EXCEPT", bytewise_7,
                                                             mavlink.MAV_PARAM_TYPE_INT32))
    assert np.float32(changed.param_value).tobytes() == (7).to_bytes(4, "little")
    # Refusals: a read-only one keeps its value, a wrong type or a value out of range is answered in words.
    (kept,) = [m for m in link.send(mavlink.MAVLink_param_set_message(1, 1, b"MPC_XY_VEL_MAX", 20.0,
                                                                      mavlink.MAV_PARAM_TYPE_REAL32))
               if m.get_type() == "PARAM_VALUE"]
    assert kept.param_value == 10.0
    wrong = link.send(mavlink.MAVLink_param_set_message(1, 1, b"COM_OF_LOSS_T", 2.0, mavlink.MAV_PARAM_TYPE_INT32))
    assert [m.get_type() for m in wrong] == ["STATUSTEXT"]
    outside = link.send(mavlink.MAVLink_param_set_message(1, 1, b"MIS_TAKEOFF_ALT", -3.0,
                                                          mavlink.MAV_PARAM_TYPE_REAL32))
    assert [m.get_type() for m in outside] == ["STATUSTEXT"] and "outside" in outside[0].text
    assert link.send(mavlink.MAVLink_param_request_read_message(1, 1, b"NO_SUCH_PARAM", -1)) == []


def test_ping_and_an_empty_mission(link):
    (pong,) = link.send(mavlink.MAVLink_ping_message(1234, 7, 0, 0))
    assert (pong.time_usec, pong.seq, pong.target_system, pong.target_component) == (1234, 7, 255, 190)
    (count,) = link.send(mavlink.MAVLink_mission_request_list_message(1, 1, 0))
    assert count.count == 0
    (ack,) = [m for m in link.send(mavlink.MAVLink_mission_count_message(1, 1, 3, 0)) if m.get_type() == "MISSION_ACK"]
    assert ack.type == mavlink.MAV_MISSION_UNSUPPORTED


# --- telemetry in the map frame -----------------------------------------------------------------------------
def test_positions_attitude_and_geo_follow_the_map_frame():
    link = Link(position=(10.0, 20.0, 0.0))  # 10 m east, 20 m north of the map origin
    link.run(0.2)
    local = link.last("LOCAL_POSITION_NED")
    assert (local.x, local.y, local.z) == pytest.approx((20.0, 10.0, 0.0), abs=1e-3)
    lat, lon, alt = geo.enu_to_geodetic([10.0, 20.0, 0.0], PX4_SITL_HOME)
    position = link.last("GLOBAL_POSITION_INT")
    assert (position.lat, position.lon) == (int(round(lat * 1e7)), int(round(lon * 1e7)))
    assert position.alt == pytest.approx(alt * 1000.0, abs=1) and position.relative_alt == 0
    assert position.hdg == 9000  # spawned with ENU yaw 0: facing east
    assert link.last("ATTITUDE").yaw == pytest.approx(math.pi / 2, abs=1e-3)
    quaternion = link.last("ATTITUDE_QUATERNION")
    assert (quaternion.q1, quaternion.q4) == pytest.approx((math.cos(math.pi / 4), math.sin(math.pi / 4)), abs=1e-3)
    link.world.close()


# --- shared with the UAL ------------------------------------------------------------------------------------
def test_a_ual_flight_is_reported_and_a_mavlink_command_is_a_pilots_take_over():
    link = Link(with_ual=True)
    link.run(0.05)
    link.ual.take_off(2.0)
    link.run_until(lambda: link.ual.state == UalState.FLYING_AUTO, "UAL take-off")
    assert link.armed() and link.mode() == "OFFBOARD"  # as a UAL over PX4 flies
    assert link.vehicle.external
    assert link.set_mode("AUTO.LOITER") == ACCEPTED
    link.run(0.1)
    assert link.ual.state == UalState.FLYING_MANUAL and not link.vehicle.external
    link.ual.recover_from_manual()  # the UAL takes it back: MAVLink watches again
    link.run(0.1)
    assert link.ual.state == UalState.FLYING_AUTO and link.vehicle.external and link.mode() == "OFFBOARD"
    assert link.result(mavlink.MAV_CMD_NAV_LAND) == ACCEPTED
    assert link.ual.state == UalState.FLYING_MANUAL
    link.run_until(lambda: link.vehicle.on_ground, "touch-down")
    link.run(0.1)
    assert link.ual.state == UalState.LANDED_ARMED
    link.world.close()


def test_a_mavlink_offboard_take_over_is_not_undone_by_the_uals_velocity_timeout():
    link = Link(with_ual=True)
    link.run(0.05)
    link.ual.take_off(2.0)
    link.run_until(lambda: link.ual.state == UalState.FLYING_AUTO, "UAL take-off")
    link.ual.set_velocity([0.5, 0.0, 0.0], 0.0)  # the UAL flies a velocity, then falls silent

    def north():
        link.setpoint(VELOCITY_ONLY | 1024, vx=1.0)

    north()
    assert link.set_mode("OFFBOARD") == ACCEPTED
    assert link.ual.state == UalState.FLYING_MANUAL
    link.run(3.0, every=0.1, each=north)  # past the UAL's 1 s velocity timeout
    assert link.vehicle.mode == "OFFBOARD" and not link.vehicle.external
    assert link.uav.velocity[1] == pytest.approx(1.0, abs=0.05)  # MAVLink's north, not the UAL's hold
    link.world.close()


def test_the_fast_attitude_matches_magna_mavlink_frames():
    """mavlink_telemetry's plain-float attitude against the rotation-matrix conversion of magna_mavlink.frames."""
    from scipy.spatial.transform import Rotation

    from magna_mavlink import frames
    from magna_sim.mavlink_telemetry import _quaternion_zyx, attitude_ned

    for quaternion in Rotation.random(200, random_state=3).as_quat():
        reference = Rotation.from_quat(frames.attitude_enu_flu_to_ned_frd(quaternion))
        yaw, pitch, roll = reference.as_euler("ZYX")
        fast = attitude_ned(*quaternion)
        assert fast == pytest.approx((roll, pitch, yaw), abs=1e-9) or abs(abs(pitch) - math.pi / 2) < 1e-3
        w, x, y, z = _quaternion_zyx(*fast)
        assert abs(np.dot([x, y, z, w], reference.as_quat())) == pytest.approx(1.0, abs=1e-9)  # same rotation
