"""The Concurrence callbacks a mission may name: `outcome_cb` and `child_termination_cb`.

Both receive `{child label: outcome}` of the children ended so far (all of them, for an
outcome_cb). As in the original ROS-MAGNA ground station:

- outcome_cb `collision_if_any_collided`: "collision" when any child ended with
  "collision"; otherwise no decision (None), so the occurrencies_outcome_map and then
  the default outcome decide.
- child_termination_cb `all_at_one_collision`: as soon as one child ends with
  "collision", preempt every child still running.

A mission names them by these keys; `validate` refuses other names, and `plan` uses
`outcomes` to know what a Concurrence with an outcome_cb can end with.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

COLLISION = "collision"


def collision_if_any_collided(child_outcomes: Mapping[str, str]) -> str | None:
    return COLLISION if any(outcome == COLLISION for outcome in child_outcomes.values()) else None


def all_at_one_collision(child_outcomes: Mapping[str, str]) -> bool:
    return any(outcome == COLLISION for outcome in child_outcomes.values())


@dataclass(frozen=True)
class OutcomeCallback:
    function: Callable[[Mapping[str, str]], str | None]
    outcomes: tuple[str, ...]  # every outcome it may return (it may also return None: no decision)
    description: str


@dataclass(frozen=True)
class ChildTerminationCallback:
    function: Callable[[Mapping[str, str]], bool]
    description: str


OUTCOME_CALLBACKS: dict[str, OutcomeCallback] = {
    "collision_if_any_collided": OutcomeCallback(
        collision_if_any_collided, (COLLISION,),
        "'collision' when any child ended with 'collision'; else the outcome map decides"),
}

CHILD_TERMINATION_CALLBACKS: dict[str, ChildTerminationCallback] = {
    "all_at_one_collision": ChildTerminationCallback(
        all_at_one_collision, "preempt the other children as soon as one ends with 'collision'"),
}
