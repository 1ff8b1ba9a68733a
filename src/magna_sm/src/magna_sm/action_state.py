"""SimpleActionState: a state that sends one action goal and turns its result into an outcome.

Timeouts are measured on ROS time (simulated time when `use_sim_time` is set),
so a mission paced by the simulator keeps its meaning at any real-time factor.
Each run sends a fresh goal and forgets it at the end, so a state that was
preempted runs again normally.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

import rospy
from actionlib_msgs.msg import GoalStatus

from magna_sm.simple_action import SimpleActionClient
from magna_sm.state import State

DEFAULT_OUTCOMES = ("succeeded", "preempted", "aborted")
_POLL = 0.02  # wall seconds between checks for preemption and ROS-time deadlines


def _duration(value) -> rospy.Duration | None:
    if value is None:
        return None
    if isinstance(value, rospy.Duration):
        return value if value > rospy.Duration(0) else None
    return rospy.Duration.from_sec(float(value)) if float(value) > 0 else None


class SimpleActionState(State):
    """Send a goal to `action_name` and wait for its result.

    The goal is, in order: `goal_cb(ud, default_goal)` if given, else
    `ud[goal_key]`, else `goal` (or an empty goal) with `goal_slots` copied in
    from userdata. The result goes to `ud[result_key]` and its `result_slots`
    to userdata keys of the same names; `result_cb(ud, status, result)` may
    return an outcome of its own (any declared in `outcomes`), otherwise
    SUCCEEDED -> succeeded, PREEMPTED/RECALLED -> preempted, else aborted.
    """

    def __init__(self, action_name: str, action_spec, goal=None, goal_key: str | None = None,
                 goal_slots: Iterable[str] = (), goal_cb: Callable | None = None, goal_cb_args=(),
                 goal_cb_kwargs=None, result_key: str | None = None, result_slots: Iterable[str] = (),
                 result_cb: Callable | None = None, result_cb_args=(), result_cb_kwargs=None,
                 input_keys: Iterable[str] = (), output_keys: Iterable[str] = (), outcomes: Iterable[str] = (),
                 exec_timeout=None, preempt_timeout=60.0, server_wait_timeout=60.0,
                 client_factory: Callable[[str, Any], SimpleActionClient] = SimpleActionClient):
        goal_slots, result_slots = list(goal_slots), list(result_slots)
        inputs = [*input_keys, *goal_slots] + ([goal_key] if goal_key else [])
        outputs = [*output_keys, *result_slots] + ([result_key] if result_key else [])
        super().__init__(list(dict.fromkeys([*DEFAULT_OUTCOMES, *outcomes])), inputs, outputs)
        if goal is not None and goal_key is not None:
            raise ValueError(f"SimpleActionState({action_name}): give either goal or goal_key, not both")
        self.action_name = action_name
        self._spec = action_spec
        self._goal = goal
        self._goal_key = goal_key
        self._goal_slots = goal_slots
        self._goal_cb = goal_cb
        self._goal_cb_args, self._goal_cb_kwargs = tuple(goal_cb_args), dict(goal_cb_kwargs or {})
        self._result_key = result_key
        self._result_slots = result_slots
        self._result_cb = result_cb
        self._result_cb_args, self._result_cb_kwargs = tuple(result_cb_args), dict(result_cb_kwargs or {})
        self._exec_timeout = _duration(exec_timeout)
        self._preempt_timeout = _duration(preempt_timeout)
        self._server_wait_timeout = _duration(server_wait_timeout)
        self._client_factory = client_factory
        self._client: SimpleActionClient | None = None  # made on the first run, kept for the next ones
        self.last_status: int | None = None
        self.last_status_text = ""

    # -- the goal ---------------------------------------------------------------
    def _goal_type(self):
        return type(self._spec().action_goal.goal)

    def _build_goal(self, ud):
        goal = self._goal if self._goal is not None else self._goal_type()()
        if self._goal_key is not None:
            goal = ud[self._goal_key]
        for slot in self._goal_slots:
            setattr(goal, slot, ud[slot])
        if self._goal_cb is not None:
            built = self._goal_cb(ud, goal, *self._goal_cb_args, **self._goal_cb_kwargs)
            goal = goal if built is None else built
        return goal

    # -- waiting, preemptably, on ROS time --------------------------------------------
    def _wait(self, done: Callable[[], bool], timeout: rospy.Duration | None, stop_on_preempt: bool) -> str:
        """'done', 'timeout', 'preempted' or 'shutdown'."""
        deadline = None if timeout is None else rospy.Time.now() + timeout
        while not done():
            if rospy.is_shutdown():
                return "shutdown"
            if stop_on_preempt and self.preempt_requested():
                return "preempted"
            if deadline is not None and rospy.Time.now() >= deadline:
                return "timeout"
            if stop_on_preempt:
                self._preempt.wait(_POLL)  # wakes at once on a preemption
            else:
                time.sleep(_POLL)
        return "done"

    def _get_client(self) -> SimpleActionClient:
        if self._client is None:
            self._client = self._client_factory(self.action_name, self._spec)
        return self._client

    def _connect(self, client: SimpleActionClient) -> str:
        connected = [False]

        def check() -> bool:
            connected[0] = connected[0] or client.wait_for_server(rospy.Duration.from_sec(_POLL))
            return connected[0]

        return self._wait(check, self._server_wait_timeout, stop_on_preempt=True)

    # -- running ----------------------------------------------------------------
    def execute(self, ud) -> str:
        self.last_status, self.last_status_text = None, ""
        client = self._get_client()
        waited = self._connect(client)
        if waited != "done":
            if waited == "preempted":
                self.service_preempt()
                return "preempted"
            rospy.logwarn(f"{self.path}: action server '{self.action_name}' not available ({waited})")
            return "aborted"

        finished = threading.Event()
        client.send_goal(self._build_goal(ud), done_cb=lambda status, result: finished.set())
        try:
            waited = self._wait(finished.is_set, self._exec_timeout, stop_on_preempt=True)
            preempted = waited == "preempted"
            if waited != "done":
                client.cancel_goal()
                if self._wait(finished.is_set, self._preempt_timeout, stop_on_preempt=False) != "done":
                    rospy.logwarn(f"{self.path}: '{self.action_name}' did not confirm the cancel in time")
                    if preempted:
                        self.service_preempt()
                        return "preempted"
                    return "aborted"
            status = client.get_state()
            result = client.get_result()
            self.last_status, self.last_status_text = status, client.get_goal_status_text()
        finally:
            client.stop_tracking_goal()

        if preempted:
            self.service_preempt()
        return self._outcome(ud, status, result, preempted, waited)

    def _outcome(self, ud, status: int, result, preempted: bool, waited: str) -> str:
        if result is not None:
            if self._result_key is not None:
                ud[self._result_key] = result
            for slot in self._result_slots:
                ud[slot] = getattr(result, slot)
        if self._result_cb is not None:
            outcome = self._result_cb(ud, status, result, *self._result_cb_args, **self._result_cb_kwargs)
            if outcome is not None:
                if outcome not in self._outcomes:
                    raise ValueError(f"{self.path}: result_cb returned '{outcome}', not one of {list(self._outcomes)}")
                return outcome
        if waited == "timeout":
            return "aborted"
        if status == GoalStatus.SUCCEEDED:
            return "succeeded"
        if status in (GoalStatus.PREEMPTED, GoalStatus.RECALLED) or preempted:
            return "preempted"
        return "aborted"


def outcome_from_result(ud, status: int, result, field: str = "outcome") -> str | None:
    """A result_cb for MAGNA actions: the outcome string the UAV manager put in the result."""
    outcome = "" if result is None else getattr(result, field, "")
    return outcome or None
