"""magna_sm: hierarchical state machines for MAGNA missions.

The core (states, containers, userdata, validation) imports no ROS; the
SimpleAction protocol, SimpleActionState and introspection live in modules
that do, imported only when used.
"""
from magna_sm.concurrence import Concurrence
from magna_sm.container import PREEMPTED, Container, ContainerEvent, ContainerStructure
from magna_sm.exceptions import (
    InvalidOutcomeError,
    StateExecutionError,
    StateMachineError,
    UserDataError,
    ValidationError,
)
from magna_sm.iterator import Iterator
from magna_sm.sequence import Sequence
from magna_sm.state import CBState, State
from magna_sm.state_machine import StateMachine
from magna_sm.userdata import Remapper, UserData

__all__ = [
    "PREEMPTED", "CBState", "Concurrence", "Container", "ContainerEvent", "ContainerStructure", "InvalidOutcomeError",
    "Iterator", "Remapper", "Sequence", "State", "StateExecutionError", "StateMachine", "StateMachineError",
    "UserData", "UserDataError", "ValidationError",
]
