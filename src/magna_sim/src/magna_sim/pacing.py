"""Keeps simulated time at a chosen multiple of wall time (or lets it run free), and behind the controllers."""
from __future__ import annotations

import math
import time


def parse_real_time_factor(value) -> float:
    """1.0 = real time, 5 = five times faster, 0 / "max" / "inf" = as fast as possible (returns inf)."""
    if isinstance(value, str):
        text = value.strip().lower()
        if text in ("max", "inf", "fast", "0"):
            return math.inf
        try:
            value = float(text)
        except ValueError:
            raise ValueError(f"real_time_factor: {value!r} is not a number; use e.g. 1.0, 10 or max") from None
    value = float(value)
    if math.isnan(value) or value < 0:
        raise ValueError(f"real_time_factor: {value} must be positive (or 0 / max for as fast as possible)")
    return math.inf if value == 0 else value


class Pacer:
    """Sleeps so that sim time t is reached no earlier than t / factor of wall time after start."""

    # Further behind than this and we stop trying to catch up (a paused debugger, a slow step burst).
    MAX_LAG = 0.5

    def __init__(self, factor: float, clock=time.monotonic, sleep=time.sleep):
        self.factor = factor
        self._clock = clock
        self._sleep = sleep
        self._wall_start = None
        self._sim_start = 0.0

    def restart(self) -> None:
        """Forget the past: the next `wait` starts a new reference (after a pause, for instance)."""
        self._wall_start = None

    def wait(self, sim_time: float) -> None:
        if math.isinf(self.factor):
            return
        now = self._clock()
        if self._wall_start is None:
            self._wall_start, self._sim_start = now, sim_time
            return
        due = self._wall_start + (sim_time - self._sim_start) / self.factor
        if due > now:
            self._sleep(due - now)
        elif now - due > self.MAX_LAG:
            self._wall_start, self._sim_start = now, sim_time


class Hold:
    """Whether the simulation is paused: time stands still while nodes start and UAVs are spawned.

    Set from service threads, read by the simulation loop. Each change is counted so that the
    loop can tell that a pause happened between two of its looks (and restart its pacing).
    """

    def __init__(self, paused: bool = False):
        self._paused = bool(paused)
        self.changes = 0

    @property
    def paused(self) -> bool:
        return self._paused

    def set(self, paused: bool, sim_time: float) -> str:
        """Pause (True) or resume (False); say what happened, at which simulated time."""
        paused = bool(paused)
        if paused == self._paused:
            return f"already {'paused' if paused else 'running'} at t={sim_time:.3f} s"
        self._paused = paused
        self.changes += 1
        return f"{'paused' if paused else 'resumed'} at t={sim_time:.3f} s"


class Lockstep:
    """Keeps the simulation from running ahead of the controllers that fly its UAVs.

    At rtf max nothing else limits the simulator: on a loaded machine (ten UAV managers on two
    cores) it outran them, and they flew on stale poses, 3 to 7 control steps per simulated
    second instead of 10. Each UAV manager announces the simulated time of every control step
    while it flies a role (`heard`), and a negative time when it stops stepping. The loop asks
    `holds(next_time)` before each physics step: it holds while an engaged controller's last
    step is more than `lead` seconds behind. A controller that stays silent for `timeout` wall
    seconds (a dead or stuck process) is let go, so that it cannot freeze the simulation; it
    is engaged again by its next step.
    """

    def __init__(self, lead: float = 0.15, timeout: float = 1.0, clock=time.monotonic):
        if not (math.isfinite(lead) and lead > 0):
            raise ValueError(f"~lockstep_lead: {lead} must be a positive number of simulated seconds")
        if not (math.isfinite(timeout) and timeout > 0):
            raise ValueError(f"~lockstep_timeout: {timeout} must be a positive number of wall seconds")
        self.lead, self.timeout, self._clock = lead, timeout, clock
        self._last: dict[int, tuple[float, float]] = {}  # id -> (simulated time of its last step, wall time heard)
        self.let_go: list[int] = []  # controllers released by the timeout, for the caller to report

    def heard(self, uav_id: int, sim_time: float) -> None:
        """A control step at `sim_time` (negative: the controller stopped stepping)."""
        if sim_time < 0:
            self._last.pop(uav_id, None)
        else:
            self._last[uav_id] = (sim_time, self._clock())

    def forget(self, uav_id: int) -> None:
        self._last.pop(uav_id, None)

    def holds(self, next_time: float) -> bool:
        """True while some engaged controller is too far behind `next_time` (and not yet given up on)."""
        now = self._clock()
        holding = False
        for uav_id, (last, wall) in list(self._last.items()):
            if next_time <= last + self.lead:
                continue
            if now - wall > self.timeout:
                self._last.pop(uav_id, None)
                self.let_go.append(uav_id)
                continue
            holding = True
        return holding
