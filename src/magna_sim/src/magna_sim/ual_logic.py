"""The UAL state machine of one UAV, and what each UAL command does to its setpoint.

    UNINITIALIZED -> LANDED_ARMED -> TAKING_OFF -> FLYING_AUTO -> LANDING -> LANDED_ARMED

Commands are checked here and refused with `CommandRefused` (the message says
why and what state would accept it); the ROS layer turns that into a failed
service call. `update` advances the machine after each physics step.
Every accepted command bumps `command_id`, so a blocking call can tell when a
newer command took its place.

A fixed wing (an airframe with a fixed_wing block) runs the same machine; only what
counts as done differs, because it cannot stop: a waypoint is reached once the plane
circles it on its loiter circle, and a landing ends when the plane has rolled to a stop.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

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


class CommandRefused(ValueError):
    """A UAL command that cannot be done now; the message is for the caller."""


@dataclass(frozen=True)
class UalSettings:
    position_th: float = 0.33  # m: a waypoint counts as reached (UAL's default)
    orientation_th: float = 0.65  # rad
    take_off_speed: float = 1.0  # m/s
    land_speed: float = 0.6  # m/s
    velocity_timeout: float = 1.0  # s of sim time without set_velocity before holding position; 0 = never
    landed_height: float = 0.05  # m above the ground that counts as touched down


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

    # --- commands --------------------------------------------------------------------------------------------
    def take_off(self, height: float) -> None:
        _require_finite("height", height)
        if height <= 0.0:
            raise CommandRefused(f"take_off: height must be positive, got {height}")
        self._require(UalState.LANDED_ARMED, "take_off")
        target = self.vehicle.position + np.array([0.0, 0.0, height])
        self._command(Setpoint(SetpointMode.POSITION, position=target, yaw=self.vehicle.yaw,
                               max_vertical_speed=self.settings.take_off_speed, manoeuvre=Manoeuvre.TAKE_OFF))
        self.state = UalState.TAKING_OFF

    def land(self) -> None:
        self._require(UalState.FLYING_AUTO, "land")
        self._start_landing()

    def go_to(self, position, yaw: float) -> None:
        position = _finite_vector("waypoint.pose.position", position)
        _require_finite("waypoint orientation (yaw)", yaw)
        self._require(UalState.FLYING_AUTO, "go_to_waypoint")
        self._command(Setpoint(SetpointMode.POSITION, position=position, yaw=yaw))

    def failsafe_land(self) -> None:
        """Land whatever was commanded (empty battery); the commander sees LANDING."""
        self._start_landing()

    def set_pose(self, position, yaw: float) -> None:
        """Streamed position setpoint; refused (the ROS layer only warns) unless FLYING_AUTO."""
        position = _finite_vector("set_pose position", position)
        _require_finite("set_pose orientation (yaw)", yaw)
        self._require(UalState.FLYING_AUTO, "set_pose")
        self._command(Setpoint(SetpointMode.POSITION, position=position, yaw=yaw))

    def set_velocity(self, velocity, yaw_rate: float) -> None:
        velocity = _finite_vector("set_velocity linear", velocity)
        _require_finite("set_velocity angular.z", yaw_rate)
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

    # --- progress --------------------------------------------------------------------------------------------
    def update(self, time: float) -> None:
        """Called after every physics step with the sim time."""
        self._time = time
        vehicle, state = self.vehicle, self.state
        if state == UalState.UNINITIALIZED:
            self.state = UalState.LANDED_ARMED
        elif state == UalState.TAKING_OFF:
            if abs(vehicle.position[2] - vehicle.setpoint.position[2]) < self.settings.position_th / 2:
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
        """Is the current position setpoint reached within UAL's thresholds?"""
        setpoint = self.vehicle.setpoint
        if setpoint.mode != SetpointMode.POSITION:
            return False
        if self._fixed_wing is not None:  # it circles the point; its heading is its course
            return fixed_wing.on_station(self._fixed_wing, setpoint.position, self.vehicle.position,
                                         self.settings.position_th)
        distance = np.linalg.norm(setpoint.position - self.vehicle.position)
        heading = abs(float((setpoint.yaw - self.vehicle.yaw + math.pi) % (2 * math.pi) - math.pi))
        return distance < self.settings.position_th and heading < self.settings.orientation_th

    # --- helpers ---------------------------------------------------------------------------------------------
    def _require(self, state: UalState, command: str) -> None:
        if self.state != state:
            raise CommandRefused(f"{command} refused: UAV {self.vehicle.uav_id} is {self.state.name}; "
                                 f"{command} needs {state.name}")

    def _start_landing(self) -> None:
        # Aim below the floor so the descent never stalls just above it; touching down ends it.
        target = np.array([self.vehicle.position[0], self.vehicle.position[1], -1.0])
        self._command(Setpoint(SetpointMode.POSITION, position=target, yaw=self.vehicle.yaw,
                               max_vertical_speed=self.settings.land_speed, manoeuvre=Manoeuvre.LAND))
        self.state = UalState.LANDING

    def _command(self, setpoint: Setpoint) -> None:
        self.vehicle.setpoint = setpoint
        self.command_id += 1

    def _hold_here(self) -> None:
        self.vehicle.setpoint = Setpoint(SetpointMode.POSITION, position=self.vehicle.position.copy(),
                                         yaw=self.vehicle.yaw)
        self.command_id += 1


def _require_finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise CommandRefused(f"{name}: {value} is not a finite number")


def _finite_vector(name: str, values) -> np.ndarray:
    vector = np.asarray(values, dtype=float)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise CommandRefused(f"{name}: {np.ravel(vector).tolist()} is not three finite numbers")
    return vector
