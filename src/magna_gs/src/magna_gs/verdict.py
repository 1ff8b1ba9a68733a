"""The actions that failed in a mission, and what they do to the ground station's verdict.

A mission may end `completed` although an action failed on the way: the original's Concurrence ends
`completed` when its children end mixed (one UAV's take-off aborted, the other's succeeded), and a
mission may map an aborted action to its next state. So, as a critical event does, every action that
ended aborted (the UAL refused it, or it failed) makes the mission not a success, and result.json's
message names it with its reason. No ROS here: the ground station's states gather them.
"""
from __future__ import annotations

import threading
from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class FailedAction:
    uav_id: int
    action: str  # take_off, land, follow_path, ...
    where: str  # the mission state (its JSON path)
    reason: str  # the UAV manager's message (the UAL's refusal, what the role saw), or the ground station's
    sim_time: float

    def describe(self) -> str:
        return f"UAV {self.uav_id} {self.action} aborted at {self.sim_time:.1f} s ({self.where}): {self.reason}"


class FailedActions:
    """The actions of a mission that ended aborted, in the order they ended (the states run in threads)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._failed: list[FailedAction] = []

    def add(self, failed: FailedAction) -> None:
        with self._lock:
            self._failed.append(failed)

    def all(self) -> list[FailedAction]:
        with self._lock:
            return list(self._failed)


def judge_actions(success: bool, message: str, failed_actions: Iterable[FailedAction]) -> tuple[bool, str]:
    """The verdict (success, message) once the failed actions are weighed: any one makes the mission not a
    success, whatever its outcome, and the message names each with its reason."""
    failed = list(failed_actions)
    if not failed:
        return success, message
    return False, message + "; aborted actions: " + "; ".join(f.describe() for f in failed)
