"""One simulated UAV as the rest of the simulator sees it, and the flight-model contract.

A `Vehicle` holds what is known about a UAV at the current step (pose, twist),
what it was told to do (`Setpoint`), and the pybullet body that stands for it.
A flight model moves a group of vehicles of its kind each physics step:

    model.apply_controls(vehicles, velocity_commands, yaw_rate_commands)   # before stepSimulation
    model.read_state(vehicles)                                           # after stepSimulation

`guidance.velocity_commands` turns setpoints into the velocity and yaw-rate
commands for every vehicle at once, so both multirotor models track the same
references. A fixed wing flies its setpoints itself: `model.apply_controls(vehicles)`.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol, TypeAlias

import numpy as np

from magna_common.airframes import Airframe


class SetpointMode(enum.IntEnum):
    OFF = 0  # motors off: on the ground, nothing commanded
    POSITION = 1  # fly to `position` with heading `yaw`
    VELOCITY = 2  # track `velocity` (map frame) and `yaw_rate`


class Manoeuvre(enum.IntEnum):
    """What a POSITION setpoint is for. Multirotors fly them all alike; a fixed wing cannot hover,
    so it climbs out along its heading to take off and glides down a slope to land."""

    GOTO = 0  # fly to `position` and hold there
    TAKE_OFF = 1  # climb to `position[2]`
    LAND = 2  # descend to the ground


@dataclass
class Setpoint:
    mode: SetpointMode = SetpointMode.OFF
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw: float = 0.0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw_rate: float = 0.0
    # Vertical speed cap for this manoeuvre (take-off and landing are gentler); None = airframe limit.
    max_vertical_speed: float | None = None
    manoeuvre: Manoeuvre = Manoeuvre.GOTO


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Heading (rotation about z) of a quaternion; a zero quaternion reads as 0, as UAL treats it."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class Vehicle:
    """A UAV in the world. Arrays are in the map frame; the body origin is the bottom centre."""

    def __init__(self, name: str, uav_id: int, airframe: Airframe, flight_model: str, body_id: int = -1,
                 position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0)):
        self.name = name  # model name, e.g. "uav_1"
        self.uav_id = uav_id
        self.airframe = airframe
        self.flight_model = flight_model  # "light", "dynamic" or "fixed_wing"
        self.body_id = body_id  # pybullet body, set by the world
        self.position = np.array(position, dtype=float)
        self.orientation = np.array(orientation, dtype=float)  # quaternion x y z w; sets yaw too
        self.velocity = np.zeros(3)
        self.angular_velocity = np.zeros(3)
        self.setpoint = Setpoint()

    @property
    def orientation(self) -> np.ndarray:
        return self._orientation

    @orientation.setter
    def orientation(self, quaternion) -> None:
        # The heading is read many times per step (guidance, UAL checks): work it out once per change.
        self._orientation = quaternion
        self.yaw = yaw_from_quaternion(*quaternion)

    def set_attitude(self, orientation: np.ndarray, yaw: float) -> None:
        """Set the orientation when the caller already knows its yaw (saves the setter's atan2)."""
        self._orientation, self.yaw = orientation, yaw

    @property
    def motors_on(self) -> bool:
        return self.setpoint.mode != SetpointMode.OFF


class _FlightModelBase(Protocol):
    name: str

    def attach(self, vehicle: Vehicle) -> None:
        """Called once after the world created the vehicle's body."""

    def detach(self, vehicle: Vehicle) -> None:
        """Called before the world removes the vehicle's body."""

    def read_state(self, vehicles: Sequence[Vehicle]) -> None:
        """After a physics step: refresh each vehicle's pose and twist from what happened."""


class GuidedFlightModel(_FlightModelBase, Protocol):
    """A model the world hands guidance.velocity_commands (light.LightModel, quadrotor.QuadrotorModel)."""

    follows_guidance: Literal[True]

    def apply_controls(self, vehicles: Sequence[Vehicle], velocity_commands: np.ndarray,
                       yaw_rate_commands: np.ndarray) -> None:
        """Before a physics step: move or push every vehicle toward its commands (N x 3, N)."""


class SelfGuidedFlightModel(_FlightModelBase, Protocol):
    """A model that flies the setpoints itself (fixed_wing.FixedWingModel: a fixed wing cannot follow a
    multirotor's velocity reference)."""

    follows_guidance: Literal[False]

    def apply_controls(self, vehicles: Sequence[Vehicle]) -> None:
        """Before a physics step: move every vehicle toward its setpoint."""


# What the world needs from a flight model; `follows_guidance` tells the two kinds apart.
FlightModel: TypeAlias = GuidedFlightModel | SelfGuidedFlightModel
