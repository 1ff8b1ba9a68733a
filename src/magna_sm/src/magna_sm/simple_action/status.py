"""Goal states of the actionlib protocol and the rules for moving between them.

The numeric states are those of `actionlib_msgs/GoalStatus`, so they mean the same
thing on the wire, in our code and in code written against actionlib.
"""
from actionlib_msgs.msg import GoalStatus

__all__ = [
    "ACTIVE_STATES",
    "GoalStatus",
    "PENDING_STATES",
    "SimpleGoalState",
    "TERMINAL_STATES",
    "is_terminal",
    "status_name",
]

#: States from which a goal never moves again.
TERMINAL_STATES = frozenset({
    GoalStatus.PREEMPTED,
    GoalStatus.SUCCEEDED,
    GoalStatus.ABORTED,
    GoalStatus.REJECTED,
    GoalStatus.RECALLED,
    GoalStatus.LOST,
})

#: Not yet accepted by the server (a cancel may be on its way: RECALLING).
PENDING_STATES = frozenset({GoalStatus.PENDING, GoalStatus.RECALLING})

#: Accepted and being worked on (a cancel may be on its way: PREEMPTING).
ACTIVE_STATES = frozenset({GoalStatus.ACTIVE, GoalStatus.PREEMPTING})

_NAMES = {
    value: name
    for name, value in vars(GoalStatus).items()
    if name.isupper() and isinstance(value, int) and not name.startswith("_")
}


def status_name(status: int) -> str:
    """`GoalStatus.SUCCEEDED` -> "SUCCEEDED" (for logs and error messages)."""
    return _NAMES.get(status, f"UNKNOWN({status})")


def is_terminal(status: int) -> bool:
    return status in TERMINAL_STATES


class SimpleGoalState:
    """The three-state view of a goal that a simple client offers."""

    PENDING = 0
    ACTIVE = 1
    DONE = 2

    @classmethod
    def to_string(cls, state: int) -> str:
        return {cls.PENDING: "PENDING", cls.ACTIVE: "ACTIVE", cls.DONE: "DONE"}.get(state, f"UNKNOWN({state})")


# Server-side moves allowed by the protocol, as (from-state, event) -> to-state.
# Events: "accept", "reject", "cancel_request", "canceled", "succeed", "abort".
SERVER_TRANSITIONS = {
    (GoalStatus.PENDING, "accept"): GoalStatus.ACTIVE,
    (GoalStatus.RECALLING, "accept"): GoalStatus.PREEMPTING,
    (GoalStatus.PENDING, "reject"): GoalStatus.REJECTED,
    (GoalStatus.RECALLING, "reject"): GoalStatus.REJECTED,
    (GoalStatus.PENDING, "cancel_request"): GoalStatus.RECALLING,
    (GoalStatus.ACTIVE, "cancel_request"): GoalStatus.PREEMPTING,
    (GoalStatus.PENDING, "canceled"): GoalStatus.RECALLED,
    (GoalStatus.RECALLING, "canceled"): GoalStatus.RECALLED,
    (GoalStatus.ACTIVE, "canceled"): GoalStatus.PREEMPTED,
    (GoalStatus.PREEMPTING, "canceled"): GoalStatus.PREEMPTED,
    (GoalStatus.ACTIVE, "succeed"): GoalStatus.SUCCEEDED,
    (GoalStatus.PREEMPTING, "succeed"): GoalStatus.SUCCEEDED,
    (GoalStatus.ACTIVE, "abort"): GoalStatus.ABORTED,
    (GoalStatus.PREEMPTING, "abort"): GoalStatus.ABORTED,
}

# What a client accepts to hear about its goal, given what it last heard. A status
# list published before a later change can arrive after the result that ended the
# goal; anything that would move a goal backwards is ignored.
CLIENT_NEXT_STATES = {
    GoalStatus.PENDING: frozenset({GoalStatus.PENDING, GoalStatus.RECALLING, GoalStatus.ACTIVE,
                                   GoalStatus.PREEMPTING}) | TERMINAL_STATES,
    GoalStatus.RECALLING: frozenset({GoalStatus.RECALLING, GoalStatus.PREEMPTING}) | TERMINAL_STATES,
    GoalStatus.ACTIVE: frozenset({GoalStatus.ACTIVE, GoalStatus.PREEMPTING, GoalStatus.PREEMPTED,
                                  GoalStatus.SUCCEEDED, GoalStatus.ABORTED}),
    GoalStatus.PREEMPTING: frozenset({GoalStatus.PREEMPTING, GoalStatus.PREEMPTED, GoalStatus.SUCCEEDED,
                                      GoalStatus.ABORTED}),
}
