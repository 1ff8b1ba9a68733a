"""Sequence: a StateMachine whose children are chained by one connector outcome, in the order added."""
from __future__ import annotations

from collections.abc import Iterable, Mapping

from magna_sm.container import Container
from magna_sm.state import State
from magna_sm.state_machine import StateMachine


class Sequence(StateMachine):
    """Each child's `connector_outcome` leads to the next child added; other outcomes use `transitions`.

    The last child's connector outcome ends the sequence with the container
    outcome of the same name (or whatever its transitions say).
    """

    def __init__(self, outcomes: Iterable[str], connector_outcome: str, input_keys: Iterable[str] = (),
                 output_keys: Iterable[str] = (), io_keys: Iterable[str] = (), name: str | None = None):
        super().__init__(outcomes, input_keys, output_keys, io_keys, name)
        self._connector_outcome = connector_outcome
        self._last_label: str | None = None

    @staticmethod
    def add(label: str, state: State, transitions: Mapping[str, str] | None = None,
            remapping: Mapping[str, str] | None = None) -> State:
        return Container._current(Sequence).add_state(label, state, transitions, remapping)

    def add_state(self, label: str, state: State, transitions: Mapping[str, str] | None = None,
                  remapping: Mapping[str, str] | None = None) -> State:
        previous = self._last_label
        super().add_state(label, state, transitions, remapping)
        if previous is not None:
            self._transitions[previous].setdefault(self._connector_outcome, label)
        self._last_label = label
        return state
