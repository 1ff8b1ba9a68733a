"""Where the node's goals wait for its state machine: one at a time, the newest wins.

An action server's callback thread submits an `Order` and waits for its answer; the machine's
`idle` state takes the next order and its role answers it. A newer goal preempts the one that
is flying and any still waiting (the UAV does one thing at a time), and a die request preempts
everything and refuses what comes after. No ROS here: the node hands each order a callable that
says whether its client cancelled it.
"""
from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from magna_uav.manager import ABORTED, PREEMPTED, RoleResult


def _never() -> bool:
    return False


@dataclass
class Order:
    """A goal waiting for, or flown by, the state machine."""

    action: str
    goal: object
    cancelled: Callable[[], bool] = _never  # its client cancelled it, or the node is shutting down
    preempt: threading.Event = field(default_factory=threading.Event)
    sent_at: float = float("inf")  # sim time the ground station sent the goal (its goal id's stamp)
    done: threading.Event = field(default_factory=threading.Event)
    result: RoleResult | None = None

    def finish(self, result: RoleResult) -> None:
        self.result = result
        self.done.set()

    def preempt_requested(self) -> bool:
        return self.preempt.is_set() or self.cancelled()

    def wait(self, shutting_down: Callable[[], bool], poll: float = 0.1) -> RoleResult:
        """The order's result, once the machine gives it; a node shutting down answers aborted itself."""
        while not self.done.wait(poll):
            if shutting_down():
                self.finish(RoleResult(ABORTED, "the node is shutting down"))
        assert self.result is not None  # finish() sets it before it sets done
        return self.result


class OrderDesk:
    """Goals wait here for the machine; a new goal preempts the one flying and any still waiting."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._waiting: collections.deque[Order] = collections.deque()
        self.current: Order | None = None
        self.dying = False

    def submit(self, order: Order) -> None:
        with self._cond:
            if self.dying:
                order.finish(RoleResult(ABORTED, "the UAV manager is shutting down"))
                return
            for older in [self.current, *self._waiting]:
                if older is not None:
                    older.preempt.set()
            self._waiting.append(order)
            self._cond.notify_all()

    def take(self, timeout: float) -> Order | None:
        """The newest order not yet preempted (answering the older ones preempted), or None after `timeout` s."""
        with self._cond:
            if not self._waiting:
                self._cond.wait(timeout)
            while self._waiting:
                order = self._waiting.popleft()
                if not order.preempt.is_set():
                    self.current = order
                    return order
                order.finish(RoleResult(PREEMPTED, f"{order.action} replaced by a newer goal before it started"))
            return None

    def release(self, order: Order) -> None:
        with self._cond:
            if self.current is order:
                self.current = None

    def die(self) -> None:
        with self._cond:
            self.dying = True
            for order in [self.current, *self._waiting]:
                if order is not None:
                    order.preempt.set()
            self._cond.notify_all()
