"""The kinematic "light" flight model, in the spirit of UAL's light backend.

The velocity follows the command through a first-order lag (the airframe's
velocity_time_constant) and the yaw follows the yaw-rate command; the pose is
integrated here and written into pybullet, which then only detects contacts.
The ground is a floor: a light UAV never sinks below z = 0.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import pybullet as p

from .guidance import airframe_limits
from .vehicle import Vehicle


class LightModel:
    name = "light"
    follows_guidance: Literal[True] = True

    def __init__(self, client: int, physics_dt: float):
        self.client = client
        self.dt = physics_dt
        self._blend_key: tuple[int, ...] = ()
        self._blend_value = np.zeros(0)

    def attach(self, vehicle: Vehicle) -> None:
        if vehicle.airframe.limits is None:
            raise ValueError(f"{vehicle.airframe.source}: 'limits': missing; the light model needs the speed limits")

    def detach(self, vehicle: Vehicle) -> None:
        pass

    def apply_controls(self, vehicles: Sequence[Vehicle], velocity_commands: np.ndarray,
                       yaw_rate_commands: np.ndarray) -> None:
        if not vehicles:
            return
        blend = self._blend(vehicles)
        velocity = np.array([v.velocity for v in vehicles])
        velocity += (velocity_commands - velocity) * blend[:, None]
        position = np.array([v.position for v in vehicles]) + velocity * self.dt
        on_floor = position[:, 2] < 0.0
        position[on_floor, 2] = 0.0
        velocity[on_floor, 2] = np.maximum(velocity[on_floor, 2], 0.0)
        yaw = np.array([v.yaw for v in vehicles]) + yaw_rate_commands * self.dt
        orientation = np.zeros((len(vehicles), 4))
        orientation[:, 2], orientation[:, 3] = np.sin(0.5 * yaw), np.cos(0.5 * yaw)
        spin = np.zeros((len(vehicles), 3))
        spin[:, 2] = yaw_rate_commands
        for i, vehicle in enumerate(vehicles):
            vehicle.position = position[i]
            vehicle.velocity = velocity[i]
            vehicle.set_attitude(orientation[i], yaw[i])
            vehicle.angular_velocity = spin[i]
            # Bodies are placed, not pushed: pybullet only tells us what they touch.
            p.resetBasePositionAndOrientation(vehicle.body_id, position[i], vehicle.orientation,
                                              physicsClientId=self.client)
            p.resetBaseVelocity(vehicle.body_id, velocity[i], vehicle.angular_velocity, physicsClientId=self.client)

    def _blend(self, vehicles: Sequence[Vehicle]) -> np.ndarray:
        """Per-step weight of the first-order lag, cached while the group stays the same."""
        key = tuple(id(v.airframe) for v in vehicles)
        if key != self._blend_key:
            tau = np.array([airframe_limits(v.airframe).velocity_time_constant for v in vehicles])
            self._blend_value = 1.0 - np.exp(-self.dt / np.maximum(tau, 1e-6))
            self._blend_key = key
        return self._blend_value

    def read_state(self, vehicles: Sequence[Vehicle]) -> None:
        pass  # the state is ours; contacts do not push a light UAV
