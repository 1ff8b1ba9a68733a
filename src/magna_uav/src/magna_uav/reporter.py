"""State actualizations to the ground station, sent from a thread so the control loop never waits.

The node reports `idle`, the action it starts and `{action}_{outcome}`, each with the critical
event it saw (empty when none), in the order reported. No ROS here: the node passes the ground
station's service as a callable, `call(id=, state=, critical_event=)` answering with `success`
and `message`, and the exceptions that mean no ground station serves it (a manager may fly
without one; those reports are dropped).
"""
from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Protocol


def _silent(message: str) -> None:
    pass


class Answer(Protocol):
    """The ground station's answer (a StateActualizationResponse)."""

    @property
    def success(self) -> bool: ...

    @property
    def message(self) -> str: ...


class Reporter:
    def __init__(self, uav_id: int, call: Callable[..., Answer], running: Callable[[], bool],
                 unreachable: tuple[type[BaseException], ...], warn: Callable[[str], None] = _silent,
                 debug: Callable[[str], None] = _silent, poll: float = 0.5):
        self.uav_id = uav_id
        self._call, self._running, self._unreachable = call, running, unreachable
        self._warn, self._debug, self._poll = warn, debug, poll
        self._queue: queue.Queue[tuple[str, str]] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name=f"uav_{uav_id}_reporter", daemon=True)
        self._thread.start()

    def report(self, state: str, critical_event: str = "") -> None:
        self._queue.put((state, critical_event))

    def _run(self) -> None:
        while self._running():
            try:
                state, event = self._queue.get(timeout=self._poll)
            except queue.Empty:
                continue
            try:
                answer = self._call(id=self.uav_id, state=state, critical_event=event)
            except self._unreachable:
                self._debug(f"no ground station to report {state!r} to")
                continue
            if not answer.success:
                self._warn(f"ground station refused the state of UAV {self.uav_id}: {answer.message}")
