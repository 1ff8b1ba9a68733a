"""magna_sim's PX4-like MAVLink vehicle: the protocol and the flight-mode machine over a simulated UAV.

PX4-like, not PX4: it speaks what MAVSDK, pymavlink and ground stations use to fly a multirotor, with
PX4's mode encoding and OFFBOARD rules, over magna_sim's physics. No sockets here and no wall clock:
`handle(msg, now)` takes one incoming pymavlink message and `tick(now)` runs after each physics step;
both return the messages to send, and `now` is simulated time.

Modes (PX4's names): AUTO.LOITER (hold a position; also POSCTL and ALTCTL, as with centred sticks),
AUTO.TAKEOFF (climb to MIS_TAKEOFF_ALT above home, then AUTO.LOITER), AUTO.LAND (descend; on the
ground it disarms after COM_DISARM_LAND s) and OFFBOARD (follow SET_POSITION_TARGET_* set-points).
OFFBOARD rules as PX4's: it is refused unless set-points arrived within the last 0.5 s, and when they
stop for longer than COM_OF_LOSS_T the vehicle leaves OFFBOARD and holds where it is (AUTO.LOITER).
Every mode or arming change sends a HEARTBEAT at once, besides the 1 Hz stream.

Shared with the UAL server (interface "ual+mavlink"): when another API (magna_sim's UAL) commands
the UAV, this side reports it armed, in OFFBOARD while it flies (as a UAL over PX4 would fly), and
applies none of its own failsafes; a MAVLink command takes control back, and the UAL then sees
FLYING_MANUAL (a pilot's take-over) until the MAVLink side has landed the UAV.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from magna_mavlink import autopilot, frames

from .guidance import POSITION_GAIN, YAW_GAIN, airframe_limits
from .mavlink_params import ParamError, ParamTable, default_params, encode
from .mavlink_telemetry import PX4_SITL_HOME, Streams, Telemetry, VehicleStatus
from .ual_logic import UalLogic, UalState
from .vehicle import Manoeuvre, Setpoint, SetpointMode, Vehicle

COMPONENT_ID = mavlink.MAV_COMP_ID_AUTOPILOT1
FORCE = 21196  # param2 of COMPONENT_ARM_DISARM that forces a disarm in the air (PX4's magic number)
OFFBOARD_FRESH = 0.5  # s: OFFBOARD starts only if a set-point arrived this recently
LANDED_HEIGHT = 0.05  # m above the ground that counts as touched down (as ual_logic)
LIFTOFF_HEIGHT = 0.1  # m above the ground that counts as airborne
STALL_TIME = 1.0  # s a landing may stand still above the ground (on an obstacle) before it counts as landed
TAKEOFF_ACCEPTANCE = 0.15  # m below the take-off altitude that completes a take-off
INT32_MAX = 2**31 - 1

HOLD_MODES = ("AUTO.LOITER", "POSCTL", "ALTCTL")
ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND

# SET_POSITION_TARGET_* type_mask bits
IGNORE_POSITION = (1, 2, 4)
IGNORE_VELOCITY = (8, 16, 32)
IGNORE_YAW, IGNORE_YAW_RATE = 1024, 2048

ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
REJECTED = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
DENIED = mavlink.MAV_RESULT_DENIED
UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED

GLOBAL_AMSL_FRAMES = (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT)
GLOBAL_RELATIVE_FRAMES = (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)


@dataclass
class Command:
    """A COMMAND_LONG or COMMAND_INT, with COMMAND_INT's x, y, z as param5-7 (degrees for global frames)."""

    command: int
    params: tuple[float, float, float, float, float, float, float]
    frame: int  # COMMAND_INT's frame; COMMAND_LONG: MAV_FRAME_GLOBAL (PX4 reads its positions as AMSL)

    def param(self, n: int) -> float:
        return float(self.params[n - 1])


@dataclass
class OffboardTarget:
    """The latest set-point, in the map frame (ENU); NaN marks an axis it does not command."""

    position: np.ndarray
    velocity: np.ndarray
    yaw: float  # ENU heading to hold (the heading at arrival when the set-point gives none)
    yaw_rate: float | None  # ENU (anticlockwise) rad/s; None: steer to `yaw`

    @property
    def is_position(self) -> bool:
        return not np.isnan(self.position).any()


class MavlinkVehicle:
    def __init__(self, vehicle: Vehicle, system_id: int, origin_geo=PX4_SITL_HOME, now: float = 0.0,
                 ual: UalLogic | None = None, battery: Callable[[], tuple[float, float]] | None = None):
        """`ual`: the UAL state machine of the same UAV, when a UAL server shares it; `battery`: a callable
        giving (volts, remaining fraction) for SYS_STATUS and BATTERY_STATUS."""
        if vehicle.airframe.is_fixed_wing:
            raise ValueError(f"{vehicle.name}: the MAVLink vehicle is a multirotor (PX4 QUADROTOR); "
                             f"'{vehicle.airframe.source}' is a fixed wing")
        self.vehicle = vehicle
        self.system_id = system_id
        self.ual = ual
        self.telemetry = Telemetry(vehicle, system_id, origin_geo, boot_time=now)
        limits = airframe_limits(vehicle.airframe)
        self.params = ParamTable(default_params(system_id, limits.max_horizontal_speed, limits.max_vertical_speed))
        self.streams = Streams(now, battery=battery is not None)
        self._battery = battery
        self.armed = False
        self.mode = "AUTO.LOITER"
        self.on_ground = True
        self.external = False  # another API (the UAL) commands the UAV
        self.home = vehicle.position.copy()
        self._now = now
        self._own: Setpoint = vehicle.setpoint  # the setpoint this side wrote last
        self._target: OffboardTarget | None = None
        self._last_setpoint = -math.inf  # sim time the latest set-point arrived
        self._takeoff_z = 0.0
        self._ground_since = now
        self._still_since: float | None = None
        self._flown = False  # left the ground since arming (COM_DISARM_LAND rather than COM_DISARM_PRFLT)
        self._outbox: list = []
        self._commands = {
            mavlink.MAV_CMD_COMPONENT_ARM_DISARM: self._arm_disarm,
            mavlink.MAV_CMD_NAV_TAKEOFF: self._takeoff,
            mavlink.MAV_CMD_NAV_LAND: self._land,
            mavlink.MAV_CMD_DO_SET_MODE: self._do_set_mode,
            mavlink.MAV_CMD_DO_REPOSITION: self._reposition,
            mavlink.MAV_CMD_DO_SET_HOME: self._set_home,
            mavlink.MAV_CMD_REQUEST_MESSAGE: self._request_message,
            mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._request_capabilities,
            mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: self._set_message_interval,
            mavlink.MAV_CMD_GET_MESSAGE_INTERVAL: self._get_message_interval,
        }
        self._handlers = {
            "COMMAND_LONG": self._on_command_long,
            "COMMAND_INT": self._on_command_int,
            "SET_POSITION_TARGET_LOCAL_NED": self._on_set_position_target_local_ned,
            "SET_POSITION_TARGET_GLOBAL_INT": self._on_set_position_target_global_int,
            "PARAM_REQUEST_LIST": self._on_param_request_list,
            "PARAM_REQUEST_READ": self._on_param_request_read,
            "PARAM_SET": self._on_param_set,
            "MISSION_REQUEST_LIST": self._on_mission_request_list,
            "MISSION_COUNT": self._on_mission_count,
            "MISSION_CLEAR_ALL": self._on_mission_clear_all,
            "PING": self._on_ping,
        }

    # --- the two entry points ---------------------------------------------------------------------------------
    def handle(self, msg, now: float) -> list:
        """React to one incoming message; returns the answers (COMMAND_ACK, PARAM_VALUE, ...)."""
        self._now = now
        handler = self._handlers.get(msg.get_type())
        if handler is not None:
            handler(msg)
        return self._flush()

    def tick(self, now: float) -> list:
        """After a physics step: fly the current mode, apply the failsafes, send the telemetry that is due."""
        self._now = now
        if self.vehicle.setpoint is not self._own:
            self._someone_else_commands()
        self._watch_the_ground(now)
        if not self.external:
            self._fly(now)
            self._auto_disarm(now)
            self._tell_the_ual()
        due = self.streams.due(now)
        if due:
            status = self.status()
            for msg_id in due:
                message = self.telemetry.message(msg_id, now, status)
                if message is not None:
                    self._outbox.append(message)
        return self._flush()

    @property
    def offboard_set_point_time(self) -> float | None:
        """Simulated time of the latest set-point while this side flies OFFBOARD, else None. The node keeps
        the simulation from running far ahead of such a stream (as of a UAV manager flying a role)."""
        return self._last_setpoint if self.mode == "OFFBOARD" and self.armed and not self.external else None

    def heartbeat(self):
        """A HEARTBEAT now (the node sends one per wall second while the simulation is paused)."""
        return self.telemetry.heartbeat(self.status())

    def status(self) -> VehicleStatus:
        if self.on_ground:
            landed = ON_GROUND
        elif self.mode == "AUTO.TAKEOFF":
            landed = mavlink.MAV_LANDED_STATE_TAKEOFF
        elif self.mode == "AUTO.LAND":
            landed = mavlink.MAV_LANDED_STATE_LANDING
        else:
            landed = mavlink.MAV_LANDED_STATE_IN_AIR
        return VehicleStatus(self.armed, self.mode, landed, self.home,
                             None if self._battery is None else self._battery())

    # --- flying -----------------------------------------------------------------------------------------------
    def _fly(self, now: float) -> None:
        if not self.armed:
            self._write_off()
            return
        if self.mode == "OFFBOARD":
            target = self._target  # None: no set-point ever came, so none came lately either
            if target is None or now - self._last_setpoint > self.params["COM_OF_LOSS_T"]:
                self._say(mavlink.MAV_SEVERITY_CRITICAL, f"Offboard set-points lost for "
                                                         f"{self.params['COM_OF_LOSS_T']:g} s: holding")
                self._hold_here()
            else:
                self._follow_target(target)
                return
        if self.mode == "AUTO.TAKEOFF" and self.vehicle.position[2] >= self._takeoff_z - TAKEOFF_ACCEPTANCE:
            position = self.vehicle.position.copy()
            position[2] = self._takeoff_z
            self._hold_at(position, self.vehicle.setpoint.yaw)
            return
        if self.on_ground and self.mode != "AUTO.TAKEOFF":
            self._write_off()  # idle on the ground until told to climb

    def _follow_target(self, target: OffboardTarget) -> None:
        """OFFBOARD: track the latest set-point. Axes without a position follow their velocity (0 when unset)."""
        setpoint = self._own
        if target.is_position:
            return  # a POSITION setpoint, written when the set-point arrived
        vehicle = self.vehicle
        velocity = np.where(np.isnan(target.velocity), 0.0, target.velocity)
        has_position = ~np.isnan(target.position)
        if has_position.any():
            velocity = np.where(has_position, velocity + POSITION_GAIN * (target.position - vehicle.position),
                                velocity)
        setpoint.velocity = velocity
        if target.yaw_rate is not None:
            setpoint.yaw_rate = target.yaw_rate
        else:
            setpoint.yaw_rate = YAW_GAIN * frames.wrap_angle(target.yaw - vehicle.yaw)

    def _watch_the_ground(self, now: float) -> None:
        """PX4's land detector, simplified: low, not sinking and not told to climb; or a landing that stalls."""
        vehicle = self.vehicle
        z, vz = float(vehicle.position[2]), float(vehicle.velocity[2])
        if self.on_ground:
            if z > LIFTOFF_HEIGHT:
                self.on_ground = False
                self._flown = self._flown or self.armed
                self._say(mavlink.MAV_SEVERITY_INFO, "Takeoff detected")
            return
        landed = z < LANDED_HEIGHT and abs(vz) < 0.2 and not self._told_to_climb()
        if self.mode == "AUTO.LAND" and not landed:
            if float(np.linalg.norm(vehicle.velocity)) < 0.05:  # standing on something above the ground
                self._still_since = now if self._still_since is None else self._still_since
                landed = now - self._still_since >= STALL_TIME
            else:
                self._still_since = None
        if landed:
            self.on_ground, self._ground_since, self._still_since = True, now, None
            self._say(mavlink.MAV_SEVERITY_INFO, "Landing detected")

    def _told_to_climb(self) -> bool:
        setpoint, z = self.vehicle.setpoint, float(self.vehicle.position[2])
        if setpoint.mode == SetpointMode.POSITION:
            return float(setpoint.position[2]) > z + 0.05
        return setpoint.mode == SetpointMode.VELOCITY and float(setpoint.velocity[2]) > 0.05

    def _auto_disarm(self, now: float) -> None:
        if not (self.armed and self.on_ground):
            return
        name = "COM_DISARM_LAND" if self._flown else "COM_DISARM_PRFLT"
        delay = self.params[name]
        if delay > 0 and now - self._ground_since >= delay:
            self._disarm(f"Disarmed: on the ground for {delay:g} s ({name})")

    def _tell_the_ual(self) -> None:
        """A UAV flown through MAVLink is, for the UAL sharing it, flown by a pilot."""
        ual = self.ual
        if ual is None:
            return
        if self.armed and not self.on_ground and ual.state != UalState.FLYING_MANUAL:
            ual.state = UalState.FLYING_MANUAL
        elif self.on_ground and ual.state == UalState.FLYING_MANUAL:
            ual.state = UalState.LANDED_ARMED

    def _someone_else_commands(self) -> None:
        """The UAL (or any other API) replaced the setpoint: report what it does, leave it alone."""
        self._own = self.vehicle.setpoint
        self.external = True
        self._set_armed(True)
        self._set_mode("OFFBOARD" if self.vehicle.motors_on else "AUTO.LOITER")

    def _take_control(self) -> None:
        """A MAVLink command that flies the UAV ends another API's control."""
        if self.external:
            self.external = False
            self._flown = not self.on_ground
            self._ground_since = self._now
        if self.ual is not None and self.ual.state in (UalState.TAKING_OFF, UalState.FLYING_AUTO, UalState.LANDING):
            self.ual.state = UalState.FLYING_MANUAL  # at once: the UAL's own rules must not undo this command

    # --- mode changes -----------------------------------------------------------------------------------------
    def _write(self, setpoint: Setpoint) -> None:
        self.vehicle.setpoint = self._own = setpoint

    def _write_off(self) -> None:
        if self._own.mode != SetpointMode.OFF or self.vehicle.setpoint is not self._own:
            self._write(Setpoint(SetpointMode.OFF))

    def _set_mode(self, mode: str) -> None:
        if mode != self.mode:
            self.mode = mode
            self._outbox.append(self.heartbeat())

    def _set_armed(self, armed: bool) -> None:
        if armed != self.armed:
            self.armed = armed
            self._outbox.append(self.heartbeat())

    def _hold_at(self, position, yaw: float, mode: str = "AUTO.LOITER") -> None:
        if not self.on_ground or position[2] > self.vehicle.position[2] + 0.05:
            self._write(Setpoint(SetpointMode.POSITION, position=np.array(position, dtype=float), yaw=yaw))
        self._set_mode(mode)

    def _hold_here(self, mode: str = "AUTO.LOITER") -> None:
        self._hold_at(self.vehicle.position.copy(), self.vehicle.yaw, mode)

    def _start_takeoff(self, target_z: float, yaw: float) -> None:
        self._takeoff_z = target_z
        position = self.vehicle.position.copy()
        position[2] = target_z
        self._write(Setpoint(SetpointMode.POSITION, position=position, yaw=yaw,
                             max_vertical_speed=self.params["MPC_TKO_SPEED"], manoeuvre=Manoeuvre.TAKE_OFF))
        self._set_mode("AUTO.TAKEOFF")

    def _start_landing(self) -> None:
        # Aim below the floor so the descent never stalls just above it (as ual_logic); touching down ends it.
        position = self.vehicle.position.copy()
        position[2] = -1.0
        if not self.on_ground:
            self._write(Setpoint(SetpointMode.POSITION, position=position, yaw=self.vehicle.yaw,
                                 max_vertical_speed=self.params["MPC_LAND_SPEED"], manoeuvre=Manoeuvre.LAND))
        self._still_since = None
        self._set_mode("AUTO.LAND")

    def _start_offboard(self, target: OffboardTarget) -> None:
        self._set_mode("OFFBOARD")
        self._apply_target(target)

    def _apply_target(self, target: OffboardTarget) -> None:
        """Write the setpoint for the latest OFFBOARD set-point (velocity ones are refreshed every tick)."""
        if not self.armed:
            return
        if target.is_position:
            self._write(Setpoint(SetpointMode.POSITION, position=target.position.copy(), yaw=target.yaw))
        else:
            if self._own.mode != SetpointMode.VELOCITY or self.vehicle.setpoint is not self._own:
                self._write(Setpoint(SetpointMode.VELOCITY))
            self._follow_target(target)

    def _arm(self) -> int:
        if self.armed:
            return ACCEPTED
        if not self.on_ground:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Arming denied: not on the ground")
            return REJECTED
        self._flown = False
        self._ground_since = self._now
        self.home = self.vehicle.position.copy()  # PX4 sets home where it arms
        self._set_armed(True)
        if self.mode in ("AUTO.LAND", "AUTO.TAKEOFF"):  # a finished landing or take-off: wait for orders
            self._set_mode("AUTO.LOITER")
        if self.mode == "OFFBOARD" and self._target is not None:
            self._apply_target(self._target)
        self._outbox.append(self.telemetry.home_position(self._now, self.status()))
        self._say(mavlink.MAV_SEVERITY_INFO, "Armed by external command")
        return ACCEPTED

    def _disarm(self, reason: str) -> None:
        self._set_armed(False)
        self._write_off()
        self._say(mavlink.MAV_SEVERITY_INFO, reason)

    # --- commands ---------------------------------------------------------------------------------------------
    def _on_command_long(self, msg) -> None:
        if not self._for_me(msg.target_system, msg.target_component):
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        self._run(Command(msg.command, params, mavlink.MAV_FRAME_GLOBAL), msg)

    def _on_command_int(self, msg) -> None:
        if not self._for_me(msg.target_system, msg.target_component):
            return
        scale = 1e-7 if msg.frame in GLOBAL_AMSL_FRAMES + GLOBAL_RELATIVE_FRAMES else 1.0
        x = math.nan if msg.x == INT32_MAX else msg.x * scale
        y = math.nan if msg.y == INT32_MAX else msg.y * scale
        params = (msg.param1, msg.param2, msg.param3, msg.param4, x, y, msg.z)
        self._run(Command(msg.command, params, msg.frame), msg)

    def _run(self, command: Command, msg) -> None:
        handler = self._commands.get(command.command)
        followers = len(self._outbox)
        result = UNSUPPORTED if handler is None else handler(command)
        # The answer goes first: a message a command asked for follows its COMMAND_ACK.
        self._outbox.insert(followers, mavlink.MAVLink_command_ack_message(
            command.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))

    def _arm_disarm(self, command: Command) -> int:
        if command.param(1) >= 0.5:
            self._take_control()
            return self._arm()
        if not self.armed:
            return ACCEPTED
        if not self.on_ground and command.param(2) != FORCE:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Disarming denied: not landed")
            return DENIED
        self.external = False
        self._disarm("Disarmed by external command")
        return ACCEPTED

    def _takeoff(self, command: Command) -> int:
        if not self.armed:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Takeoff denied: disarmed")
            return REJECTED
        self._take_control()
        target_z = self.home[2] + self.params["MIS_TAKEOFF_ALT"]
        altitude = command.param(7)  # AMSL; NaN (or below the vehicle) keeps MIS_TAKEOFF_ALT
        if math.isfinite(altitude):
            lat, lon, _ = self.telemetry.geodetic(self.vehicle.position)
            wanted = float(self.telemetry.enu_of(lat, lon, altitude)[2])
            if wanted > self.vehicle.position[2] + LIFTOFF_HEIGHT:
                target_z = wanted
        yaw = command.param(4)
        self._start_takeoff(target_z, self.vehicle.yaw if not math.isfinite(yaw) else frames.yaw_ned_to_enu(yaw))
        return ACCEPTED

    def _land(self, command: Command) -> int:
        self._take_control()
        self._start_landing()
        return ACCEPTED

    def _do_set_mode(self, command: Command) -> int:
        base_mode = int(command.param(1))
        if not base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            self._say(mavlink.MAV_SEVERITY_WARNING, "Set mode: only PX4 custom modes are simulated")
            return DENIED
        main, sub = int(command.param(2)), int(command.param(3))
        mode = autopilot.decode_mode(autopilot.MAV_AUTOPILOT_PX4, base_mode, (main << 16) | (sub << 24)).name
        return self._switch_to(mode)

    def _switch_to(self, mode: str) -> int:
        if mode == self.mode and not self.external:
            return ACCEPTED
        if mode == "OFFBOARD":
            if self._target is None or self._now - self._last_setpoint > OFFBOARD_FRESH:
                self._say(mavlink.MAV_SEVERITY_CRITICAL, "Switching to OFFBOARD denied: no set-points")
                return REJECTED
            self._take_control()
            self._start_offboard(self._target)
        elif mode in HOLD_MODES:
            self._take_control()
            self._hold_here(mode)
        elif mode == "AUTO.TAKEOFF":
            if not self.armed:
                self._say(mavlink.MAV_SEVERITY_CRITICAL, "Takeoff denied: disarmed")
                return REJECTED
            self._take_control()
            self._start_takeoff(max(self.home[2] + self.params["MIS_TAKEOFF_ALT"], self.vehicle.position[2]),
                                self.vehicle.yaw)
        elif mode == "AUTO.LAND":
            self._take_control()
            self._start_landing()
        else:
            self._say(mavlink.MAV_SEVERITY_WARNING, f"Mode {mode} is not simulated")
            return DENIED
        return ACCEPTED

    def _reposition(self, command: Command) -> int:
        if not self.armed or self.on_ground:
            self._say(mavlink.MAV_SEVERITY_CRITICAL, "Reposition denied: not flying")
            return REJECTED
        target = self._global_target(command)
        if target is None:
            return UNSUPPORTED
        self._take_control()
        yaw = command.param(4)
        self._hold_at(target, self.vehicle.yaw if not math.isfinite(yaw) else frames.yaw_ned_to_enu(yaw))
        return ACCEPTED

    def _set_home(self, command: Command) -> int:
        if command.param(1) >= 0.5:
            self.home = self.vehicle.position.copy()
        else:
            target = self._global_target(command)
            if target is None:
                return UNSUPPORTED
            self.home = target
        self._outbox.append(self.telemetry.home_position(self._now, self.status()))
        return ACCEPTED

    def _global_target(self, command: Command) -> np.ndarray | None:
        """param5-7 (lat, lon, alt) as a map position; NaN keeps the vehicle's own coordinate."""
        lat, lon, alt = self.telemetry.geodetic(self.vehicle.position)
        if command.frame in GLOBAL_RELATIVE_FRAMES:
            home_alt = self.telemetry.geodetic(self.home)[2]
            altitude = home_alt + command.param(7) if math.isfinite(command.param(7)) else alt
        elif command.frame in GLOBAL_AMSL_FRAMES:
            altitude = command.param(7) if math.isfinite(command.param(7)) else alt
        else:
            return None
        lat = command.param(5) if math.isfinite(command.param(5)) else lat
        lon = command.param(6) if math.isfinite(command.param(6)) else lon
        return self.telemetry.enu_of(lat, lon, altitude)

    def _request_message(self, command: Command) -> int:
        return self._send_now(int(command.param(1)))

    def _request_capabilities(self, command: Command) -> int:
        return self._send_now(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) if command.param(1) >= 0.5 else ACCEPTED

    def _send_now(self, msg_id: int) -> int:
        message = self.telemetry.message(msg_id, self._now, self.status())
        if message is None:
            return UNSUPPORTED
        self._outbox.append(message)
        return ACCEPTED

    def _set_message_interval(self, command: Command) -> int:
        msg_id, interval_us = int(command.param(1)), command.param(2)
        if not self.streams.known(msg_id) or not math.isfinite(interval_us):
            return UNSUPPORTED
        self.streams.set_interval(msg_id, interval_us, self._now)
        return ACCEPTED

    def _get_message_interval(self, command: Command) -> int:
        msg_id = int(command.param(1))
        self._outbox.append(mavlink.MAVLink_message_interval_message(msg_id, self.streams.interval_us(msg_id)))
        return ACCEPTED

    # --- set-points -------------------------------------------------------------------------------------------
    def _on_set_position_target_local_ned(self, msg) -> None:
        if not self._for_me(msg.target_system, msg.target_component):
            return
        vehicle = self.vehicle
        position = _masked((msg.x, msg.y, msg.z), msg.type_mask, IGNORE_POSITION)
        velocity = _masked((msg.vx, msg.vy, msg.vz), msg.type_mask, IGNORE_VELOCITY)
        frame = msg.coordinate_frame
        if frame in (mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_OFFSET_NED):
            # PX4: vectors in the heading frame (yaw only), positions as offsets from where the UAV is.
            heading = frames.yaw_enu_to_ned(vehicle.yaw)
            position, velocity = _turn(position, heading), _turn(velocity, heading)
            position = position + frames.enu_to_ned(vehicle.position)
        elif frame == mavlink.MAV_FRAME_LOCAL_OFFSET_NED:
            position = position + frames.enu_to_ned(vehicle.position)
        elif frame != mavlink.MAV_FRAME_LOCAL_NED:
            return
        self._set_point(_ned_to_enu(position), _ned_to_enu(velocity), msg)

    def _on_set_position_target_global_int(self, msg) -> None:
        if not self._for_me(msg.target_system, msg.target_component):
            return
        position = np.full(3, np.nan)
        if not msg.type_mask & 7:
            altitude = msg.alt
            if msg.coordinate_frame in GLOBAL_RELATIVE_FRAMES:
                altitude += self.telemetry.geodetic(self.home)[2]
            elif msg.coordinate_frame == mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT:
                altitude += self.telemetry.origin_geo[2]  # the map's ground is flat at the origin's altitude
            elif msg.coordinate_frame not in GLOBAL_AMSL_FRAMES:
                return
            position = self.telemetry.enu_of(msg.lat_int * 1e-7, msg.lon_int * 1e-7, altitude)
        velocity = _masked((msg.vx, msg.vy, msg.vz), msg.type_mask, IGNORE_VELOCITY)
        self._set_point(position, _ned_to_enu(velocity), msg)

    def _set_point(self, position: np.ndarray, velocity: np.ndarray, msg) -> None:
        if np.isnan(position).all() and np.isnan(velocity).all():
            return  # accelerations, forces or attitude only: not simulated, and no set-point for OFFBOARD
        yaw = self.vehicle.yaw if msg.type_mask & IGNORE_YAW or not math.isfinite(msg.yaw) \
            else frames.yaw_ned_to_enu(msg.yaw)
        yaw_rate = None if msg.type_mask & IGNORE_YAW_RATE or not math.isfinite(msg.yaw_rate) else -msg.yaw_rate
        self._target = OffboardTarget(position, velocity, yaw, yaw_rate)
        self._last_setpoint = self._now
        if self.mode == "OFFBOARD" and not self.external:
            self._apply_target(self._target)

    # --- parameters and the mission protocol -----------------------------------------------------------------
    def _on_param_request_list(self, msg) -> None:
        if self._for_me(msg.target_system, msg.target_component):
            for index, param in enumerate(self.params):
                self._outbox.append(self._param_value(index, param))

    def _on_param_request_read(self, msg) -> None:
        if not self._for_me(msg.target_system, msg.target_component):
            return
        found = self.params.find(msg.param_id, msg.param_index)
        if found is not None:  # PX4 stays silent about a name it does not know
            self._outbox.append(self._param_value(*found))

    def _on_param_set(self, msg) -> None:
        if not self._for_me(msg.target_system, msg.target_component):
            return
        try:
            index, param = self.params.set(msg.param_id, msg.param_value, msg.param_type)
        except ParamError as err:
            self._say(mavlink.MAV_SEVERITY_WARNING, str(err))
            return
        if not param.settable:
            self._say(mavlink.MAV_SEVERITY_WARNING, f"{param.name} is read-only here")
        self._outbox.append(self._param_value(index, param))

    def _param_value(self, index: int, param):
        return mavlink.MAVLink_param_value_message(param.name.encode(), encode(param), param.param_type,
                                                   len(self.params), index)

    def _on_mission_request_list(self, msg) -> None:
        if self._for_me(msg.target_system, msg.target_component):  # no mission is ever stored: it is empty
            self._outbox.append(mavlink.MAVLink_mission_count_message(
                msg.get_srcSystem(), msg.get_srcComponent(), 0, msg.mission_type))

    def _on_mission_count(self, msg) -> None:
        if self._for_me(msg.target_system, msg.target_component):
            result = mavlink.MAV_MISSION_ACCEPTED if msg.count == 0 else mavlink.MAV_MISSION_UNSUPPORTED
            if msg.count:
                self._say(mavlink.MAV_SEVERITY_WARNING, "Missions are not simulated")
            self._outbox.append(mavlink.MAVLink_mission_ack_message(
                msg.get_srcSystem(), msg.get_srcComponent(), result, msg.mission_type))

    def _on_mission_clear_all(self, msg) -> None:
        if self._for_me(msg.target_system, msg.target_component):
            self._outbox.append(mavlink.MAVLink_mission_ack_message(
                msg.get_srcSystem(), msg.get_srcComponent(), mavlink.MAV_MISSION_ACCEPTED, msg.mission_type))

    def _on_ping(self, msg) -> None:
        if msg.target_system == 0 and msg.target_component == 0:  # a request, not someone's answer
            self._outbox.append(mavlink.MAVLink_ping_message(msg.time_usec, msg.seq, msg.get_srcSystem(),
                                                             msg.get_srcComponent()))

    # --- helpers ----------------------------------------------------------------------------------------------
    def _for_me(self, target_system: int, target_component: int) -> bool:
        return target_system in (0, self.system_id) and target_component in (0, COMPONENT_ID)

    def _say(self, severity: int, text: str) -> None:
        self._outbox.append(self.telemetry.statustext(severity, text))

    def _flush(self) -> list:
        out, self._outbox = self._outbox, []
        return out


def _masked(values, type_mask: int, bits) -> np.ndarray:
    """The three values of a set-point, NaN where type_mask ignores them (or they are NaN already)."""
    return np.array([math.nan if type_mask & bit else float(v) for v, bit in zip(values, bits, strict=True)])


def _ned_to_enu(vector: np.ndarray) -> np.ndarray:
    """frames.ned_to_enu by moving components, not by a matrix product: an unset (NaN) axis stays its own."""
    return np.array([vector[1], vector[0], -vector[2]])


def _turn(vector_ned: np.ndarray, heading: float) -> np.ndarray:
    """A vector given in the heading frame (x forward, y right, z down) in NED."""
    c, s = math.cos(heading), math.sin(heading)
    x, y, z = vector_ned
    if math.isnan(x) and math.isnan(y):
        return np.array([x, y, z])
    return np.array([c * x - s * y, s * x + c * y, z])
