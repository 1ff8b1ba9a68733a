"""Simple guidance: straight at the goal, braking linearly, with the target's velocity as feed-forward.

Speed profile. With `d` the distance from the UAV to `Goal.position` and `b` the braking
distance:

    speed(d) = max_speed * min(1, d / b)        direction: towards Goal.position

Outside `b` the UAV flies at `max_speed`; inside, the speed falls linearly to 0 at the
goal, so the approach is exponential with time constant `b / max_speed` and the UAV
never passes the goal. Stepped with a period `dt`, each step covers at most the fraction
`max_speed * dt / b` of the remaining distance, so there is no overshoot as long as
`dt <= b / max_speed` (30 Hz control with the default `b = max_speed * 1 s`: dt / (b /
max_speed) = 0.03). The goal is reached, in practice, once inside the airframe's
`accepted_target_radius`.

Following roles ("agent_ad", "agent_ap") add the target's velocity to the tracking term
(feed-forward), so a goal moving with the target is tracked without lag; the sum is saturated to
`max_speed` (norm), so a target faster than the UAV is chased at full speed.

Heading (`heading_rate`): "none" keeps the yaw (rate 0); "goal" turns towards `Goal.yaw`
when the goal has one (else rate 0); "travel" turns towards the horizontal direction of
the commanded velocity, or towards `Goal.yaw` (if any) once slower than 5 cm/s. The rate
is `yaw_gain * (wrapped yaw error)`, clipped to `max_yaw_rate`.
"""
from __future__ import annotations

import math

import numpy as np

from magna_uav.nai.goal import FOLLOWING_ROLES, Goal
from magna_uav.world_view import AgentState

HEADING_MODES = ("none", "goal", "travel")
DEFAULT_BRAKING_TIME = 1.0  # s: the default braking distance is max_speed times this
TRAVEL_MIN_SPEED = 0.05  # m/s: below this horizontal speed "travel" has no direction to face


def saturate(velocity: np.ndarray, max_speed: float) -> np.ndarray:
    """`velocity` scaled down to a norm of at most `max_speed`."""
    speed = float(np.linalg.norm(velocity))
    if speed > max_speed:
        return velocity * (max_speed / speed)
    return velocity


def wrap_angle(angle: float) -> float:
    """`angle` in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def heading_rate(yaw: float, goal_yaw: float | None, velocity: np.ndarray, mode: str = "goal",
                 yaw_gain: float = 1.0, max_yaw_rate: float = 1.0) -> float:
    """Yaw rate (rad/s) for the heading `mode` (see the module docstring)."""
    if mode not in HEADING_MODES:
        raise ValueError(f"heading is {mode!r}: give one of {', '.join(HEADING_MODES)}")
    target = None
    if mode == "goal":
        target = goal_yaw
    elif mode == "travel":
        if math.hypot(velocity[0], velocity[1]) >= TRAVEL_MIN_SPEED:
            target = math.atan2(velocity[1], velocity[0])
        else:
            target = goal_yaw
    if target is None:
        return 0.0
    rate = yaw_gain * wrap_angle(target - yaw)
    return float(min(max(rate, -max_yaw_rate), max_yaw_rate))


def tracking_velocity(position: np.ndarray, aim: np.ndarray, max_speed: float, braking_distance: float) -> np.ndarray:
    """The linear braking profile of the module docstring, without feed-forward."""
    to_aim = aim - position
    distance = float(np.linalg.norm(to_aim))
    if distance < 1e-12:
        return np.zeros(3)
    speed = max_speed * min(1.0, distance / braking_distance)
    return to_aim * (speed / distance)


def simple_velocity(own: AgentState, goal: Goal, max_speed: float, braking_distance: float | None = None,
                    heading: str = "goal", yaw_gain: float = 1.0,
                    max_yaw_rate: float = 1.0) -> tuple[np.ndarray, float]:
    """(velocity (3,) m/s in map, yaw rate rad/s) towards `goal`; `braking_distance` None is max_speed * 1 s."""
    if not math.isfinite(max_speed) or max_speed <= 0.0:
        raise ValueError(f"max_speed is {max_speed}: give a positive speed in m/s")
    if braking_distance is None:
        braking_distance = max_speed * DEFAULT_BRAKING_TIME
    if not math.isfinite(braking_distance) or braking_distance <= 0.0:
        raise ValueError(f"braking_distance is {braking_distance}: give a positive distance in metres")
    velocity = tracking_velocity(own.position, goal.position, max_speed, braking_distance)
    if goal.role in FOLLOWING_ROLES:
        velocity = velocity + goal.target_velocity
    velocity = saturate(velocity, max_speed)
    return velocity, heading_rate(own.yaw, goal.yaw, velocity, heading, yaw_gain, max_yaw_rate)
