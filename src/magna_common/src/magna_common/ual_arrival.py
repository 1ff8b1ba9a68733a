"""When a take-off or a waypoint counts as reached, and when it is given up on: one rule for every UAL server.

Reached (GRVC UAL's referencePoseReached, stated as one rule): the vehicle has stayed within
`radius` of the target and its heading within `yaw_tolerance` of the target's for `hold_time`
without a break. UAL's defaults (position_th 0.33 m, orientation_th 0.65 rad) halve to the
defaults here. magna_sim's UAL and ual_mavlink both use this class, so a blocking call returns at
the same closeness whichever serves the UAV.

Given up on: the vehicle has come no `PROGRESS_STEP` nearer for `stuck_time` (blocked, a target
under the ground, an autopilot that ignores us), so a blocking call fails with the reason instead of
waiting for ever. Times are the caller's clock, in seconds.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

PROGRESS_STEP = 0.05  # m nearer than the best so far that counts as progress


class Arrival:
    def __init__(self, target: Sequence[float] | np.ndarray, yaw: float | None, now: float, radius: float = 0.165,
                 yaw_tolerance: float = 0.325, hold_time: float = 1.0, stuck_time: float = 10.0,
                 time_unit: str = "s"):
        self.target = tuple(float(c) for c in target)
        self.yaw = yaw  # None: any heading
        self.radius = radius
        self.yaw_tolerance = yaw_tolerance
        self.hold_time = hold_time
        self.stuck_time = stuck_time
        self.time_unit = time_unit  # how `stuck` names the clock: "s", "s of simulated time"
        self.arrived = False
        self.stuck: str | None = None  # why the target is given up on: "at (x, y, z), d m from ..."
        self._within_since: float | None = None
        self._best = math.inf
        self._best_time = now
        self._nearest = math.inf

    def update(self, position: Sequence[float] | np.ndarray, yaw: float, now: float) -> None:
        if self.arrived or self.stuck:
            return
        # Plain floats: a simulator calls this every physics step of every UAV flying to a target.
        x, y, z = float(position[0]), float(position[1]), float(position[2])
        tx, ty, tz = self.target
        distance = math.sqrt((tx - x) ** 2 + (ty - y) ** 2 + (tz - z) ** 2)
        heading_ok = self.yaw is None or abs((self.yaw - yaw + math.pi) % (2 * math.pi) - math.pi) <= self.yaw_tolerance
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
            where = ", ".join(f"{c:.2f}" for c in (x, y, z))
            goal = ", ".join(f"{c:.2f}" for c in self.target)
            self.stuck = (f"at ({where}), {distance:.2f} m from ({goal}), and has come no nearer in "
                          f"{self.stuck_time:g} {self.time_unit} (nearest {self._nearest:.2f} m; "
                          f"arrival needs {self.radius:g} m)")
