"""What magna_sim's PX4-like vehicle tells the world: telemetry messages and their rates.

`Telemetry` turns the simulated UAV (map frame: ENU world, FLU body) into MAVLink messages (NED world,
FRD body, WGS84 through the map origin) as a PX4 autopilot sends them. `Streams` holds each
stream's interval in simulated seconds, changed by MAV_CMD_SET_MESSAGE_INTERVAL, and says which
are due at a given simulated time.

The local NED frame is the map frame turned into NED: its origin is the map origin, which is also
the GPS origin (`origin_geo`). No geoid is modelled: AMSL altitudes are heights above the
WGS84 ellipsoid.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from magna_common import geo
from magna_mavlink import autopilot, frames

from .vehicle import Vehicle

PX4_SITL_HOME = (47.397742, 8.545594, 488.0)  # PX4 SITL's default home: lat, lon (deg), alt (m)

# Default intervals (simulated s), close to what PX4 streams on its offboard (onboard) link.
DEFAULT_INTERVALS = {
    mavlink.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    mavlink.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: 2.0,
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 1.0 / 30.0,
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 1.0 / 10.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE: 1.0 / 20.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 1.0 / 10.0,
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
    mavlink.MAVLINK_MSG_ID_VFR_HUD: 1.0 / 4.0,
    mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: 2.0,
}

# The sensors and controllers SYS_STATUS reports; MAVSDK's health_all_ok needs the gyro, accelerometer,
# magnetometer and GPS present and healthy (local and global position follow from the GPS).
SENSORS = (mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
           | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
           | mavlink.MAV_SYS_STATUS_SENSOR_GPS | mavlink.MAV_SYS_STATUS_AHRS | mavlink.MAV_SYS_STATUS_PREARM_CHECK)
CONTROLLERS = (mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
               | mavlink.MAV_SYS_STATUS_SENSOR_YAW_POSITION | mavlink.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
               | mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS)

CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
                | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2)
FLIGHT_SW_VERSION = (0 << 24) | (1 << 16) | (0 << 8) | 0  # magna_sim 0.1.0 (development): not a PX4 release
CUSTOM_VERSION = list(b"magnasim")  # AUTOPILOT_VERSION.flight_custom_version: who is really answering

UINT16_MAX = 65535


@dataclass
class VehicleStatus:
    """What the state machine knows that the physics does not."""

    armed: bool
    mode: str  # PX4 mode name, e.g. "AUTO.LOITER" or "OFFBOARD"
    landed_state: int  # MAV_LANDED_STATE_*
    home: np.ndarray  # map frame (ENU), m
    battery: tuple[float, float] | None  # (volts, remaining fraction 0..1), or None when not simulated


class Streams:
    """Which telemetry stream is due when, in simulated time."""

    def __init__(self, now: float, battery: bool = True):
        self.intervals: dict[int, float | None] = dict(DEFAULT_INTERVALS)
        if not battery:
            self.intervals[mavlink.MAVLINK_MSG_ID_BATTERY_STATUS] = None
        self._next = {msg_id: now for msg_id in self.intervals}
        self._earliest = now

    def known(self, msg_id: int) -> bool:
        return msg_id in self.intervals

    def set_interval(self, msg_id: int, interval_us: float, now: float) -> None:
        """As MAV_CMD_SET_MESSAGE_INTERVAL: -1 stops the stream, 0 restores its default, else microseconds."""
        if interval_us < 0:
            self.intervals[msg_id] = None
        elif interval_us == 0:
            self.intervals[msg_id] = DEFAULT_INTERVALS[msg_id]
        else:
            self.intervals[msg_id] = interval_us / 1e6
        self._next[msg_id] = now
        self._earliest = min(self._earliest, now)

    def interval_us(self, msg_id: int) -> int:
        """As MESSAGE_INTERVAL.interval_us: -1 when stopped, 0 when unknown."""
        if msg_id not in self.intervals:
            return 0
        interval = self.intervals[msg_id]
        return -1 if interval is None else int(round(interval * 1e6))

    def due(self, now: float) -> list[int]:
        if now + 1e-9 < self._earliest:
            return []  # the common case, every physics step: nothing to send
        due = []
        for msg_id, interval in self.intervals.items():
            if interval is None or now + 1e-9 < self._next[msg_id]:
                continue
            due.append(msg_id)
            self._next[msg_id] = max(self._next[msg_id] + interval, now)
        active = [self._next[m] for m, i in self.intervals.items() if i is not None]
        self._earliest = min(active) if active else math.inf
        return due


class Telemetry:
    """Builds the telemetry messages of one simulated UAV."""

    def __init__(self, vehicle: Vehicle, system_id: int, origin_geo=PX4_SITL_HOME, boot_time: float = 0.0):
        self.vehicle = vehicle
        self.system_id = system_id
        self.origin_geo = tuple(float(v) for v in origin_geo)
        self.boot_time = boot_time
        self._builders = self._message_builders()

    # --- geometry ---------------------------------------------------------------------------------------------
    def geodetic(self, position_enu) -> tuple[float, float, float]:
        return geo.enu_to_geodetic(position_enu, self.origin_geo)

    def enu_of(self, lat: float, lon: float, alt: float) -> np.ndarray:
        return geo.geodetic_to_enu(lat, lon, alt, self.origin_geo)

    def time_boot_ms(self, now: float) -> int:
        return int((now - self.boot_time) * 1000.0) & 0xFFFFFFFF

    def _attitude_ned(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) of the FRD body in NED; see attitude_ned."""
        return attitude_ned(*(float(c) for c in self.vehicle.orientation))

    def _body_rates(self) -> tuple[float, float, float]:
        """Angular velocity (the sim keeps it in the map frame) in the FRD body frame."""
        p, q, r = _into_body(self.vehicle.orientation, self.vehicle.angular_velocity)
        return p, -q, -r  # FLU -> FRD

    # --- messages ---------------------------------------------------------------------------------------------
    def message(self, msg_id: int, now: float, status: VehicleStatus):
        """The message `msg_id` now, or None when there is nothing to say (no battery simulated)."""
        build = self._builders.get(msg_id)
        return None if build is None else build(now, status)

    def _message_builders(self):
        return {mavlink.MAVLINK_MSG_ID_HEARTBEAT: lambda now, s: self.heartbeat(s),
                mavlink.MAVLINK_MSG_ID_SYS_STATUS: lambda now, s: self.sys_status(s),
                mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: lambda now, s: self.extended_sys_state(s),
                mavlink.MAVLINK_MSG_ID_HOME_POSITION: self.home_position,
                mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self.local_position_ned,
                mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self.global_position_int,
                mavlink.MAVLINK_MSG_ID_ATTITUDE: self.attitude,
                mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: self.attitude_quaternion,
                mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: self.gps_raw_int,
                mavlink.MAVLINK_MSG_ID_VFR_HUD: self.vfr_hud,
                mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: self.battery_status,
                mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: self.gps_global_origin,
                mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION: lambda now, s: self.autopilot_version()}

    def can_send(self, msg_id: int) -> bool:
        """Whether MAV_CMD_REQUEST_MESSAGE can be answered for `msg_id`."""
        return msg_id in self._builders

    def heartbeat(self, status: VehicleStatus):
        _, custom_mode = autopilot.encode_mode(autopilot.PX4, status.mode)
        base_mode = (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
                     | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED)
        if status.mode.startswith("AUTO.") or status.mode == "OFFBOARD":
            base_mode |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED
        if status.armed:
            base_mode |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        state = mavlink.MAV_STATE_ACTIVE if status.armed else mavlink.MAV_STATE_STANDBY
        return mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, base_mode,
                                                 custom_mode, state, 3)

    def sys_status(self, status: VehicleStatus):
        present = SENSORS | CONTROLLERS
        enabled = SENSORS | (CONTROLLERS if status.armed else 0)
        volts, remaining = UINT16_MAX, -1  # unknown, as MAVLink spells it
        if status.battery is not None:
            present |= mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
            enabled |= mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
            volts = min(int(status.battery[0] * 1000.0), UINT16_MAX - 1)
            remaining = int(round(status.battery[1] * 100.0))
        return mavlink.MAVLink_sys_status_message(present, enabled, present, 0, volts, -1, remaining,
                                                  0, 0, 0, 0, 0, 0, 0, 0, 0)

    def extended_sys_state(self, status: VehicleStatus):
        return mavlink.MAVLink_extended_sys_state_message(mavlink.MAV_VTOL_STATE_UNDEFINED, status.landed_state)

    def home_position(self, now: float, status: VehicleStatus):
        lat, lon, alt = self.geodetic(status.home)
        north, east, down = frames.enu_to_ned(status.home)
        return mavlink.MAVLink_home_position_message(int(round(lat * 1e7)), int(round(lon * 1e7)),
                                                     int(round(alt * 1000.0)), north, east, down, [1.0, 0.0, 0.0, 0.0],
                                                     0.0, 0.0, 0.0, int(now * 1e6))

    def local_position_ned(self, now: float, status: VehicleStatus):
        x, y, z = frames.enu_to_ned(self.vehicle.position)
        vx, vy, vz = frames.enu_to_ned(self.vehicle.velocity)
        return mavlink.MAVLink_local_position_ned_message(self.time_boot_ms(now), x, y, z, vx, vy, vz)

    def global_position_int(self, now: float, status: VehicleStatus):
        lat, lon, alt = self.geodetic(self.vehicle.position)
        home_alt = self.geodetic(status.home)[2]
        vx, vy, vz = frames.enu_to_ned(self.vehicle.velocity)
        heading = math.degrees(frames.yaw_enu_to_ned(self.vehicle.yaw)) % 360.0
        return mavlink.MAVLink_global_position_int_message(
            self.time_boot_ms(now), int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000.0)),
            int(round((alt - home_alt) * 1000.0)), _int16(vx * 100.0), _int16(vy * 100.0), _int16(vz * 100.0),
            int(round(heading * 100.0)) % 36000)

    def attitude(self, now: float, status: VehicleStatus):
        roll, pitch, yaw = self._attitude_ned()
        p, q, r = self._body_rates()
        return mavlink.MAVLink_attitude_message(self.time_boot_ms(now), roll, pitch, yaw, p, q, r)

    def attitude_quaternion(self, now: float, status: VehicleStatus):
        w, x, y, z = _quaternion_zyx(*self._attitude_ned())
        p, q, r = self._body_rates()
        return mavlink.MAVLink_attitude_quaternion_message(self.time_boot_ms(now), w, x, y, z, p, q, r,
                                                           [0.0, 0.0, 0.0, 0.0])

    def gps_raw_int(self, now: float, status: VehicleStatus):
        lat, lon, alt = self.geodetic(self.vehicle.position)
        vx, vy, _ = frames.enu_to_ned(self.vehicle.velocity)
        speed = math.hypot(vx, vy)
        course = int(round(math.degrees(math.atan2(vy, vx)) % 360.0 * 100.0)) % 36000 if speed > 0.1 else UINT16_MAX
        altitude_mm = int(round(alt * 1000.0))
        return mavlink.MAVLink_gps_raw_int_message(int(now * 1e6), mavlink.GPS_FIX_TYPE_3D_FIX, int(round(lat * 1e7)),
                                                   int(round(lon * 1e7)), altitude_mm, 70, 100,
                                                   min(int(speed * 100.0), UINT16_MAX - 1), course, 12, altitude_mm,
                                                   300, 500, 100, 0, 0)

    def vfr_hud(self, now: float, status: VehicleStatus):
        speed = float(np.linalg.norm(self.vehicle.velocity[:2]))
        heading = int(math.degrees(frames.yaw_enu_to_ned(self.vehicle.yaw)) % 360.0)
        altitude = self.geodetic(self.vehicle.position)[2]
        throttle = 50 if status.armed and status.landed_state != mavlink.MAV_LANDED_STATE_ON_GROUND else 0
        climb = float(self.vehicle.velocity[2])
        return mavlink.MAVLink_vfr_hud_message(speed, speed, heading, throttle, altitude, climb)

    def battery_status(self, now: float, status: VehicleStatus):
        if status.battery is None:
            return None
        volts, remaining = status.battery
        voltages = [min(int(volts * 1000.0), UINT16_MAX - 1)] + [UINT16_MAX] * 9
        return mavlink.MAVLink_battery_status_message(
            0, mavlink.MAV_BATTERY_FUNCTION_ALL, mavlink.MAV_BATTERY_TYPE_LIPO, 32767, voltages, -1, -1, -1,
            int(round(remaining * 100.0)), 0, mavlink.MAV_BATTERY_CHARGE_STATE_OK, [0, 0, 0, 0], 0, 0)

    def gps_global_origin(self, now: float, status: VehicleStatus):
        lat, lon, alt = self.origin_geo
        return mavlink.MAVLink_gps_global_origin_message(int(round(lat * 1e7)), int(round(lon * 1e7)),
                                                         int(round(alt * 1000.0)), int(now * 1e6))

    def autopilot_version(self):
        return mavlink.MAVLink_autopilot_version_message(CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, CUSTOM_VERSION,
                                                         [0] * 8, [0] * 8, 0, 0, self.system_id, [0] * 18)

    def statustext(self, severity: int, text: str):
        return mavlink.MAVLink_statustext_message(severity, text[:50].encode(), 0, 0)


def attitude_ned(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """The (roll, pitch, yaw) Euler angles (ZYX) of the FRD body in NED, from the FLU body's quaternion in ENU.

    Between the two conventions roll is the same, pitch changes sign and yaw = pi/2 - yaw (as MAVROS
    converts). Plain floats: magna_mavlink.frames.attitude_enu_flu_to_ned_frd gives the same through
    rotation matrices (the tests compare them), at many times the cost, 20 times a second per UAV.
    """
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, -pitch, frames.wrap_angle(math.pi / 2.0 - yaw)


def _quaternion_zyx(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """(w, x, y, z) of ZYX Euler angles."""
    cr, sr = math.cos(roll / 2.0), math.sin(roll / 2.0)
    cp, sp = math.cos(pitch / 2.0), math.sin(pitch / 2.0)
    cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy)


def _into_body(orientation_xyzw, vector) -> tuple[float, float, float]:
    """A world vector in the body frame (R^T v) of the quaternion x, y, z, w, in plain floats."""
    x, y, z, w = (float(c) for c in orientation_xyzw)
    vx, vy, vz = (float(c) for c in vector)
    # R^T v = v + 2 q' x (q' x v + w v) with q' = -(x, y, z)
    tx, ty, tz = -y * vz + z * vy + w * vx, -z * vx + x * vz + w * vy, -x * vy + y * vx + w * vz
    return vx + 2.0 * (-y * tz + z * ty), vy + 2.0 * (-z * tx + x * tz), vz + 2.0 * (-x * ty + y * tx)


def _int16(value: float) -> int:
    return max(-32768, min(32767, int(round(value))))
