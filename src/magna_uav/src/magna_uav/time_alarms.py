"""Alarms on simulated time: many threads wait for their instant at the cost of one watcher.

rospy wakes every thread that waits on simulated time at each /clock message (100 per simulated
second), whatever instant it waits for. A host of N managers, each waiting for its next control
tick, then does 100 N wake-ups per simulated second to act on 10 N of them. Here one watcher
wakes at each change of the time (`ring_due`), and each waiter only when its instant has come,
or when the time went back (a reset), which it must hear of at once.

No ROS here: `now` is the time source; the ROS side (magna_uav.ros_node) runs the watcher on
rospy's time-changed condition.
"""
from __future__ import annotations

import heapq
import itertools
import threading
from collections.abc import Callable


class Alarm:
    """One waiter's instant; `wait` returns True once it has rung."""

    __slots__ = ("target", "_rung")

    def __init__(self, target: float):
        self.target = target
        self._rung = threading.Event()

    def ring(self) -> None:
        self._rung.set()

    def wait(self, timeout: float) -> bool:
        return self._rung.wait(timeout)


class TimeAlarms:
    def __init__(self, now: Callable[[], float]):
        self._now = now
        self._lock = threading.Lock()
        self._due: list[tuple[float, int, Alarm]] = []  # a heap, soonest first
        self._order = itertools.count()  # ties ring in the order they were set
        self._latest = float("-inf")  # the time at the latest ring_due: a smaller one went back

    def set(self, target: float) -> Alarm | None:
        """An alarm for `target`; None when the time has reached it already."""
        with self._lock:
            if self._now() >= target:
                return None
            alarm = Alarm(target)
            heapq.heappush(self._due, (target, next(self._order), alarm))
            return alarm

    def ring_due(self) -> int:
        """Ring every alarm whose instant has come; every alarm when the time went back. Returns how many rang.
        Call it after each change of the time."""
        with self._lock:
            now = self._now()
            went_back, self._latest = now < self._latest, now
            rung = 0
            while self._due and (went_back or self._due[0][0] <= now):
                heapq.heappop(self._due)[2].ring()
                rung += 1
            return rung

    @property
    def waiting(self) -> int:
        with self._lock:
            return len(self._due)
