"""The UAL state machine of one UAV, and what each UAL command does to its setpoint.

    UNINITIALIZED -> LANDED_ARMED -> TAKING_OFF -> FLYING_AUTO -> LANDING -> LANDED_ARMED

Commands are checked here and refused with `CommandRefused` (the message says
why and what state would accept it); the ROS layer turns that into a failed
service call. Numbers must be finite. A position target (take_off, go_to_waypoint, set_pose) far
outside the world's boundaries (`boundaries`, from the world node's /magna/world/boundaries, once the
ROS layer knows them) is refused; one just outside is flown, as the original's UAL did, and told to
`on_warning`. `update` advances the machine after each physics step.
Every accepted command bumps `command_id`, so a blocking call can tell when a
newer command took its place.

Arrival (magna_common.ual_arrival, as GRVC UAL's referencePoseReached, with the UAV's true pose):
a multirotor has reached a take-off or waypoint target once it has stayed within `arrival_radius` of it
(half of UAL's position_th, and never more than the airframe's accepted_target_radius),
with its heading within half of orientation_th, for `hold_time` of simulated time. A
take-off becomes FLYING_AUTO only then. A target that comes no nearer for `stuck_time`
(blocked, under the ground, ...) is given up on: `stuck` says why, and a blocking call
fails with that reason instead of waiting for ever.

A fixed wing (an airframe with a fixed_wing block) runs the same machine; only what
counts as done differs, because it cannot stop: a waypoint is reached once the plane
circles it on its loiter circle, and a landing ends when the plane has rolled to a stop.
"""
from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from magna_common.ual_arrival import Arrival
from magna_common.ual_commands import CommandRefused, finite_vector, require_finite

from . import fixed_wing
from .vehicle import Manoeuvre, Setpoint, SetpointMode, Vehicle


class UalState(enum.IntEnum):  # values of uav_abstraction_layer/State
    UNINITIALIZED = 0
    LANDED_DISARMED = 1
    LANDED_ARMED = 2
    TAKING_OFF = 3
    FLYING_AUTO = 4
    FLYING_MANUAL = 5
    LANDING = 6


@dataclass(frozen=True)
class UalSettings:
    position_th: float = 0.33  # m: UAL's default; a target is reached within half of it (see arrival_radius)
    orientation_th: float = 0.65  # rad: UAL's default; the heading must be within half of it
    hold_time: float = 1.0  # s of sim time the UAV must stay there (UAL's hold_pose_time, 3 s on a real UAV)
    stuck_time: float = 10.0  # s of sim time without coming nearer before a target counts as out of reach
    take_off_speed: float = 1.0  # m/s
    land_speed: float = 0.6  # m/s
    velocity_timeout: float = 1.0  # s of sim time without set_velocity before holding position; 0 = never
    landed_height: float = 0.05  # m above the ground that counts as touched down


FAR_OUTSIDE = 1.0  # times the world's largest extent: a target farther outside than this is refused


class UalLogic:
    def __init__(self, vehicle: Vehicle, settings: UalSettings = UalSettings()):
        self.vehicle = vehicle
        self.settings = settings
        self.state = UalState.UNINITIALIZED
        self.command_id = 0
        self.home = vehicle.position.copy()
        self._fixed_wing = vehicle.airframe.fixed_wing  # None for a multirotor
        self._last_velocity_time = 0.0
        self._time = 0.0
        self._approach: Arrival | None = None  # the take-off or waypoint being flown to, if any
        self.boundaries: np.ndarray | None = None  # the world's [[xmin, xmax], [ymin, ymax], [zmin, zmax]], if known
        self.on_warning: Callable[[str], None] = lambda message: None  # a target flown outside the world
        # A blocking call must never return farther out than MAGNA's own idea of "there".
        self.arrival_radius = min(settings.position_th / 2.0, vehicle.airframe.accepted_target_radius)

    # --- commands --------------------------------------------------------------------------------------------
    def take_off(self, height: float) -> None:
        require_finite("height", height)
        if height <= 0.0:
            raise CommandRefused(f"take_off: height must be positive, got {height}")
        self._require(UalState.LANDED_ARMED, "take_off")
        target = self.vehicle.position + np.array([0.0, 0.0, height])
        self._require_inside(f"take_off to {height:g} m", target)
        self._command(Setpoint(SetpointMode.POSITION, position=target, yaw=self.vehicle.yaw,
                               max_vertical_speed=self.settings.take_off_speed, manoeuvre=Manoeuvre.TAKE_OFF))
        self._watch()
        self.state = UalState.TAKING_OFF

    def land(self) -> None:
        self._require(UalState.FLYING_AUTO, "land")
        self._start_landing()

    def go_to(self, position, yaw: float) -> None:
        position = finite_vector("waypoint.pose.position", position)
        require_finite("waypoint orientation (yaw)", yaw)
        self._require(UalState.FLYING_AUTO, "go_to_waypoint")
        self._require_inside("go_to_waypoint", position)
        self._command(Setpoint(SetpointMode.POSITION, position=position, yaw=yaw))
        self._watch()

    def failsafe_land(self) -> None:
        """Land whatever was commanded (empty battery); the commander sees LANDING."""
        self._start_landing()

    def set_pose(self, position, yaw: float) -> None:
        """Streamed position setpoint; refused (the ROS layer only warns) unless FLYING_AUTO."""
        position = finite_vector("set_pose position", position)
        require_finite("set_pose orientation (yaw)", yaw)
        self._require(UalState.FLYING_AUTO, "set_pose")
        self._require_inside("set_pose", position)
        self._command(Setpoint(SetpointMode.POSITION, position=position, yaw=yaw))

    def set_velocity(self, velocity, yaw_rate: float) -> None:
        velocity = finite_vector("set_velocity linear", velocity)
        require_finite("set_velocity angular.z", yaw_rate)
        self._require(UalState.FLYING_AUTO, "set_velocity")
        self._command(Setpoint(SetpointMode.VELOCITY, velocity=velocity, yaw_rate=yaw_rate))
        self._last_velocity_time = self._time

    def set_home(self, set_z: bool) -> None:
        self.home[:2] = self.vehicle.position[:2]
        if set_z:
            self.home[2] = self.vehicle.position[2]

    def recover_from_manual(self) -> None:
        self._require(UalState.FLYING_MANUAL, "recover_from_manual")
        self._hold_here()
        self.state = UalState.FLYING_AUTO

    def start_airborne(self) -> None:
        """FLYING_AUTO at once, holding where the vehicle is: for a learning environment that places a UAV in the
        air rather than flying its take-off (SimWorld.place_airborne). A fixed wing cannot hold a point: refused."""
        if self._fixed_wing is not None:
            raise CommandRefused(f"UAV {self.vehicle.uav_id} is a fixed wing, which cannot start airborne holding a "
                                 "point; fly its take-off instead")
        self._hold_here()
        self.state = UalState.FLYING_AUTO

    # --- progress --------------------------------------------------------------------------------------------
    def update(self, time: float) -> None:
        """Called after every physics step with the sim time."""
        self._time = time
        vehicle, state = self.vehicle, self.state
        approach = self._approach
        if approach is not None and self._fixed_wing is None:
            approach.update(vehicle.position, vehicle.yaw, time)
        if state == UalState.UNINITIALIZED:
            self.state = UalState.LANDED_ARMED
        elif state == UalState.TAKING_OFF:
            if self._fixed_wing is not None:  # it climbs out along its heading: only the height counts
                if abs(vehicle.position[2] - vehicle.setpoint.position[2]) < self.settings.position_th / 2:
                    self.state = UalState.FLYING_AUTO
            elif approach is not None and approach.arrived:
                self.state = UalState.FLYING_AUTO
        elif state == UalState.LANDING:
            # A plane touches down at speed and rolls out: landed once it has stopped.
            rolling = self._fixed_wing is not None and float(np.linalg.norm(vehicle.velocity[:2])) >= 0.2
            if vehicle.position[2] < self.settings.landed_height and abs(vehicle.velocity[2]) < 0.2 and not rolling:
                vehicle.setpoint = Setpoint(SetpointMode.OFF)
                self.state = UalState.LANDED_ARMED
        elif (state == UalState.FLYING_AUTO and vehicle.setpoint.mode == SetpointMode.VELOCITY
              and self.settings.velocity_timeout > 0
              and time - self._last_velocity_time > self.settings.velocity_timeout):
            self._hold_here()  # a silent commander must not leave a UAV drifting away

    def reached(self) -> bool:
        """Has the UAV arrived at the target of the current take-off or go_to_waypoint (see the module doc)?"""
        setpoint = self.vehicle.setpoint
        if setpoint.mode != SetpointMode.POSITION:
            return False
        if self._fixed_wing is not None:  # it circles the point; its heading is its course
            return fixed_wing.on_station(self._fixed_wing, setpoint.position, self.vehicle.position,
                                         self.settings.position_th)
        return self._approach is not None and self._approach.arrived

    @property
    def stuck(self) -> str | None:
        """Why the current take-off or waypoint is out of reach, or None while it is not (or is reached)."""
        if self._approach is None or self._approach.stuck is None:
            return None
        return (f"UAV {self.vehicle.uav_id} is {self._approach.stuck}: something blocks it or the target is out of "
                "reach. It keeps flying toward the target until another command")

    # --- helpers ---------------------------------------------------------------------------------------------
    def _require(self, state: UalState, command: str) -> None:
        if self.state != state:
            raise CommandRefused(f"{command} refused: UAV {self.vehicle.uav_id} is {self.state.name}; "
                                 f"{command} needs {state.name}")

    def _require_inside(self, command: str, target: np.ndarray) -> None:
        """A target far beyond the world (a typo, 1e6 m away) is refused, not flown toward. One within a world's
        size of it is flown with a warning: the original's UAL flew anything, and its missions may leave the box."""
        box = self.boundaries
        if box is None:
            return
        beyond = float(np.max(np.maximum(box[:, 0] - target, target - box[:, 1])))  # > 0: outside
        if beyond <= 0.0:
            return
        limits = ", ".join(f"{axis} {low:g}..{high:g}" for axis, (low, high) in zip("xyz", box.tolist(), strict=True))
        where = (f"the target ({', '.join(f'{v:.6g}' for v in target)}) is {beyond:.6g} m outside the world's "
                 f"boundaries ({limits} m)")
        margin = FAR_OUTSIDE * float(np.max(box[:, 1] - box[:, 0]))
        if not beyond <= margin:
            raise CommandRefused(f"{command} refused: {where}, more than the world's size ({margin:g} m); "
                                 f"give a target inside them")
        self.on_warning(f"{command}: {where}; flown all the same")

    def _start_landing(self) -> None:
        # Aim below the floor so the descent never stalls just above it; touching down ends it.
        target = np.array([self.vehicle.position[0], self.vehicle.position[1], -1.0])
        self._command(Setpoint(SetpointMode.POSITION, position=target, yaw=self.vehicle.yaw,
                               max_vertical_speed=self.settings.land_speed, manoeuvre=Manoeuvre.LAND))
        self.state = UalState.LANDING

    def _command(self, setpoint: Setpoint) -> None:
        self.vehicle.setpoint = setpoint
        self.command_id += 1
        self._approach = None

    def _hold_here(self) -> None:
        self.vehicle.setpoint = Setpoint(SetpointMode.POSITION, position=self.vehicle.position.copy(),
                                         yaw=self.vehicle.yaw)
        self.command_id += 1
        self._approach = None

    def _watch(self) -> None:
        """Follow the UAV toward the setpoint just commanded, for reached() and stuck."""
        setpoint, settings = self.vehicle.setpoint, self.settings
        self._approach = Arrival(setpoint.position, setpoint.yaw, self._time, self.arrival_radius,
                                 settings.orientation_th / 2, settings.hold_time, settings.stuck_time,
                                 time_unit="s of simulated time")
