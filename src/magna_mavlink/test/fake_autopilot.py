"""A scripted autopilot for the link and backend tests: a few PX4 (or ArduPilot Copter) rules over real UDP.

Not a simulator (magna_sim's MAVLink vehicle is that): it moves kinematically toward the set-points
it is sent, so the tests can check what ual_mavlink sends and how it reads what it hears. It sends
to `udpin` ports as PX4 SITL does (everything to one address), and answers whoever writes to it.
Tests switch its behaviour by attribute: stop the HEARTBEAT, have a pilot select a mode, refuse
commands. Time is wall time, in its own thread.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from magna_common import geo
from magna_mavlink import autopilot as ap
from magna_mavlink.link import mavlink, mavutil

ORIGIN = (37.41, -6.0, 10.0)  # lat, lon, alt of the fake's local origin


class FakeAutopilot:
    def __init__(self, url: str, system_id: int = 1, autopilot: str = ap.PX4, rate: float = 50.0):
        """`url`: udpout:127.0.0.1:P sends to a ual_mavlink listening on P (PX4 SITL's way), udpin:127.0.0.1:P
        listens on P and answers whoever writes (a ual_mavlink with udpout:127.0.0.1:P)."""
        self.system_id = system_id
        self.autopilot = autopilot
        self.connection = mavutil.mavlink_connection(url, source_system=system_id, source_component=1)
        self.rate = rate
        self.lock = threading.Lock()
        self.heartbeat = True  # False: silent, as a cut link
        self.heartbeats = True  # False: no HEARTBEAT, telemetry still (as when a lossy radio loses a few)
        self.send_telemetry = True
        self.extended_sys_state = True
        self.answer_commands = True
        self.disarm_when_told_to_climb = False  # once: PX4's pre-flight auto-disarm hitting as a climb begins
        self.mode = "POSCTL" if autopilot == ap.PX4 else "LOITER"
        self.armed = False
        self.position = np.zeros(3)  # NED
        self.velocity = np.zeros(3)
        self.yaw = 0.0  # NED
        self.speed = 2.0  # m/s toward a position set-point
        self.set_points: list[tuple[float, object]] = []  # (wall time, SET_POSITION_TARGET_LOCAL_NED)
        self.commands: list[object] = []  # every COMMAND_LONG
        self.home_commands: list[object] = []
        self.home = ORIGIN  # lat, lon, alt
        self.senders: set[tuple[int, int]] = set()  # (system, component) of what it heard
        self._land_time: float | None = None
        self._takeoff_altitude: float | None = None
        self._stop = threading.Event()
        self._boot = time.monotonic()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def start(self) -> FakeAutopilot:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.connection.close()

    # --- what a test scripts --------------------------------------------------------------------------------------
    def pilot_selects(self, mode: str) -> None:
        with self.lock:
            self.mode = mode

    def last_set_point(self):
        with self.lock:
            return self.set_points[-1][1] if self.set_points else None

    # --- the loop -------------------------------------------------------------------------------------------------
    def _loop(self) -> None:
        period, last_heartbeat = 1.0 / self.rate, -1.0
        while not self._stop.is_set():
            now = time.monotonic()
            while True:
                msg = self.connection.recv_match(blocking=False)
                if msg is None:
                    break
                self._handle(msg, now)
            with self.lock:
                self._step(period, now)
                if self.heartbeat and self.heartbeats and now - last_heartbeat >= 0.2:
                    last_heartbeat = now
                    self._send_heartbeat()
                    self._send_home()
                if self.heartbeat and self.send_telemetry:
                    self._send_telemetry()
            self._stop.wait(period)

    def _handle(self, msg, now: float) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        self.senders.add((msg.get_srcSystem(), msg.get_srcComponent()))
        with self.lock:
            if kind == "SET_POSITION_TARGET_LOCAL_NED" and msg.target_system == self.system_id:
                self.set_points.append((now, msg))
                climbing = not msg.type_mask & 1 and msg.z < self.position[2] - 0.05  # NED: up is -z
                if self.disarm_when_told_to_climb and climbing and self.armed and self.landed_state == 1:
                    self.disarm_when_told_to_climb, self.armed = False, False
            elif kind == "COMMAND_LONG" and msg.target_system == self.system_id:
                self.commands.append(msg)
                if self.answer_commands:
                    result = self._command(msg, now)
                    self.connection.mav.command_ack_send(msg.command, result, 0, 0, msg.get_srcSystem(),
                                                         msg.get_srcComponent())

    def _command(self, msg, now: float) -> int:
        if msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            self.armed = msg.param1 == 1
            return mavlink.MAV_RESULT_ACCEPTED
        if msg.command == mavlink.MAV_CMD_DO_SET_MODE:
            name = self._mode_name(msg)
            if name == ap.SET_POINT_MODE[self.autopilot] and self.autopilot == ap.PX4 and not self._streamed(now):
                return mavlink.MAV_RESULT_TEMPORARILY_REJECTED  # PX4: no OFFBOARD without set-points
            self.mode = name
            return mavlink.MAV_RESULT_ACCEPTED
        if msg.command == mavlink.MAV_CMD_NAV_TAKEOFF and self.autopilot == ap.ARDUPILOT:
            self._takeoff_altitude = msg.param7
            return mavlink.MAV_RESULT_ACCEPTED
        if msg.command == mavlink.MAV_CMD_DO_SET_HOME:
            self.home_commands.append(msg)
            self.home = self._geodetic() if msg.param1 == 1 else (msg.param5, msg.param6, msg.param7)
            return mavlink.MAV_RESULT_ACCEPTED
        if msg.command in (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_CMD_REQUEST_MESSAGE):
            return mavlink.MAV_RESULT_ACCEPTED
        return mavlink.MAV_RESULT_UNSUPPORTED

    def _mode_name(self, msg) -> str:
        if self.autopilot == ap.PX4:
            custom = (int(msg.param2) << 16) | (int(msg.param3) << 24)
            return ap.decode_mode(ap.MAV_AUTOPILOT_PX4, 1, custom).name
        return ap.decode_mode(ap.MAV_AUTOPILOT_ARDUPILOTMEGA, 1, int(msg.param2)).name

    def _streamed(self, now: float) -> bool:
        return bool(self.set_points) and now - self.set_points[-1][0] < 0.5

    def _step(self, dt: float, now: float) -> None:
        flying = self.armed and self.position[2] < -0.05
        target_velocity = np.zeros(3)
        if self.armed and self.mode == ap.SET_POINT_MODE[self.autopilot] and self.set_points:
            target = self.set_points[-1][1]
            if target.type_mask & 1:  # position ignored: a velocity set-point
                target_velocity = np.array([target.vx, target.vy, target.vz])
            else:
                error = np.array([target.x, target.y, target.z]) - self.position
                distance = float(np.linalg.norm(error))
                if distance > 1e-6:
                    target_velocity = error / distance * min(self.speed, distance / dt)
                if not target.type_mask & 1024:
                    self.yaw = target.yaw
            if self._takeoff_altitude is not None:  # ArduPilot climbing on its own
                target_velocity = np.array([0.0, 0.0, -1.0])
                if -self.position[2] >= self._takeoff_altitude:
                    self._takeoff_altitude = None
        elif self.mode in ("AUTO.LAND", "LAND") and self.armed:
            target_velocity = np.array([0.0, 0.0, 1.0])
        self.velocity = target_velocity if (flying or target_velocity[2] < 0) else np.zeros(3)
        self.position = self.position + self.velocity * dt
        if self.position[2] >= 0.0:
            self.position[2] = 0.0
            if self.mode in ("AUTO.LAND", "LAND") and self.armed:
                self._land_time = self._land_time or now
                if now - self._land_time > 0.3:
                    self.armed, self._land_time = False, None  # PX4's auto-disarm after landing

    @property
    def landed_state(self) -> int:
        return 1 if self.position[2] >= -0.05 else 2  # ON_GROUND, IN_AIR

    def _send_heartbeat(self) -> None:
        if self.autopilot == ap.PX4:
            base, custom = ap.encode_mode(ap.PX4, self.mode)
            number = ap.MAV_AUTOPILOT_PX4
        else:
            base, custom = ap.encode_mode(ap.ARDUPILOT, self.mode)
            number = ap.MAV_AUTOPILOT_ARDUPILOTMEGA
        base |= ap.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0
        self.connection.mav.heartbeat_send(mavlink.MAV_TYPE_QUADROTOR, number, base, custom,
                                           mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY)

    def _geodetic(self) -> tuple[float, float, float]:
        return geo.enu_to_geodetic([self.position[1], self.position[0], -self.position[2]], ORIGIN)

    def _send_home(self) -> None:
        lat, lon, alt = self.home
        north, east, up = geo.geodetic_to_enu(lat, lon, alt, ORIGIN)[[1, 0, 2]]
        self.connection.mav.home_position_send(round(lat * 1e7), round(lon * 1e7), round(alt * 1000), north, east,
                                               -up, [1, 0, 0, 0], 0, 0, 0)

    def _send_telemetry(self) -> None:
        mav, ms = self.connection.mav, int((time.monotonic() - self._boot) * 1000)
        mav.local_position_ned_send(ms, *self.position, *self.velocity)
        mav.attitude_send(ms, 0.0, 0.0, self.yaw, 0.0, 0.0, 0.0)
        lat, lon, alt = self._geodetic()
        mav.global_position_int_send(ms, round(lat * 1e7), round(lon * 1e7), round(alt * 1000),
                                     round(-self.position[2] * 1000), 0, 0, 0, 0)
        if self.extended_sys_state:
            mav.extended_sys_state_send(0, self.landed_state)
        mav.sys_status_send(0, 0, 0, 0, 12000, -1, 80, 0, 0, 0, 0, 0, 0)
