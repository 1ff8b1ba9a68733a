"""What every container shares: children with labels, userdata plumbing, preemption, validation, observers.

Subclasses implement `_run()` (the execution policy), `_container_problems()`
(their own validation) and `_structure_transitions()` (for introspection).
"""
from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import TypeVar

from magna_sm.exceptions import InvalidOutcomeError, StateExecutionError, StateMachineError, ValidationError
from magna_sm.state import State
from magna_sm.userdata import Remapper, UserData

PREEMPTED = "preempted"

_opened = threading.local()  # the stack of containers opened with `with`, per thread

_C = TypeVar("_C", bound="Container")


@dataclass(frozen=True)
class ContainerEvent:
    """What observers (introspection, recorders, tests) hear from a container."""

    kind: str                      # "start", "transition" or "finish"
    path: str                      # the container's path
    active_states: tuple[str, ...]  # labels running after this event
    from_state: str = ""           # transition: the child that finished
    outcome: str = ""              # transition: its outcome; finish: the container's outcome
    to_state: str = ""             # transition: the next child or container outcome


@dataclass(frozen=True)
class ContainerStructure:
    """The static shape of a container, for introspection and drawing."""

    path: str
    container_type: str
    children: tuple[str, ...]
    child_types: tuple[str, ...]
    container_outcomes: tuple[str, ...]
    initial_states: tuple[str, ...]
    transitions: tuple[tuple[str, str, str], ...] = field(default=())  # (from child, outcome, to)


class Container(State):
    """A state made of labelled child states."""

    def __init__(self, outcomes: Iterable[str], input_keys: Iterable[str] = (), output_keys: Iterable[str] = (),
                 io_keys: Iterable[str] = (), name: str | None = None):
        outcomes = list(outcomes)
        if PREEMPTED not in outcomes:
            outcomes.append(PREEMPTED)  # a preempted container always reports it
        super().__init__(outcomes, input_keys, output_keys, io_keys)
        self._label = name
        self.userdata = UserData()
        self._children: dict[str, State] = {}
        self._remappings: dict[str, dict[str, str]] = {}
        self._observers: list[Callable[[ContainerEvent], None]] = []
        self._lock = threading.RLock()
        self._active: list[str] = []
        self._running = False  # preemption applies only while running (or armed by the parent)
        self._checked = False

    # -- construction -----------------------------------------------------------
    def __enter__(self):
        stack = getattr(_opened, "stack", None)
        if stack is None:
            stack = _opened.stack = []
        stack.append(self)
        return self

    def __exit__(self, *exc) -> None:
        _opened.stack.pop()

    @staticmethod
    def _current(kind: type[_C]) -> _C:
        stack = getattr(_opened, "stack", None)
        if not stack:
            raise StateMachineError(f"{kind.__name__}.add() needs an open container: use `with container:`")
        container = stack[-1]
        if not isinstance(container, kind):
            raise StateMachineError(f"{kind.__name__}.add() called while a {type(container).__name__} "
                                    f"({container.path}) is the open container")
        return container

    def _add_child(self, label: str, state: State, remapping: Mapping[str, str] | None) -> None:
        if not isinstance(label, str) or not label:
            raise ValidationError([f"{self.path}: a state label must be a non-empty string, got {label!r}"])
        if not isinstance(state, State):
            raise ValidationError([f"{self.path}/{label}: {state!r} is not a State"])
        if label in self._children:
            raise ValidationError([f"{self.path}: duplicate state label '{label}'"])
        if label in self.get_registered_outcomes():
            raise ValidationError([f"{self.path}: state label '{label}' is also an outcome of the container"])
        if state._parent is not None:
            raise ValidationError([f"{self.path}/{label}: this state object is already {state.path}; "
                                   "create a new instance for each place it is used"])
        state._parent = self
        state._label = label
        self._children[label] = state
        self._remappings[label] = dict(remapping or {})
        self._checked = False

    def get_children(self) -> dict[str, State]:
        return dict(self._children)

    def __getitem__(self, label: str) -> State:
        return self._children[label]

    def get_active_states(self) -> list[str]:
        with self._lock:
            return list(self._active)

    # -- validation -------------------------------------------------------------
    def check(self) -> None:
        """Raise ValidationError listing every problem of this container and its descendants."""
        problems = self._collect_problems()
        if problems:
            raise ValidationError(problems)
        self._checked = True

    def _collect_problems(self) -> list[str]:
        problems = []
        if not self._children and self._requires_children():
            problems.append(f"{self.path}: has no states")
        problems.extend(self._container_problems())
        for child in self._children.values():
            if isinstance(child, Container):
                problems.extend(child._collect_problems())
        return problems

    def _requires_children(self) -> bool:
        return True

    def _container_problems(self) -> list[str]:
        return []

    # -- observers --------------------------------------------------------------
    def register_observer(self, observer: Callable[[ContainerEvent], None]) -> None:
        self._observers.append(observer)

    def unregister_observer(self, observer: Callable[[ContainerEvent], None]) -> None:
        if observer in self._observers:
            self._observers.remove(observer)

    def _notify(self, kind: str, from_state: str = "", outcome: str = "", to_state: str = "") -> None:
        if self._observers:
            event = ContainerEvent(kind, self.path, tuple(self._active), from_state, outcome, to_state)
            for observer in self._observers:
                observer(event)

    def walk(self):
        """This container and every container below it, depth first."""
        yield self
        for child in self._children.values():
            if isinstance(child, Container):
                yield from child.walk()

    def describe(self) -> ContainerStructure:
        labels = tuple(self._children)
        return ContainerStructure(
            path=self.path, container_type=type(self).__name__, children=labels,
            child_types=tuple(type(self._children[label]).__name__ for label in labels),
            container_outcomes=self.get_registered_outcomes(), initial_states=tuple(self._initial_labels()),
            transitions=tuple(self._structure_transitions()))

    @property
    def initial_states(self) -> list[str]:
        """Labels of the children a run starts with."""
        return self._initial_labels()

    def _initial_labels(self) -> list[str]:
        return list(self._children)

    def _structure_transitions(self) -> list[tuple[str, str, str]]:
        return []

    # -- running ----------------------------------------------------------------
    def execute(self, parent_ud=None) -> str:
        if self._parent is None and not self._checked:
            self.check()
        self._arm()
        if parent_ud is not None:
            self._copy_inputs(parent_ud)
        try:
            outcome = self._run()  # announces "start" once its first children are active
        finally:
            with self._lock:
                self._active = []
                self._running = False
                self._forget_preemptions()
            if parent_ud is not None:
                self._copy_outputs(parent_ud)
        self._notify("finish", outcome=outcome)
        return outcome

    def _arm(self) -> None:
        with self._lock:
            self._running = True

    def _copy_inputs(self, parent_ud) -> None:
        for key in self._input_keys:
            if key in parent_ud:
                self.userdata[key] = parent_ud[key]

    def _copy_outputs(self, parent_ud) -> None:
        for key in self._output_keys:
            if key in self.userdata:
                parent_ud[key] = self.userdata[key]

    def _run(self) -> str:
        raise NotImplementedError

    def _execute_child(self, label: str, state: State) -> str:
        ud = Remapper(self.userdata, state._input_keys, state._output_keys, self._remappings[label], state.path)
        try:
            outcome = state.execute(ud)
        except StateMachineError:
            raise
        except Exception as error:
            raise StateExecutionError(f"{state.path} raised {type(error).__name__}: {error}") from error
        if outcome not in state._outcomes:
            raise InvalidOutcomeError(f"{state.path} returned outcome {outcome!r}, "
                                      f"not one of its declared outcomes {list(state._outcomes)}")
        return outcome

    def request_preempt(self) -> None:
        """Stop the current run promptly; on an idle container (nothing to stop) it is dropped."""
        with self._lock:
            if not self._running:
                return
            super().request_preempt()
            for label in self._active:
                self._children[label].request_preempt()

    def _forget_preemptions(self) -> None:
        """A preemption that arrived as the run ended must not leak into the next run."""
        self._preempt.clear()
        for child in self._children.values():
            if isinstance(child, Container):
                child._forget_preemptions()
            else:
                child._reset_after_run()
