"""What the UAL streams to the autopilot at every tick (30 Hz), kept apart from the thread that sends it.

PX4 leaves OFFBOARD when set-points stop, so the UAL sends one on every tick whatever the callers
do. The latest command wins: a position (a waypoint, a set_pose) is held until replaced; a velocity
(set_velocity) must be renewed, and one older than VELOCITY_TIMEOUT becomes a hold at the position
the vehicle had when the timeout was noticed, as GRVC UAL does, so a caller that dies does not leave
the UAV flying on.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STREAM_RATE = 30.0  # Hz: PX4 wants more than 2 Hz; UAL streams at 30
VELOCITY_TIMEOUT = 0.5  # s without a new set_velocity before the UAV holds where it is


@dataclass(frozen=True)
class SetPoint:
    kind: str  # "position" or "velocity"
    vector: np.ndarray  # ENU: metres, or metres per second
    yaw: float | None = None  # ENU heading to hold (positions), None to keep the current one
    yaw_rate: float = 0.0  # ENU yaw rate (velocities), rad/s, anticlockwise


class SetPointStream:
    """The latest command and what it means at a given time; times are the caller's clock, in s."""

    def __init__(self, velocity_timeout: float = VELOCITY_TIMEOUT):
        self.velocity_timeout = velocity_timeout
        self._latest: SetPoint | None = None
        self._velocity_time = 0.0

    def hold(self, position, yaw: float | None = None) -> None:
        """Fly to and hold `position` (go_to_waypoint, set_pose, take-off target, a velocity's end)."""
        self._latest = SetPoint("position", np.asarray(position, dtype=float), yaw)

    def velocity(self, velocity, now: float, yaw_rate: float = 0.0) -> None:
        """Fly at `velocity` (turning at `yaw_rate`) until it is renewed or VELOCITY_TIMEOUT passes."""
        self._latest = SetPoint("velocity", np.asarray(velocity, dtype=float), yaw_rate=float(yaw_rate))
        self._velocity_time = now

    def clear(self) -> None:
        """Nothing to stream (landed, or the pilot has the vehicle)."""
        self._latest = None

    @property
    def latest(self) -> SetPoint | None:
        return self._latest

    def at(self, now: float, position, yaw: float | None = None) -> SetPoint | None:
        """The set-point to send now; `position` (and `yaw`) are the vehicle's, held when a velocity has expired."""
        latest = self._latest
        if latest is not None and latest.kind == "velocity" and now - self._velocity_time > self.velocity_timeout:
            self.hold(position, yaw)
            latest = self._latest
        return latest
