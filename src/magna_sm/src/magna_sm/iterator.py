"""Iterator: run one contained state once per item, with the item in userdata."""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from magna_sm.container import PREEMPTED, Container
from magna_sm.exceptions import ValidationError
from magna_sm.state import State


class Iterator(Container):
    """For each item of `it` (an iterable, or a callable returning one at run time), put the item
    in userdata key `it_label` and run the contained state.

    An outcome in `loop_outcomes` goes on to the next item; an outcome in
    `break_outcomes` ends the iterator with the container outcome of the same
    name; when the items run out the outcome is `exhausted_outcome`.
    """

    def __init__(self, outcomes: Iterable[str], it: Iterable[Any] | Callable[[], Iterable[Any]],
                 it_label: str = "it_data", exhausted_outcome: str = "succeeded", input_keys: Iterable[str] = (),
                 output_keys: Iterable[str] = (), io_keys: Iterable[str] = (), name: str | None = None):
        super().__init__(outcomes, input_keys, output_keys, io_keys, name)
        self._items = it
        self._it_label = it_label
        self._exhausted_outcome = exhausted_outcome
        self._loop_outcomes: frozenset[str] = frozenset()
        self._break_outcomes: frozenset[str] = frozenset()
        self._contained: str | None = None

    @staticmethod
    def set_contained_state(label: str, state: State, loop_outcomes: Iterable[str] = (),
                            break_outcomes: Iterable[str] = (), remapping: Mapping[str, str] | None = None) -> State:
        return Container._current(Iterator).set_state(label, state, loop_outcomes, break_outcomes, remapping)

    def set_state(self, label: str, state: State, loop_outcomes: Iterable[str] = (),
                  break_outcomes: Iterable[str] = (), remapping: Mapping[str, str] | None = None) -> State:
        if self._contained is not None:
            raise ValidationError([f"{self.path}: an Iterator contains one state; '{self._contained}' is already set"])
        self._add_child(label, state, remapping)
        self._contained = label
        self._loop_outcomes = frozenset(loop_outcomes)
        self._break_outcomes = frozenset(break_outcomes)
        return state

    def _container_problems(self) -> list[str]:
        problems = []
        if self._exhausted_outcome not in self._outcomes:
            problems.append(f"{self.path}: exhausted_outcome '{self._exhausted_outcome}' is not an outcome "
                            "of the iterator")
        if self._contained is None:
            return problems
        state = self._children[self._contained]
        for outcome in state.get_registered_outcomes():
            if outcome in self._loop_outcomes:
                continue
            if outcome not in self._outcomes:
                problems.append(f"{self.path}/{self._contained}: outcome '{outcome}' neither loops nor ends the "
                                f"iterator (add it to loop_outcomes, or to the iterator's outcomes)")
        return problems

    def _structure_transitions(self) -> list[tuple[str, str, str]]:
        if self._contained is None:
            return []
        state = self._children[self._contained]
        return [(self._contained, outcome, self._contained if outcome in self._loop_outcomes else outcome)
                for outcome in state.get_registered_outcomes()]

    def _run(self) -> str:
        items = self._items() if callable(self._items) else self._items
        label = self._contained
        assert label is not None  # check() refuses an Iterator without states, and set_state() is how one is added
        state = self._children[label]
        self._notify("start")
        for item in items:
            with self._lock:
                if self._preempt.is_set():
                    self.service_preempt()
                    return PREEMPTED
                self._active = [label]
                state._arm()
            self.userdata[self._it_label] = item
            outcome = self._execute_child(label, state)
            with self._lock:
                self._active = []
            if self._preempt.is_set():
                self.service_preempt()
                return PREEMPTED
            self._notify("transition", label, outcome, label if outcome in self._loop_outcomes else outcome)
            if outcome not in self._loop_outcomes:
                return outcome
        return self._exhausted_outcome
