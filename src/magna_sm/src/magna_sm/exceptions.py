"""Errors of the state-machine engine; each names the state or container path it is about."""
from __future__ import annotations


class StateMachineError(Exception):
    """Base of every engine error."""


class ValidationError(StateMachineError):
    """A machine that cannot run as built. `problems` lists every finding, each starting with its path."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("invalid state machine:\n  " + "\n  ".join(self.problems))


class UserDataError(StateMachineError, KeyError):
    """A state read or wrote a userdata key it did not declare, or wrote a read-only key."""

    def __str__(self) -> str:  # KeyError would print the message quoted
        return str(self.args[0]) if self.args else ""


class InvalidOutcomeError(StateMachineError):
    """A state returned an outcome it did not declare."""


class StateExecutionError(StateMachineError):
    """A state raised; the original exception is chained as __cause__."""
