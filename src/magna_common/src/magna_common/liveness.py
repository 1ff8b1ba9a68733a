"""Liveness of the UAV managers: each one beats in simulated time, and the ground station's watchdog
notices one that stops.

The contract (both sides import it from here): a manager publishes its simulated time on
`ros_names.manager_alive(id)` (std_msgs/Float64) every BEAT_PERIOD simulated seconds, from a timer
of its own, so a long control step does not delay it. `LivenessWatchdog` declares a watched manager
lost when it has been silent for SILENCE_LIMIT simulated seconds and

- its process is gone (killed, crashed) or stopped (SIGSTOP, a debugger): at once. A dead or frozen
  manager is so noticed within SILENCE_LIMIT plus one check period of simulated time;
- or its process still runs (or is not ours to look at) and the silence has also lasted WALL_GUARD
  wall seconds: at a high real-time factor a loaded machine can keep a live manager off the CPU for
  several simulated seconds, so silence in simulated time alone proves nothing about a running one.

No ROS here: the ground station feeds beats and the clocks, and passes the probe that looks at a
manager's process (`describe_process` for a subprocess it started).
"""
from __future__ import annotations

import math
import signal
import subprocess
import threading
from collections.abc import Callable
from dataclasses import dataclass

from magna_common.processes import process_state

BEAT_PERIOD = 0.2  # simulated s between two beats of a manager
SILENCE_LIMIT = 0.6  # simulated s of silence (three beats) before the process is looked at
WALL_GUARD = 2.0  # wall s of silence too, before a manager whose process runs is declared lost
CHECK_PERIOD = 0.1  # simulated s between two checks of the ground station

MANAGER_LOST = "manager_lost"  # the critical event's name


def describe_process(process: subprocess.Popen) -> str | None:
    """Why `process` cannot beat: "killed by SIGKILL", "exited with status 1", "stopped (frozen)"; None while
    it runs."""
    code = process.poll()
    if code is not None:
        if code < 0:
            try:
                return f"killed by {signal.Signals(-code).name}"
            except ValueError:
                return f"killed by signal {-code}"
        return f"exited with status {code}"
    state = process_state(process.pid)
    if state is None:
        return "gone"
    if state in ("T", "t"):
        return "stopped (frozen: SIGSTOP or a debugger)"
    return None


@dataclass(frozen=True)
class LostManager:
    """A manager the watchdog gave up on: when (simulated s), its last beat, and why."""

    uav_id: int
    noticed_at: float
    last_heard: float  # the simulated time of its last beat (or of the start of the watch)
    cause: str

    def describe(self) -> str:
        return (f"UAV {self.uav_id}'s manager lost at {self.noticed_at:.2f} s (silent since {self.last_heard:.2f} s): "
                f"{self.cause}")


@dataclass
class _Watched:
    last_beat: float  # simulated s
    last_beat_wall: float


class LivenessWatchdog:
    """Watches managers by their beats; `check` returns each newly lost one once.

    `probe(uav_id)` says why a manager's process cannot beat (see `describe_process`), or None when it
    runs or cannot be looked at. Thread-safe: beats come from subscriber threads, checks from a timer.
    """

    def __init__(self, probe: Callable[[int], str | None], silence_limit: float = SILENCE_LIMIT,
                 wall_guard: float = WALL_GUARD):
        if not silence_limit > 0 or not wall_guard >= 0:
            raise ValueError(f"silence_limit must be > 0 and wall_guard >= 0, got {silence_limit}, {wall_guard}")
        self.probe = probe
        self.silence_limit, self.wall_guard = silence_limit, wall_guard
        self._watched: dict[int, _Watched] = {}
        self._lost: dict[int, LostManager] = {}
        self._lock = threading.Lock()

    def watch(self, uav_id: int, sim_now: float, wall_now: float) -> None:
        """Start watching a manager that is up now (its silence counts from here)."""
        with self._lock:
            if uav_id not in self._lost:
                self._watched[uav_id] = _Watched(sim_now, wall_now)

    def heard(self, uav_id: int, stamp: float, wall_now: float) -> None:
        """A beat carrying the manager's simulated time `stamp`."""
        with self._lock:
            watched = self._watched.get(uav_id)
            if watched is not None and math.isfinite(stamp) and stamp >= watched.last_beat:
                watched.last_beat, watched.last_beat_wall = stamp, wall_now

    def stop(self) -> None:
        """Watch nothing any more (the mission ends and the managers are stopped on purpose)."""
        with self._lock:
            self._watched.clear()

    def lost(self, uav_id: int) -> LostManager | None:
        with self._lock:
            return self._lost.get(uav_id)

    def check(self, sim_now: float, wall_now: float) -> list[LostManager]:
        """The managers lost since the last check (each reported once, then no longer watched)."""
        with self._lock:
            silent = [(i, w) for i, w in self._watched.items() if sim_now - w.last_beat >= self.silence_limit]
        found = []
        for uav_id, watched in silent:
            cause = self.probe(uav_id)  # outside the lock: it reads /proc
            if cause is None:
                if wall_now - watched.last_beat_wall < self.wall_guard:
                    continue
                cause = (f"no beat for {sim_now - watched.last_beat:.1f} simulated s and "
                         f"{wall_now - watched.last_beat_wall:.1f} wall s, although its process runs")
            lost = LostManager(uav_id, sim_now, watched.last_beat, cause)
            with self._lock:
                if self._watched.pop(uav_id, None) is None:  # stopped meanwhile: the end, not a loss
                    continue
                self._lost[uav_id] = lost
            found.append(lost)
        return found
