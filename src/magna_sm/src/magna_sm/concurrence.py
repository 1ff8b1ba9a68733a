"""Concurrence: every child runs at once, in its own thread; the children's outcomes decide the container's."""
from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping

from magna_sm.container import PREEMPTED, Container
from magna_sm.exceptions import InvalidOutcomeError
from magna_sm.state import State

OutcomeMap = Mapping[str, Mapping[str, str]]


class Concurrence(Container):
    """Run all children together.

    The outcome is, in order of precedence:
    1. `outcome_cb(child_outcomes)` when given and it returns an outcome;
    2. the `outcome_map` entry `{container_outcome: {child: child_outcome}}` whose
       conditions all hold, the one with the most conditions winning;
    3. `default_outcome`.
    After each child ends, `child_termination_cb(child_outcomes_so_far)` may
    return True to preempt the children still running. A preempted
    Concurrence preempts its children and returns "preempted".
    """

    def __init__(self, outcomes: Iterable[str], default_outcome: str, input_keys: Iterable[str] = (),
                 output_keys: Iterable[str] = (), io_keys: Iterable[str] = (), outcome_map: OutcomeMap | None = None,
                 outcome_cb: Callable[[dict[str, str]], str | None] | None = None,
                 child_termination_cb: Callable[[dict[str, str]], bool] | None = None, name: str | None = None):
        super().__init__(outcomes, input_keys, output_keys, io_keys, name)
        self._default_outcome = default_outcome
        self._outcome_map = {outcome: dict(conditions) for outcome, conditions in (outcome_map or {}).items()}
        self._outcome_cb = outcome_cb
        self._child_termination_cb = child_termination_cb
        self._child_outcomes: dict[str, str] = {}

    @staticmethod
    def add(label: str, state: State, remapping: Mapping[str, str] | None = None) -> State:
        return Container._current(Concurrence).add_state(label, state, remapping)

    def add_state(self, label: str, state: State, remapping: Mapping[str, str] | None = None) -> State:
        self._add_child(label, state, remapping)
        return state

    @property
    def child_outcomes(self) -> dict[str, str]:
        """The outcome of each child in the last run."""
        return dict(self._child_outcomes)

    # -- validation -------------------------------------------------------------
    def _requires_children(self) -> bool:
        return False  # an empty Concurrence is legal and returns at once

    def _container_problems(self) -> list[str]:
        problems = []
        if self._default_outcome not in self._outcomes:
            problems.append(f"{self.path}: default_outcome '{self._default_outcome}' is not one of "
                            f"{list(self._outcomes)}")
        for outcome, conditions in self._outcome_map.items():
            if outcome not in self._outcomes:
                problems.append(f"{self.path}: outcome_map names '{outcome}', not an outcome of the container")
            for label, child_outcome in conditions.items():
                if label not in self._children:
                    problems.append(f"{self.path}: outcome_map['{outcome}'] names '{label}', not a child")
                elif child_outcome not in self._children[label].get_registered_outcomes():
                    problems.append(f"{self.path}: outcome_map['{outcome}'] expects '{label}' to return "
                                    f"'{child_outcome}', which it does not declare")
        if self._outcome_cb is None:
            reachable = set(self._outcome_map) | {self._default_outcome, PREEMPTED}
            problems.extend(f"{self.path}: no outcome_map entry or default leads to the container outcome "
                            f"'{outcome}'" for outcome in self._outcomes if outcome not in reachable)
        return problems

    def _structure_transitions(self) -> list[tuple[str, str, str]]:
        return [(label, child_outcome, outcome)
                for outcome, conditions in self._outcome_map.items() for label, child_outcome in conditions.items()]

    # -- running ----------------------------------------------------------------
    def _run(self) -> str:
        self._child_outcomes = {}
        if not self._children:
            self._notify("start")
            return self._decide({})
        finished = threading.Condition(self._lock)
        errors: list[BaseException] = []

        def run_child(label: str, state: State) -> None:
            try:
                outcome = self._execute_child(label, state)
            except BaseException as error:  # reported in the caller's thread
                outcome = None
                errors.append(error)
            with finished:
                self._active.remove(label)
                if outcome is not None:
                    self._child_outcomes[label] = outcome
                stop_others = bool(errors)
                if outcome is not None and self._child_termination_cb is not None:
                    stop_others = bool(self._child_termination_cb(dict(self._child_outcomes))) or stop_others
                if stop_others:
                    for other in self._active:
                        self._children[other].request_preempt()
                finished.notify_all()
            if outcome is not None:
                self._notify("transition", label, outcome, "")

        with finished:
            self._active = list(self._children)
            for state in self._children.values():
                state._arm()
            threads = [threading.Thread(target=run_child, args=(label, state), name=f"{self.path}/{label}",
                                        daemon=True)
                       for label, state in self._children.items()]
            if self._preempt.is_set():  # preempted before any child started
                for state in self._children.values():
                    state.request_preempt()
        self._notify("start")
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        if errors:
            raise errors[0]
        if self._preempt.is_set():
            self.service_preempt()
            return PREEMPTED
        return self._decide(dict(self._child_outcomes))

    def _decide(self, child_outcomes: dict[str, str]) -> str:
        if self._outcome_cb is not None:
            outcome = self._outcome_cb(dict(child_outcomes))
            if outcome is not None:
                if outcome not in self._outcomes:
                    raise InvalidOutcomeError(f"{self.path}: outcome_cb returned {outcome!r}, "
                                              f"not one of {list(self._outcomes)}")
                return outcome
        best, best_size = None, -1
        for outcome, conditions in self._outcome_map.items():
            satisfied = all(child_outcomes.get(label) == wanted for label, wanted in conditions.items())
            if satisfied and len(conditions) > best_size:
                best, best_size = outcome, len(conditions)
        return best if best is not None else self._default_outcome
