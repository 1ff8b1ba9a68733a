"""The first moments of the action goals an operator command sent: did a UAV manager end one at once?

The ground station answers an operator (/magna/gs/command) only after its goals have had a moment
with their managers: a manager ends a goal it cannot fly `aborted` straight away, with the reason as
the result's `message` (magna_uav.ros_node; e.g. "basic_move: UAL refused: go_to_waypoint refused:
UAV 1 is LANDING"), and the answer must say so rather than "accepted". `CommandGoals` sends each goal
with callbacks and `refusals` waits, `bound` wall seconds at most, until every goal is done or past
its first control step. A manager sends a step's feedback after carrying the step out (its UAL
command sent, or refused) and, when the step ended the goal, the result right after: so a goal is
past its first step at its second feedback, or `GRACE` s after its first. A goal still running when
the wait ends counts as taken. Only steps with a target send feedback: a take-off's first one, every
step of a move, turn or follow, none of a landing's, whose wait is the whole bound unless it ends.
"""
from __future__ import annotations

import functools
import math
import threading
import time
from dataclasses import dataclass

from actionlib_msgs.msg import GoalStatus

WAIT = 1.0  # wall s: the most an operator's answer waits for its goals
SETTLED_STEPS = 2  # feedback messages after which a goal counts as taken
GRACE = 0.2  # wall s after a goal's first feedback for a result that step ended it with


@dataclass
class Watched:
    uav_id: int
    verb: str  # "move", "take off": for the answer
    status: int | None = None  # GoalStatus once done
    reason: str = ""  # the result's message
    steps: int = 0  # feedback heard
    first_step_at: float | None = None  # time.monotonic() of the first feedback

    def settled_at(self) -> float:
        """When (time.monotonic()) it counts as settled: -inf once done or past SETTLED_STEPS, the end of its
        GRACE after one feedback, inf while nothing is known."""
        if self.status is not None or self.steps >= SETTLED_STEPS:
            return -math.inf
        return math.inf if self.first_step_at is None else self.first_step_at + GRACE


class CommandGoals:
    """The goals of one operator command; `send` them, then ask for their `refusals`."""

    def __init__(self, bound: float = WAIT):
        self.bound = bound
        self.watched: list[Watched] = []
        self.waited_out = False  # did the last `refusals` end because the bound was over (not every goal settled)?
        self._changed = threading.Condition()

    def send(self, client, goal, uav_id: int, verb: str) -> None:
        """Send `goal` through `client` (a SimpleActionClient) and watch it."""
        watched = Watched(uav_id, verb)
        with self._changed:
            self.watched.append(watched)
        client.send_goal(goal, done_cb=functools.partial(self._done, watched),
                         feedback_cb=functools.partial(self._feedback, watched))

    def _done(self, watched: Watched, status: int, result) -> None:
        with self._changed:
            watched.status, watched.reason = status, str(getattr(result, "message", "") or "")
            self._changed.notify_all()

    def _feedback(self, watched: Watched, _feedback) -> None:
        with self._changed:
            watched.steps += 1
            if watched.first_step_at is None:
                watched.first_step_at = time.monotonic()
            self._changed.notify_all()

    def refusals(self) -> list[Watched]:
        """The goals a manager rejected or aborted within `bound` wall seconds of now (waiting no longer than
        needed: until each is done or settled)."""
        deadline = time.monotonic() + self.bound
        with self._changed:
            self.waited_out = False
            while self.watched:
                now = time.monotonic()
                settled = max(w.settled_at() for w in self.watched)
                if settled <= now:
                    break
                if deadline <= now:
                    self.waited_out = True
                    break
                self._changed.wait(min(settled, deadline) - now)
            return [w for w in self.watched if w.status in (GoalStatus.ABORTED, GoalStatus.REJECTED)]


def refusal_message(refused: list[Watched], taken: list[str]) -> str:
    """The answer when managers ended goals at once: each UAV and its manager's reason, then what still goes
    on (`taken`: the sentences of the other UAVs' orders)."""
    parts = [f"UAV {w.uav_id} could not {w.verb}: {w.reason or 'its manager ended the goal at once'}"
             for w in refused]
    if taken:
        parts.append("still sent: " + "; ".join(taken))
    return "; ".join(parts)
