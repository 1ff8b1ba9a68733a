"""A StateFactory whose states end with scripted outcomes at once: dry runs of a mission's logic.

    factory = ScriptedFactory({("State_Machine[6].occurrencies[0].occurrencies[0]", 1): "collision"})
    outcome = build_machine(mission, factory).execute()
    factory.ran        # [Step(json_path, kind, state_type, uav, ids, outcome), ...] in the order they ended

A script maps `(json_path, uav)` (action states; uav None matches any UAV) or
`json_path` (callback states, and action states of any UAV) to an outcome, or to a
list of outcomes used one per run (the last repeats). Unscripted action states
succeed and callback states complete. The outcome `HOLD` keeps a state running until
it is preempted (it then ends "preempted" for an action state, "failed" for a callback),
for testing Concurrence termination; `hold_timeout` s guard against a test hanging.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

from magna_gs.mission.model import ACTION_OUTCOMES, CALLBACK_OUTCOMES
from magna_sm import State

HOLD = "<hold until preempted>"


@dataclass(frozen=True)
class Step:
    json_path: str
    kind: str  # SimpleActionState | CBState
    state_type: str
    uav: int | None  # action states
    ids: tuple[int, ...]  # callback states
    outcome: str
    parameters: object = None


class _ScriptedState(State):
    def __init__(self, factory: ScriptedFactory, outcomes, kind, state_type, uav, ids, parameters, json_path):
        super().__init__(outcomes)
        self.factory, self.kind, self.state_type = factory, kind, state_type
        self.uav, self.ids, self.parameters, self.json_path = uav, tuple(ids), parameters, json_path

    def execute(self, ud) -> str:
        outcome = self.factory._next(self.json_path, self.uav if self.kind == "SimpleActionState" else None)
        if outcome is None:
            outcome = "succeeded" if self.kind == "SimpleActionState" else "completed"
        if outcome == HOLD:
            action = self.kind == "SimpleActionState"
            if self.wait_for_preempt(self.factory.hold_timeout):
                self.service_preempt()
                outcome = "preempted" if action else "failed"
            else:  # the guard: nobody preempted it
                outcome = "aborted" if action else "failed"
        self.factory._record(Step(self.json_path, self.kind, self.state_type, self.uav, self.ids, outcome,
                                  self.parameters))
        return outcome


class ScriptedFactory:
    def __init__(self, script: dict | None = None, hold_timeout: float = 10.0):
        self.script = dict(script or {})
        self.hold_timeout = hold_timeout
        self.ran: list[Step] = []
        self.made: list[_ScriptedState] = []  # every state built, in build order
        self._lock = threading.Lock()
        self._used: dict[object, int] = {}

    def action_state(self, uav_id: int, action: str, parameters, json_path: str) -> State:
        state = _ScriptedState(self, ACTION_OUTCOMES, "SimpleActionState", action, uav_id, (), parameters, json_path)
        self.made.append(state)
        return state

    def callback_state(self, state_type: str, ids: list[int], parameters, json_path: str) -> State:
        state = _ScriptedState(self, CALLBACK_OUTCOMES, "CBState", state_type, None, ids, parameters, json_path)
        self.made.append(state)
        return state

    def _next(self, json_path: str, uav: int | None) -> str | None:
        with self._lock:
            for key in ((json_path, uav), (json_path, None), json_path):
                if key in self.script:
                    entry = self.script[key]
                    if isinstance(entry, list):
                        index = self._used.get(key, 0)
                        self._used[key] = index + 1
                        return entry[min(index, len(entry) - 1)]
                    return entry
        return None

    def _record(self, step: Step) -> None:
        with self._lock:
            self.ran.append(step)
