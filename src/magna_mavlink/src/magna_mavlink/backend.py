"""The UAL's behaviour over MAVLink: guards, commands, the set-point stream, take-off, landing, link health.

No ROS here. The node calls `tick(now)` at the stream rate (30 Hz of its clock: ROS time, simulated
or not) and the UAL commands from its service threads; tests do both on a clock of their own.

- **State** (ual_state.ual_state): UNINITIALIZED while the position is not valid or the HEARTBEAT is
  older than `heartbeat_timeout` (the HEARTBEAT or any other message of the autopilot, so a lossy radio
  does not count as a lost link); then from armed, landed state, flight mode and the running call.
- **Guards** as UAL: take_off from LANDED_ARMED (with arming `auto` also LANDED_DISARMED: it arms
  first); go_to_waypoint(_geo), set_pose, set_velocity and land in FLYING_AUTO; recover_from_manual
  in FLYING_MANUAL. NaN and infinities are refused. A refusal raises CommandRefused with the reason.
- **Set-points** go out on every tick. While the UAL flies the vehicle (taking off, FLYING_AUTO)
  the latest command is sent (setpoints.SetPointStream: a velocity not renewed within 0.5 s becomes
  a hold); otherwise a hold where the vehicle is, so that OFFBOARD/GUIDED, whoever selects it, starts
  by holding still. Nothing is sent once AUTO.LAND/LAND is on, nor while ArduPilot climbs on its own
  take-off.
- **Take-off** (PX4): OFFBOARD, then the set-point climbs at `take_off_speed` to the height above
  where the vehicle stood; (ArduPilot): GUIDED and MAV_CMD_NAV_TAKEOFF, then a hold at the height.
  It succeeds once magna_common.ual_arrival.Arrival says so: within position_th / 2 of that point, heading within
  orientation_th / 2, for hold_pose_time.
- **Land**: AUTO.LAND (PX4) or LAND (ArduPilot), done when the autopilot reports ON_GROUND (or
  disarms, for one that sends no EXTENDED_SYS_STATE).
- **Arming** `auto` (simulation, HIL): ual_mavlink is its own safety pilot: it selects OFFBOARD/GUIDED
  and arms a vehicle that stands disarmed on the ground, and switches modes itself. `pilot` (real
  UAVs): it never arms nor selects OFFBOARD/GUIDED before a take-off; the safety pilot arms, and a
  take_off waits for the pilot's switch. A pilot's mode change in flight shows as FLYING_MANUAL.
"""
from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from magna_common import geo
from magna_common import ros_names as names
from magna_common.ual_arrival import Arrival
from magna_common.ual_commands import CommandRefused, finite_vector, require_finite

from . import autopilot as ap
from . import frames
from .link import CommandFailed
from .setpoints import VELOCITY_TIMEOUT, SetPointStream
from .ual_state import (
    FLYING_AUTO,
    FLYING_MANUAL,
    LAND_CALL,
    LANDED_ARMED,
    LANDED_DISARMED,
    LANDED_STATE_WAIT,
    NAMES,
    ON_GROUND,
    TAKE_OFF_CALL,
    UNINITIALIZED,
    ual_state,
)
from .vehicle_state import POSITION_TIMEOUT, Telemetry, VehicleState

AUTO, PILOT = "auto", "pilot"
LAND_MODE = {ap.PX4: "AUTO.LAND", ap.ARDUPILOT: "LAND"}
GO_TO = "go_to_waypoint"
MODE_RETRY = 0.3  # s between requests of a mode the autopilot did not accept yet
MAX_ARM_AGAIN = 2  # a take-off disarmed on the ground this often more is refused (something else disarms it)


@dataclass(frozen=True)
class Settings:
    uav_id: int = 1
    arming: str = AUTO
    position_th: float = 0.33  # m (UAL's default)
    orientation_th: float = 0.65  # rad (UAL's default)
    hold_pose_time: float = 1.0  # s held at a target before it counts as reached (UAL: 3 s; magna_sim: 1 s)
    take_off_speed: float = 1.0  # m/s of the climbing set-point (PX4)
    stuck_time: float = 10.0  # s without coming nearer before a target is given up on; 0: never
    heartbeat_timeout: float = 2.0  # s without a message of the autopilot before the link counts as lost
    position_timeout: float = POSITION_TIMEOUT  # s without LOCAL_POSITION_NED before the position counts as lost
    velocity_timeout: float = VELOCITY_TIMEOUT
    mode_timeout: float = 5.0  # s for the autopilot to show a mode or arming it accepted
    pilot_timeout: float = 120.0  # s a take_off waits for the safety pilot's switch (arming pilot)
    arm_retry: float = 2.0  # s between arming attempts (arming auto)


class Log(Protocol):
    """Where the backend tells what happens: a logging.Logger, or the node's rospy logger (ros_server.RosLog)."""

    def info(self, message: str, /) -> None: ...

    def warning(self, message: str, /) -> None: ...

    def error(self, message: str, /) -> None: ...


class Operation:
    """One take_off, land or go_to_waypoint, from its start to success or failure."""

    def __init__(self, name: str):
        self.name = name
        self.phase = "start"
        self.error: str | None = None
        self.done = False
        self.arrival: Arrival | None = None
        self.start = np.zeros(3)
        self.yaw = 0.0
        self.height = 0.0
        self.climb_started = 0.0
        self.armed_again = 0  # times a take-off armed again after a disarm on the ground

    @property
    def finished(self) -> bool:
        return self.done or self.error is not None


class UalBackend:
    def __init__(self, vehicle: VehicleState, commander, settings: Settings, url: str,
                 clock: Callable[[], float] = time.monotonic, log: Log | None = None):
        if settings.arming not in (AUTO, PILOT):
            raise ValueError(f"arming: {settings.arming!r}; use {AUTO} (simulation, HIL) or {PILOT} (real UAVs)")
        self.vehicle = vehicle
        self.commander = commander  # commands.Commander, or a test's stand-in
        self.settings = settings
        self.url = url
        self.clock = clock
        self.log: Log = log or logging.getLogger("ual_mavlink")
        self.stream = SetPointStream(settings.velocity_timeout)
        self.state = UNINITIALIZED
        self.link_problem = f"no heartbeat from {url} yet"
        self.home: np.ndarray | None = None  # map position of the uav_{id}_home frame
        self._home_by_user = False
        self._lock = threading.RLock()  # guards + starting a command, against the tick
        self._ticked = threading.Condition()
        self._op: Operation | None = None
        self._in_control = False  # the UAL flies the vehicle: stream the latest command
        self._arming_since: float | None = None  # an arming attempt runs (auto), since when
        self._last_arm_try = -math.inf
        self._closed = False
        self._now = 0.0
        self._telemetry = Telemetry()

    # --- the tick -------------------------------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Advance everything by the clock: link health, state, the set-point sent, running operations."""
        with self._lock:
            self._now = now
            t = self._telemetry = self.vehicle.snapshot()
            link_ok = self._update_link(t, now)
            valid = link_ok and t.position_valid(now, self.settings.position_timeout)
            self.state = self._state(t, valid)
            if valid and (self.home is None or not self._home_by_user and t.home_geo is not None):
                self._follow_autopilot_home(t)
            op = self._op
            if op is not None and not op.finished:
                self._progress(op, t, now, link_ok)
                self.state = self._state(t, valid)  # a call that just ended no longer decides it
            if self.state == FLYING_AUTO:
                self._in_control = True  # also when a pilot (or whoever) selected OFFBOARD/GUIDED in flight
            elif self.state in (FLYING_MANUAL, LANDED_ARMED, LANDED_DISARMED) and (op is None or op.finished):
                self._in_control = False
            if t.position_time is not None and t.autopilot is not None:
                self._send_set_point(t, now)
            if valid and self.settings.arming == AUTO:
                self._keep_armed(now)
        with self._ticked:
            self._ticked.notify_all()

    def _state(self, t: Telemetry, valid: bool) -> int:
        if not valid:
            return UNINITIALIZED
        op = self._op
        call = op.name if op is not None and not op.finished and op.name in (TAKE_OFF_CALL, LAND_CALL) else None
        pending = (not t.landed_state_heard and t.first_heard_time is not None
                   and self._now - t.first_heard_time < LANDED_STATE_WAIT)
        return ual_state(True, t.armed, t.landed_state, t.follows_set_points, call, landed_state_pending=pending)

    def _update_link(self, t: Telemetry, now: float) -> bool:
        # Any message counts as a sign of life, not only the 1 Hz HEARTBEAT: through a radio that loses one
        # packet in five, two HEARTBEATs in a row go missing every minute or so, the 30 Hz telemetry never.
        if t.heartbeat_time is None:
            problem = f"no heartbeat from {self.url} yet"
        else:
            assert t.heard_time is not None  # every message sets it, the HEARTBEAT too
            if now - t.heard_time > self.settings.heartbeat_timeout:
                problem = (f"no heartbeat from {self.url} for {self.settings.heartbeat_timeout:.1f} s "
                           f"(nor any other message)")
            else:
                problem = ""
        if problem != self.link_problem:
            if problem:
                self.log.warning(f"UAV {self.settings.uav_id}: {problem}")
            else:
                again = "" if self.link_problem.endswith("yet") else " again"
                self.log.info(f"UAV {self.settings.uav_id}: heartbeat from {self.url}{again}")
        self.link_problem = problem
        return not problem

    def _follow_autopilot_home(self, t: Telemetry) -> None:
        """Home is where the autopilot says (PX4 sets it when arming) until set_home is called."""
        if t.home_geo is not None:
            where = self._geo_to_map(t, t.home_geo)
            if where is not None:
                self.home = where
                return
        if self.home is None:
            self.home = t.position.copy()

    def _send_set_point(self, t: Telemetry, now: float) -> None:
        op = self._op
        if op is not None and not op.finished and op.phase in ("descend", "autopilot climb"):
            return  # the autopilot flies on its own (set-points until then: PX4 leaves OFFBOARD without them)
        if not self._in_control:
            self.stream.hold(t.position, t.yaw)  # hold where it is, should OFFBOARD/GUIDED be selected
        point = self.stream.at(now, t.position, t.yaw)
        if point is None:
            return
        if point.kind == "velocity":
            self.commander.send_velocity(frames.enu_to_ned(point.vector), -point.yaw_rate)
        else:
            yaw = t.yaw if point.yaw is None else point.yaw
            self.commander.send_position(t.map_to_local_ned(point.vector), frames.yaw_enu_to_ned(yaw))

    def _keep_armed(self, now: float) -> None:
        if (self.state != LANDED_DISARMED or self._op is not None and not self._op.finished
                or self._arming_since is not None or now - self._last_arm_try < self.settings.arm_retry):
            return
        self._last_arm_try = now
        self._arming_since = now
        self._arm_in_background("ual_mavlink arming", self._armed_on_the_ground)

    def _armed_on_the_ground(self, err: Exception | None) -> None:
        """The end of an arming `_keep_armed` began; a failed one is tried again arm_retry s later."""
        if err is not None:
            self.log.warning(f"UAV {self.settings.uav_id}: arming: {err}; trying again in "
                             f"{self.settings.arm_retry:g} s")
        self._arming_since = None

    def _arm_in_background(self, name: str, then: Callable[[Exception | None], None]) -> None:
        """Arm on a thread of its own, as the ticks must go on meanwhile (the set-points PX4 wants before OFFBOARD,
        the telemetry that shows it armed); then `then(None)`, or `then(err)` with why it did not arm."""
        def arm() -> None:
            try:
                self._arm()
            except Exception as err:  # CommandFailed, CommandRefused, or a bug: said either way, never a dead thread
                then(err)
                return
            then(None)

        threading.Thread(target=arm, name=name, daemon=True).start()

    # --- progress of the running operation ------------------------------------------------------------------------
    def _progress(self, op: Operation, t: Telemetry, now: float, link_ok: bool) -> None:
        uav = f"UAV {self.settings.uav_id}"
        if not link_ok and t.heartbeat_time is not None:
            return self._fail(op, f"{op.name} interrupted: {self.link_problem}")
        if op.name == TAKE_OFF_CALL:
            if op.phase == "climb" and not t.armed and self._may_arm_again(op, t):
                return self._arm_again(op)
            if op.phase in ("pilot", "climb", "autopilot climb", "arrive") and not t.armed:
                return self._fail(op, f"take_off interrupted: {uav} was disarmed")
            if op.phase in ("climb", "arrive") and not t.follows_set_points:
                assert t.mode is not None  # the climb began in the set-point mode, and a mode heard stays known
                return self._fail(op, f"take_off interrupted: {uav} left {ap.SET_POINT_MODE[_autopilot(t)]} for "
                                      f"{t.mode.name} (a pilot took over?)")
            if op.phase == "climb":
                climbed = min(op.height, self.settings.take_off_speed * max(0.0, now - op.climb_started))
                self.stream.hold(op.start + [0.0, 0.0, climbed], op.yaw)
                if climbed >= op.height:
                    self._arrive(op, op.start + [0.0, 0.0, op.height], op.yaw, now)
            elif op.phase == "autopilot climb" and t.position[2] >= op.start[2] + 0.95 * op.height:
                target = np.array([t.position[0], t.position[1], op.start[2] + op.height])
                self.stream.hold(target, op.yaw)
                self._arrive(op, target, op.yaw, now)
        elif op.name == LAND_CALL:
            if op.phase == "descend":
                if t.landed_state == ON_GROUND or not t.armed:
                    op.done = True
                    self.log.info(f"{uav}: landed")
                elif t.mode is not None and t.mode.name != LAND_MODE[_autopilot(t)]:
                    return self._fail(op, f"land interrupted: {uav} left {LAND_MODE[_autopilot(t)]} for "
                                          f"{t.mode.name} (a pilot took over?)")
        elif op.name == GO_TO and self.state != FLYING_AUTO:
            why = (f" (no position from {self.url} for {self.settings.position_timeout:.1f} s)"
                   if self.state == UNINITIALIZED else "")
            return self._fail(op, f"{GO_TO} interrupted: {uav} is {NAMES[self.state]}{why}")
        if op.phase == "arrive" and op.arrival is not None:
            op.arrival.update(t.position, t.yaw, now)
            if op.arrival.arrived:
                op.done = True
            elif op.arrival.stuck:
                self._fail(op, f"{op.name} not reached: {uav} is {op.arrival.stuck}")

    def _may_arm_again(self, op: Operation, t: Telemetry) -> bool:
        """A disarm before the climb left the ground, with arming auto: the autopilot's pre-flight auto-disarm
        (PX4's COM_DISARM_PRFLT: armed on the ground too long) met a take-off that came just then. ual_mavlink
        armed the UAV itself, so it arms it again, as an operator would; in the air a disarm stays a failure."""
        on_ground = t.landed_state == ON_GROUND or t.position[2] < op.start[2] + 0.1
        return self.settings.arming == AUTO and on_ground and op.armed_again < MAX_ARM_AGAIN

    def _arm_again(self, op: Operation) -> None:
        uav = f"UAV {self.settings.uav_id}"
        op.armed_again += 1
        op.phase = "arming"  # the set-points hold op.start meanwhile (PX4 wants them before OFFBOARD)
        self.log.warning(f"{uav}: disarmed on the ground as the take-off began (the autopilot's pre-flight "
                         f"auto-disarm?): arming it again")

        def climb_once_armed(err: Exception | None) -> None:
            with self._lock:
                if err is not None:
                    self._fail(op, f"take_off interrupted: {uav} was disarmed on the ground and did not arm "
                                   f"again: {err}")
                elif not op.finished:
                    op.climb_started, op.phase = self._now, "climb"

        self._arm_in_background("ual_mavlink arming again", climb_once_armed)

    def _arrive(self, op: Operation, target, yaw: float | None, now: float) -> None:
        s = self.settings
        op.phase = "arrive"
        op.arrival = Arrival(target, yaw, now, s.position_th / 2.0, s.orientation_th / 2.0, s.hold_pose_time,
                             s.stuck_time)

    def _fail(self, op: Operation, reason: str) -> None:
        if not op.finished:
            op.error = reason
            self.log.error(f"{names.ual(self.settings.uav_id, op.name)}: {reason}")

    # --- commands -------------------------------------------------------------------------------------------------
    def take_off(self, height: float, blocking: bool) -> None:
        require_finite("height", height)
        if height <= 0.0:
            raise CommandRefused(f"take_off: height must be positive, got {height}")
        with self._lock:
            allowed = (LANDED_ARMED, LANDED_DISARMED) if self.settings.arming == AUTO else (LANDED_ARMED,)
            if self.state not in allowed:
                self._refuse("take_off", LANDED_ARMED)
            op = self._start(TAKE_OFF_CALL)
            t = self._telemetry
            op.start, op.yaw, op.height = t.position.copy(), t.yaw, float(height)
            self.stream.hold(op.start, op.yaw)
            self._in_control = True
        self._run(op, self._take_off, blocking)

    def _take_off(self, op: Operation) -> None:
        uav = f"UAV {self.settings.uav_id}"
        autopilot = _autopilot(self._telemetry)
        mode = ap.SET_POINT_MODE[autopilot]
        if self.settings.arming == AUTO:
            if not self._telemetry.armed:
                op.phase = "arming"
                self._arm()
            op.phase = "mode"
            self._select_mode(mode)
        elif not self._telemetry.follows_set_points:
            op.phase = "pilot"
            self.log.warning(f"{uav}: take_off waits up to {self.settings.pilot_timeout:g} s for the safety pilot "
                             f"to switch to {mode} (arming: pilot); the UAV holds where it is once switched")
            self._await(lambda t: t.follows_set_points, f"the safety pilot to switch {uav} to {mode}",
                        self.settings.pilot_timeout, op)
        with self._lock:
            if op.finished:
                return
            t = self._telemetry
            if autopilot == ap.PX4:
                op.climb_started, op.phase = self._now, "climb"
                self.log.info(f"{uav}: climbing {op.height:g} m at {self.settings.take_off_speed:g} m/s")
                return
            op.phase = "autopilot climb"
            op.start = t.position.copy()
        self.commander.take_off(op.height)
        self.log.info(f"{uav}: ArduPilot climbing {op.height:g} m (MAV_CMD_NAV_TAKEOFF)")

    def land(self, blocking: bool) -> None:
        with self._lock:
            self._require(FLYING_AUTO, "land")
            op = self._start(LAND_CALL)
            t = self._telemetry
            self.stream.hold(t.position, t.yaw)  # until the landing mode is on
        self._run(op, self._land, blocking)

    def _land(self, op: Operation) -> None:
        self._select_mode(LAND_MODE[_autopilot(self._telemetry)], op)
        with self._lock:
            if not op.finished:
                op.phase = "descend"
                self._in_control = False

    def go_to(self, frame_id: str, position, yaw: float, blocking: bool) -> None:
        position = finite_vector("waypoint.pose.position", position)
        require_finite("waypoint orientation (yaw)", yaw)
        with self._lock:
            self._require(FLYING_AUTO, GO_TO)
            target = self._to_map(frame_id, position)
            op = self._start(GO_TO)
            self.stream.hold(target, yaw)
            self._arrive(op, target, yaw, self._now)
        if blocking:
            self._wait(op)

    def go_to_geo(self, latitude: float, longitude: float, altitude: float, blocking: bool) -> None:
        values = (latitude, longitude, altitude)
        if not all(math.isfinite(v) for v in values):
            raise CommandRefused(f"waypoint: latitude/longitude/altitude {list(values)} must be finite numbers")
        with self._lock:
            t = self._telemetry
            target = self._geo_to_map(t, values)
            if target is None:
                raise CommandRefused(
                    f"go_to_waypoint_geo: UAV {self.settings.uav_id} has no geographic reference yet: the "
                    f"autopilot has sent neither GPS_GLOBAL_ORIGIN nor HOME_POSITION (give --origin-geo LAT LON ALT "
                    f"of the map origin, or wait for the autopilot's position fix)")
            yaw = t.yaw
        self.go_to("map", target, yaw, blocking)

    def set_pose(self, frame_id: str, position, yaw: float) -> None:
        position = finite_vector("set_pose position", position)
        require_finite("set_pose orientation (yaw)", yaw)
        with self._lock:
            self._require(FLYING_AUTO, "set_pose")
            target = self._to_map(frame_id, position)
            self._replace_go_to()
            self.stream.hold(target, yaw)

    def set_velocity(self, velocity, yaw_rate: float) -> None:
        velocity = finite_vector("set_velocity linear", velocity)
        require_finite("set_velocity angular.z", yaw_rate)
        with self._lock:
            self._require(FLYING_AUTO, "set_velocity")
            self._replace_go_to()
            self.stream.velocity(velocity, self._now, yaw_rate)

    def set_home(self, set_z: bool) -> None:
        with self._lock:
            if self.state == UNINITIALIZED:
                raise CommandRefused(f"set_home refused: UAV {self.settings.uav_id} is UNINITIALIZED "
                                     f"({self.link_problem or 'no valid position yet'})")
            t = self._telemetry
        geo_home: tuple[float, float, float] | None = None  # None: where the vehicle is, its altitude too
        if not set_z and t.global_position is not None and t.home_geo is not None:
            geo_home = (t.global_position[0], t.global_position[1], t.home_geo[2])  # keeps the home's altitude
        try:
            self.commander.set_home(geo_home)
        except CommandFailed as err:
            raise CommandRefused(f"set_home: {err}") from None
        with self._lock:
            home = self.home.copy() if self.home is not None else t.position.copy()
            home[:2] = t.position[:2]
            if set_z:
                home[2] = t.position[2]
            self.home, self._home_by_user = home, True

    def recover_from_manual(self) -> None:
        with self._lock:
            self._require(FLYING_MANUAL, "recover_from_manual")
            t = self._telemetry
            self.stream.hold(t.position, t.yaw)
            self._in_control = True
        mode = ap.SET_POINT_MODE[_autopilot(t)]
        try:
            self._select_mode(mode)
        except CommandFailed as err:
            raise CommandRefused(f"recover_from_manual: {err}") from None
        self.log.info(f"UAV {self.settings.uav_id}: recovered from manual: {mode}, holding where it is")

    # --- helpers ------------------------------------------------------------------------------------------------
    def _refuse(self, command: str, needed: int) -> None:
        raise CommandRefused(f"{command} refused: UAV {self.settings.uav_id} is {NAMES[self.state]}; "
                             f"{command} needs {NAMES[needed]}")

    def _require(self, needed: int, command: str) -> None:
        if self.state != needed:
            self._refuse(command, needed)

    def _start(self, name: str) -> Operation:
        self._replace_go_to()
        op = self._op = Operation(name)
        return op

    def _replace_go_to(self) -> None:
        op = self._op
        if op is not None and op.name == GO_TO and not op.finished:
            op.error = f"{GO_TO} interrupted: a newer command replaced it before it finished"

    def _run(self, op: Operation, work: Callable[[Operation], None], blocking: bool) -> None:
        def run():
            try:
                work(op)
            except (CommandFailed, CommandRefused) as err:
                with self._lock:
                    self._fail(op, f"{op.name}: {err}")
                    self._in_control = False

        if blocking:
            run()
            self._wait(op)
        else:
            threading.Thread(target=run, name=f"ual_mavlink {op.name}", daemon=True).start()

    def _wait(self, op: Operation) -> None:
        """Until `op` succeeds (return) or fails (CommandRefused with why)."""
        with self._ticked:
            while not op.finished and not self._closed:
                self._ticked.wait(0.1)
        if op.error:
            raise CommandRefused(op.error)
        if not op.done:
            raise CommandRefused(f"{op.name}: ual_mavlink is shutting down")

    def _await(self, condition: Callable[[Telemetry], bool], what: str, timeout: float,
               op: Operation | None = None) -> None:
        """Until the telemetry meets `condition`, on the backend's clock; CommandRefused after `timeout` s."""
        start = self._now
        with self._ticked:
            while not condition(self._telemetry):
                if self._closed:
                    raise CommandRefused("ual_mavlink is shutting down")
                if op is not None and op.finished:
                    raise CommandRefused(op.error or f"{op.name} ended")
                if self.link_problem and self._telemetry.heartbeat_time is not None:
                    raise CommandRefused(f"waiting for {what}: {self.link_problem}")
                if self._now - start > timeout:
                    raise CommandRefused(f"{what} did not happen within {timeout:g} s")
                self._ticked.wait(0.1)

    def _arm(self) -> None:
        self._select_mode(ap.SET_POINT_MODE[_autopilot(self._telemetry)])
        self.commander.arm()
        self._await(lambda t: t.armed, f"UAV {self.settings.uav_id} to report armed", self.settings.mode_timeout)

    def _select_mode(self, mode: str, op: Operation | None = None) -> None:
        if self._telemetry.mode is not None and self._telemetry.mode.name == mode:
            return
        # PX4 refuses OFFBOARD until it has had set-points for a moment (TEMPORARILY_REJECTED): ask again.
        deadline = self._now + self.settings.mode_timeout
        while True:
            try:
                self.commander.set_mode(mode)
                break
            except CommandFailed:
                if self._now >= deadline:
                    raise
                self._pause(MODE_RETRY, op)
        self._await(lambda t: t.mode is not None and t.mode.name == mode,
                    f"UAV {self.settings.uav_id} to report mode {mode}", self.settings.mode_timeout, op)

    def _pause(self, seconds: float, op: Operation | None) -> None:
        """Let `seconds` of the backend's clock pass (the ticks keep the set-points going meanwhile)."""
        end = self._now + seconds
        try:
            self._await(lambda t: self._now >= end, "", math.inf, op)
        except CommandRefused:
            if op is not None and op.finished or self._closed:
                raise

    def _to_map(self, frame_id: str, position: np.ndarray) -> np.ndarray:
        if frame_id in ("", "map"):
            return position
        if frame_id == f"uav_{self.settings.uav_id}_home" and self.home is not None:
            return position + self.home
        raise CommandRefused(f"header.frame_id '{frame_id}' is not known here; use 'map' or "
                             f"'uav_{self.settings.uav_id}_home'")

    def _geo_to_map(self, t: Telemetry, fix: tuple[float, float, float]) -> np.ndarray | None:
        if self.vehicle.origin_geo is not None:
            return geo.geodetic_to_enu(*fix, self.vehicle.origin_geo)
        reference = t.geo_reference()
        if reference is None:
            return None
        reference_geo, reference_map = reference
        return geo.geodetic_to_enu(*fix, reference_geo) + reference_map

    # --- what the ROS side reads ---------------------------------------------------------------------------------
    @property
    def telemetry(self) -> Telemetry:
        return self._telemetry

    def close(self) -> None:
        self._closed = True
        with self._ticked:
            self._ticked.notify_all()


def _autopilot(t: Telemetry) -> str:
    """The autopilot flown. Known before any command: ual_mavlink builds the backend once the vehicle's HEARTBEAT
    named a PX4 or ArduPilot (or --autopilot did), and an autopilot heard stays known."""
    assert t.autopilot is not None
    return t.autopilot
