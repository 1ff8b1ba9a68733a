"""Hands work from ROS callback threads to the simulation thread, and waits for results.

The simulation loop owns the world and is the only thread that touches it.
A service thread calls `run(fn)`: fn runs in the loop between two physics
steps and its result (or exception) comes back to the caller. `wait_for(check)`
blocks a caller until `check()`, evaluated by the loop after each step, returns
a value other than None. Queueing instead of sharing a lock means a loop running
as fast as possible cannot starve the callers.
"""
from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable
from typing import Any


class LoopStopped(RuntimeError):
    """The simulation loop ended before the request finished."""


class _Ticket:
    __slots__ = ("fn", "done", "result", "error")

    def __init__(self, fn: Callable[[], Any]) -> None:
        self.fn = fn
        self.done = threading.Event()
        self.result: Any = None
        self.error: BaseException | None = None


class CommandQueue:
    def __init__(self) -> None:
        self._jobs: collections.deque[_Ticket] = collections.deque()
        self._waiters: list[_Ticket] = []
        self._waiters_lock = threading.Lock()
        self._stopped = False

    # --- callers (any thread) --------------------------------------------------------------------------------
    def run(self, fn: Callable[[], Any], timeout: float | None = None) -> Any:
        return self._await(self._jobs, _Ticket(fn), timeout)

    def wait_for(self, check: Callable[[], Any], timeout: float | None = None) -> Any:
        """Block until check() returns non-None (that value is returned) or raises (re-raised here)."""
        ticket = _Ticket(check)
        with self._waiters_lock:
            self._waiters.append(ticket)
        return self._await(None, ticket, timeout)

    # --- the simulation loop ---------------------------------------------------------------------------------
    def run_pending(self) -> None:
        """Run the queued jobs; call between physics steps."""
        while self._jobs:
            ticket = self._jobs.popleft()
            try:
                ticket.result = ticket.fn()
            except Exception as err:  # handed to the caller, who reports it
                ticket.error = err
            ticket.done.set()

    def check_waiters(self) -> None:
        """Evaluate every waiting check; call after each physics step."""
        if not self._waiters:
            return
        with self._waiters_lock:
            waiting = self._waiters
            self._waiters = []
        still = []
        for ticket in waiting:
            try:
                value = ticket.fn()
            except Exception as err:
                ticket.error = err
                ticket.done.set()
                continue
            if value is None:
                still.append(ticket)
            else:
                ticket.result = value
                ticket.done.set()
        with self._waiters_lock:
            self._waiters.extend(still)

    def release_waiters(self, reason: str) -> None:
        """Fail every caller still waiting for a check with LoopStopped(reason); the queue goes on serving.

        For a reset: the checks look at a world that is gone, and would never come true."""
        with self._waiters_lock:
            waiting, self._waiters = self._waiters, []
        for ticket in waiting:
            ticket.error = LoopStopped(reason)
            ticket.done.set()

    def stop(self, reason: str = "the simulation stopped") -> None:
        """Release every caller with LoopStopped; later calls fail at once."""
        self._stopped = True
        with self._waiters_lock:
            pending = list(self._jobs) + self._waiters
            self._jobs.clear()
            self._waiters = []
        for ticket in pending:
            ticket.error = LoopStopped(reason)
            ticket.done.set()

    def _await(self, queue, ticket: _Ticket, timeout: float | None) -> Any:
        if self._stopped:
            raise LoopStopped("the simulation is not running")
        if queue is not None:
            queue.append(ticket)
        deadline = None if timeout is None else time.monotonic() + timeout
        while not ticket.done.wait(0.2):
            if self._stopped:  # stop() raced with this call
                raise LoopStopped("the simulation stopped")
            if deadline is not None and time.monotonic() > deadline:
                with self._waiters_lock:
                    if ticket in self._waiters:
                        self._waiters.remove(ticket)
                raise TimeoutError(f"no answer from the simulation loop within {timeout} s")
        if ticket.error is not None:
            raise ticket.error
        return ticket.result
