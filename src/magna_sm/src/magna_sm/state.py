"""States: the leaves of a machine. A state declares its outcomes and userdata keys and runs `execute`.

Preemption is cooperative: `request_preempt()` sets a flag the running state
polls with `preempt_requested()`; a state that honours it calls
`service_preempt()` and returns "preempted". Containers clear any flag left
over when an execution ends, so a preempted state can run again.
"""
from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from typing import Any


class State:
    """Base of every state and container."""

    def __init__(self, outcomes: Iterable[str], input_keys: Iterable[str] = (), output_keys: Iterable[str] = (),
                 io_keys: Iterable[str] = ()):
        outcomes = list(outcomes)
        if not outcomes:
            raise ValueError(f"{type(self).__name__} needs at least one outcome")
        if len(set(outcomes)) != len(outcomes):
            raise ValueError(f"{type(self).__name__}: duplicate outcomes in {outcomes}")
        self._outcomes = tuple(outcomes)
        io_keys = list(io_keys)
        self._input_keys = frozenset([*input_keys, *io_keys])
        self._output_keys = frozenset([*output_keys, *io_keys])
        self._preempt = threading.Event()
        self._parent: State | None = None  # the container this state was added to (a State: no import circle)
        self._label: str | None = None     # its label there

    # -- what the state declares ------------------------------------------------
    def get_registered_outcomes(self) -> tuple[str, ...]:
        return self._outcomes

    def get_registered_input_keys(self) -> frozenset[str]:
        return self._input_keys

    def get_registered_output_keys(self) -> frozenset[str]:
        return self._output_keys

    def register_outcomes(self, outcomes: Iterable[str]) -> None:
        self._outcomes = tuple(dict.fromkeys([*self._outcomes, *outcomes]))

    def register_input_keys(self, keys: Iterable[str]) -> None:
        self._input_keys = self._input_keys | frozenset(keys)

    def register_output_keys(self, keys: Iterable[str]) -> None:
        self._output_keys = self._output_keys | frozenset(keys)

    # -- where it sits ----------------------------------------------------------
    @property
    def label(self) -> str | None:
        return self._label

    @property
    def path(self) -> str:
        """`/ROOT/child/grandchild`: the labels from the root container down to this state."""
        if self._parent is None:
            return "/" + (self._label or type(self).__name__.upper())
        return f"{self._parent.path}/{self._label}"

    # -- running ----------------------------------------------------------------
    def execute(self, ud) -> str:
        raise NotImplementedError(f"{type(self).__name__} must implement execute(ud)")

    def request_preempt(self) -> None:
        self._preempt.set()

    def service_preempt(self) -> None:
        self._preempt.clear()

    def recall_preempt(self) -> None:
        self._preempt.clear()

    def preempt_requested(self) -> bool:
        return self._preempt.is_set()

    def wait_for_preempt(self, timeout: float | None) -> bool:
        """Sleep up to `timeout` s, waking at once on a preemption; True if preempted."""
        return self._preempt.wait(timeout)

    def _arm(self) -> None:
        """Called by the container just before this state runs (containers start accepting preemption)."""

    def _reset_after_run(self) -> None:
        """Forget a preemption that arrived too late to matter (called by the container)."""
        self._preempt.clear()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.path}>"


class CBState(State):
    """A state whose work is a function `cb(ud, *cb_args, **cb_kwargs) -> outcome`.

    With `pass_state=True` the state itself is passed as keyword `state`, so a
    long callback can poll `state.preempt_requested()` or `state.wait_for_preempt()`.
    """

    def __init__(self, cb: Callable[..., str], outcomes: Iterable[str], input_keys: Iterable[str] = (),
                 output_keys: Iterable[str] = (), io_keys: Iterable[str] = (), cb_args: Iterable[Any] = (),
                 cb_kwargs: dict | None = None, pass_state: bool = False):
        super().__init__(outcomes, input_keys, output_keys, io_keys)
        if not callable(cb):
            raise TypeError(f"CBState callback must be callable, got {cb!r}")
        self._cb = cb
        self._cb_args = tuple(cb_args)
        self._cb_kwargs = dict(cb_kwargs or {})
        if pass_state:
            self._cb_kwargs["state"] = self

    def execute(self, ud) -> str:
        return self._cb(ud, *self._cb_args, **self._cb_kwargs)
