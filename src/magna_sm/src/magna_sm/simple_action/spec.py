"""The message classes an action spec (e.g. `TakeOffAction`) bundles, and time helpers."""
from typing import NamedTuple

import rospy


class ActionSpecError(TypeError):
    """The class given as an action spec is not a generated `*Action` message."""


class ActionTypes(NamedTuple):
    spec: type
    action_goal: type      # header, goal_id, goal        -> the `goal` topic
    action_result: type    # header, status, result       -> the `result` topic
    action_feedback: type  # header, status, feedback     -> the `feedback` topic
    goal: type
    result: type
    feedback: type


def action_types(spec) -> ActionTypes:
    try:
        sample = spec()
        return ActionTypes(
            spec=spec,
            action_goal=type(sample.action_goal),
            action_result=type(sample.action_result),
            action_feedback=type(sample.action_feedback),
            goal=type(sample.action_goal.goal),
            result=type(sample.action_result.result),
            feedback=type(sample.action_feedback.feedback),
        )
    except (AttributeError, TypeError) as error:
        raise ActionSpecError(f"not an action spec (a generated *Action message class): {spec!r}") from error


def as_duration(value) -> rospy.Duration:
    """A `rospy.Duration` from a Duration, a number of seconds or None (zero)."""
    if isinstance(value, rospy.Duration):
        return value
    if value is None:
        return rospy.Duration()
    return rospy.Duration.from_sec(float(value))


def action_topic(ns: str, leaf: str) -> str:
    """`<ns>/<leaf>`, with the namespace remapped as a node's command line asks."""
    return f"{rospy.remap_name(ns).rstrip('/')}/{leaf}"
