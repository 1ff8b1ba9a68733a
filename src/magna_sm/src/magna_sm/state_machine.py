"""StateMachine: one child runs at a time; its outcome picks the next child or the container's outcome."""
from __future__ import annotations

from collections.abc import Iterable, Mapping

from magna_sm.container import PREEMPTED, Container
from magna_sm.exceptions import ValidationError
from magna_sm.state import State


class StateMachine(Container):
    """Children joined by transitions `{outcome: next label or container outcome}`.

    A child outcome with no transition ends the machine with the container
    outcome of the same name, if there is one.
    """

    def __init__(self, outcomes: Iterable[str], input_keys: Iterable[str] = (), output_keys: Iterable[str] = (),
                 io_keys: Iterable[str] = (), name: str | None = None):
        super().__init__(outcomes, input_keys, output_keys, io_keys, name)
        self._transitions: dict[str, dict[str, str]] = {}
        self._initial: str | None = None
        self._last_outcome = ""

    @staticmethod
    def add(label: str, state: State, transitions: Mapping[str, str] | None = None,
            remapping: Mapping[str, str] | None = None) -> State:
        """Add a child to the machine opened with `with`; the first child added is the initial state."""
        return Container._current(StateMachine).add_state(label, state, transitions, remapping)

    def add_state(self, label: str, state: State, transitions: Mapping[str, str] | None = None,
                  remapping: Mapping[str, str] | None = None) -> State:
        self._add_child(label, state, remapping)
        self._transitions[label] = dict(transitions or {})
        if self._initial is None:
            self._initial = label
        return state

    def set_initial_state(self, labels: Iterable[str] | str) -> None:
        labels = [labels] if isinstance(labels, str) else list(labels)
        if len(labels) != 1:
            raise ValidationError([f"{self.path}: a StateMachine has exactly one initial state, got {labels}"])
        self._initial = labels[0]
        self._checked = False

    @property
    def last_outcome(self) -> str:
        return self._last_outcome

    def _target(self, label: str, outcome: str) -> str | None:
        target = self._transitions[label].get(outcome)
        if target is None and outcome in self._outcomes:
            return outcome
        return target

    # -- validation -------------------------------------------------------------
    def _container_problems(self) -> list[str]:
        if not self._children:
            return []
        problems = []
        if self._initial not in self._children:
            problems.append(f"{self.path}: initial state '{self._initial}' is not a state of this machine")
        produced = set()
        for label, state in self._children.items():
            for outcome, target in self._transitions[label].items():
                if outcome not in state.get_registered_outcomes():
                    problems.append(f"{self.path}/{label}: transition for outcome '{outcome}', "
                                    f"which the state does not declare {list(state.get_registered_outcomes())}")
                if target not in self._children and target not in self._outcomes:
                    problems.append(f"{self.path}/{label}: outcome '{outcome}' goes to '{target}', "
                                    "which is neither a state nor an outcome of this machine")
            for outcome in state.get_registered_outcomes():
                mapped = self._target(label, outcome)
                if mapped is None:
                    problems.append(f"{self.path}/{label}: outcome '{outcome}' is not mapped "
                                    f"(map it to a state or to one of {list(self._outcomes)})")
                elif mapped in self._outcomes:
                    produced.add(mapped)
        problems.extend(f"{self.path}/{label}: unreachable from the initial state '{self._initial}'"
                        for label in self._children if label not in self._reachable())
        problems.extend(f"{self.path}: no state leads to the container outcome '{outcome}'"
                        for outcome in self._outcomes if outcome != PREEMPTED and outcome not in produced)
        return problems

    def _reachable(self) -> set[str]:
        seen, frontier = set(), [self._initial] if self._initial in self._children else []
        while frontier:
            label = frontier.pop()
            if label in seen:
                continue
            seen.add(label)
            for outcome in self._children[label].get_registered_outcomes():
                target = self._target(label, outcome)
                if target in self._children:
                    frontier.append(target)
        return seen

    def _initial_labels(self) -> list[str]:
        return [self._initial] if self._initial else []

    def _structure_transitions(self) -> list[tuple[str, str, str]]:
        return [(label, outcome, target)
                for label, state in self._children.items()
                for outcome in state.get_registered_outcomes() if (target := self._target(label, outcome)) is not None]

    # -- running ----------------------------------------------------------------
    def _run(self) -> str:
        label = self._initial
        assert label is not None  # check() refuses a machine whose initial state is not one of its states
        self._last_outcome = ""
        starting = True
        while True:
            with self._lock:
                if self._preempt.is_set():
                    self.service_preempt()
                    return PREEMPTED
                self._active = [label]
                state = self._children[label]
                state._arm()
            if starting:
                self._notify("start")
                starting = False
            outcome = self._execute_child(label, state)
            target = self._target(label, outcome)
            # check() refuses unmapped outcomes and _execute_child() undeclared ones
            assert target is not None
            with self._lock:
                self._active = []
            self._last_outcome = outcome
            if self._preempt.is_set():
                self.service_preempt()
                self._notify("transition", label, outcome, PREEMPTED)
                return PREEMPTED
            if self._observers:
                with self._lock:
                    self._active = [target] if target in self._children else []
                self._notify("transition", label, outcome, target)
            if target in self._outcomes:
                return target
            label = target
