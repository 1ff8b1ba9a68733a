"""Setpoints -> velocity and yaw-rate commands, for every vehicle at once.

Position setpoints become a proportional velocity toward the target, capped by
the airframe's horizontal and vertical speed limits (or the manoeuvre's own
vertical cap); velocity setpoints are only capped. Both flight models track the
result, so a UAV flies the same path in the light and the dynamic model.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from magna_common.airframes import Airframe, AirframeError, Limits

from .vehicle import SetpointMode, Vehicle

POSITION_GAIN = 1.0  # 1/s: with the light model's 0.3 s lag this is close to critically damped
YAW_GAIN = 2.0  # 1/s


def wrap_angle(angle):
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def airframe_limits(airframe: Airframe) -> Limits:
    """The airframe's speed limits, which a multirotor is flown with (its flight models refuse it without them)."""
    if airframe.limits is None:
        raise AirframeError(f"{airframe.source}: 'limits': missing; a multirotor is flown within its speed limits")
    return airframe.limits


class _GroupLimits:
    """The airframe limits of one group of vehicles, as arrays."""

    def __init__(self, vehicles: Sequence[Vehicle]):
        limits = [airframe_limits(v.airframe) for v in vehicles]
        self.max_xy = np.array([lim.max_horizontal_speed for lim in limits])
        self.max_z = np.array([lim.max_vertical_speed for lim in limits])
        self.max_yaw_rate = np.array([lim.max_yaw_rate for lim in limits])


# Built once per group of airframes: gathering them every step would cost more than the maths.
_limits_cache: dict[tuple[int, ...], _GroupLimits] = {}


def _group_limits(vehicles: Sequence[Vehicle]) -> _GroupLimits:
    key = tuple(id(v.airframe) for v in vehicles)
    if key not in _limits_cache:
        if len(_limits_cache) > 64:
            _limits_cache.clear()
        _limits_cache[key] = _GroupLimits(vehicles)
    return _limits_cache[key]


def velocity_commands(vehicles: Sequence[Vehicle]) -> tuple[np.ndarray, np.ndarray]:
    n = len(vehicles)
    if n == 0:
        return np.zeros((0, 3)), np.zeros(0)
    limits = _group_limits(vehicles)
    setpoints = [v.setpoint for v in vehicles]
    mode = np.array([s.mode for s in setpoints])
    position = np.array([v.position for v in vehicles])
    target = np.array([s.position for s in setpoints])
    commanded = np.array([s.velocity for s in setpoints])
    yaw = np.array([v.yaw for v in vehicles])
    target_yaw = np.array([s.yaw for s in setpoints])
    commanded_yaw_rate = np.array([s.yaw_rate for s in setpoints])
    max_z = limits.max_z
    if any(s.max_vertical_speed for s in setpoints):
        max_z = np.array([s.max_vertical_speed or m for s, m in zip(setpoints, max_z, strict=True)])

    is_position = mode == SetpointMode.POSITION
    is_velocity = mode == SetpointMode.VELOCITY
    velocity = np.where(is_position[:, None], POSITION_GAIN * (target - position), 0.0)
    velocity = np.where(is_velocity[:, None], commanded, velocity)
    velocity = cap_velocity(velocity, limits.max_xy, max_z)

    yaw_rate = np.where(is_position, YAW_GAIN * wrap_angle(target_yaw - yaw), 0.0)
    yaw_rate = np.where(is_velocity, commanded_yaw_rate, yaw_rate)
    return velocity, np.clip(yaw_rate, -limits.max_yaw_rate, limits.max_yaw_rate)


def cap_velocity(velocity: np.ndarray, max_horizontal: np.ndarray, max_vertical: np.ndarray) -> np.ndarray:
    """Scale the horizontal part down to its limit (keeping the direction) and clip the vertical part."""
    horizontal = np.linalg.norm(velocity[:, :2], axis=1)
    scale = np.minimum(1.0, max_horizontal / np.maximum(horizontal, 1e-12))
    capped = velocity.copy()
    capped[:, :2] *= scale[:, None]
    capped[:, 2] = np.clip(velocity[:, 2], -max_vertical, max_vertical)
    return capped
