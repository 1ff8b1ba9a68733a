"""When a take-off or a waypoint counts as reached, and when it is given up on.

Reached (UAL's referencePoseReached, stated as one rule): the vehicle has stayed within
`position_th / 2` of the target and its heading within `orientation_th / 2` of the target's for
`hold_time` without a break. UAL's defaults are position_th 0.33 m and orientation_th 0.65 rad;
magna_sim uses the same rule, so a blocking call returns at the same closeness on both.

Given up on: the vehicle has come no `PROGRESS_STEP` nearer for `stuck_time` (blocked, a target
under the ground, an autopilot that ignores us), so a blocking call fails with the reason instead of
waiting for ever. Times are the caller's clock, in seconds.
"""
from __future__ import annotations

import math

import numpy as np

from .frames import wrap_angle

PROGRESS_STEP = 0.05  # m nearer than the best so far that counts as progress


class Arrival:
    def __init__(self, target, yaw: float | None, now: float, position_th: float = 0.33,
                 orientation_th: float = 0.65, hold_time: float = 1.0, stuck_time: float = 10.0):
        self.target = np.asarray(target, dtype=float)
        self.yaw = yaw  # None: any heading
        self.radius = position_th / 2.0
        self.yaw_tolerance = orientation_th / 2.0
        self.hold_time = hold_time
        self.stuck_time = stuck_time
        self.arrived = False
        self.stuck: str | None = None
        self._within_since: float | None = None
        self._best = math.inf
        self._best_time = now
        self._nearest = math.inf

    def update(self, position, yaw: float, now: float) -> None:
        if self.arrived or self.stuck:
            return
        position = np.asarray(position, dtype=float)
        distance = float(np.linalg.norm(self.target - position))
        heading_ok = self.yaw is None or abs(wrap_angle(self.yaw - yaw)) <= self.yaw_tolerance
        inside = distance <= self.radius
        if inside and heading_ok:
            if self._within_since is None:
                self._within_since = now
            if now - self._within_since >= self.hold_time:
                self.arrived = True
                return
        else:
            self._within_since = None
        self._nearest = min(self._nearest, distance)
        if inside or distance < self._best - PROGRESS_STEP:
            self._best, self._best_time = distance, now
        if self.stuck_time > 0 and now - self._best_time > self.stuck_time:
            where = ", ".join(f"{c:.2f}" for c in position)
            goal = ", ".join(f"{c:.2f}" for c in self.target)
            self.stuck = (f"at ({where}), {distance:.2f} m from ({goal}), and has come no nearer in "
                          f"{self.stuck_time:g} s (nearest {self._nearest:.2f} m; arrival needs {self.radius:g} m)")
