"""Simple guidance: straight at the goal, linear braking, feed-forward for following roles, heading."""
import math

import numpy as np
import pytest

from magna_uav.nai.goal import Goal
from magna_uav.nai.simple import heading_rate, simple_velocity, wrap_angle
from magna_uav.world_view import AgentState


def state(position, yaw=0.0, velocity=(0, 0, 0)):
    return AgentState(1, position, orientation=[0, 0, math.sin(yaw / 2), math.cos(yaw / 2)], velocity=velocity)


def test_reaches_the_goal_without_overshoot_in_a_kinematic_loop():
    start, goal = np.array([0.0, 0.0, 1.0]), np.array([7.0, 3.0, 2.0])
    own, dt, max_speed = state(start), 1 / 30, 2.0
    distances, speeds = [], []
    for _ in range(int(15 / dt)):
        velocity, _ = simple_velocity(own, Goal(goal), max_speed, braking_distance=2.0)
        speeds.append(float(np.linalg.norm(velocity)))
        own.position = own.position + velocity * dt
        distances.append(float(np.linalg.norm(goal - own.position)))
        # never past the goal: still on the start side of it, along the straight line
        assert (own.position - goal) @ (start - goal) >= 0.0
        assert np.linalg.norm(np.cross(own.position - start, goal - start)) < 1e-9
    assert distances[-1] < 0.01
    assert all(b <= a for a, b in zip(distances, distances[1:], strict=False)), "the distance only shrinks"
    assert max(speeds) == pytest.approx(max_speed) and speeds[0] == pytest.approx(max_speed)
    assert all(s <= max_speed + 1e-12 for s in speeds)


def test_speed_profile_is_full_speed_outside_and_linear_inside_the_braking_distance():
    goal = Goal([0, 0, 0])
    for distance, expected in [(0.0, 0.0), (0.5, 0.5), (1.5, 1.5), (3.0, 2.0), (30.0, 2.0)]:
        velocity, _ = simple_velocity(state([distance, 0, 0]), goal, max_speed=2.0, braking_distance=3.0)
        assert np.linalg.norm(velocity) == pytest.approx(expected * 2.0 / 3.0 if distance < 3.0 else expected)
        if distance > 0:
            np.testing.assert_allclose(velocity / np.linalg.norm(velocity), [-1, 0, 0])
    # default braking distance: max_speed * 1 s
    velocity, _ = simple_velocity(state([1.0, 0, 0]), goal, max_speed=2.0)
    assert np.linalg.norm(velocity) == pytest.approx(1.0)


def track(role, steps=600, dt=0.05):
    """Follow a target moving at 0.5 m/s along x at offset (0, 2, 0); return the final tracking error."""
    target_velocity, offset = np.array([0.5, 0.0, 0.0]), np.array([0.0, 2.0, 0.0])
    own, target = state([0, 0, 5]), np.array([0.0, 0.0, 5.0])
    for _ in range(steps):
        goal = Goal(target + offset, role=role, velocity=target_velocity,
                    offset=offset if role == "agent_ap" else None)
        velocity, _ = simple_velocity(own, goal, max_speed=2.0, braking_distance=2.0)
        own.position = own.position + velocity * dt
        target = target + target_velocity * dt
    return float(np.linalg.norm(target + offset - own.position))


def test_following_roles_use_the_target_velocity_as_feed_forward():
    assert track("agent_ap") < 1e-6
    # without feed-forward the linear profile lags by v_target * b / max_speed = 0.5 m
    assert track("path") == pytest.approx(0.5, abs=1e-3)


def test_feed_forward_is_saturated_to_max_speed():
    goal = Goal([10, 0, 0], role="agent_ad", velocity=[5, 0, 0], distance=1.0)
    velocity, _ = simple_velocity(state([0, 0, 0]), goal, max_speed=2.0)
    assert np.linalg.norm(velocity) == pytest.approx(2.0)
    np.testing.assert_allclose(velocity, [2, 0, 0])


def test_heading_turns_towards_goal_yaw_or_travel_direction():
    # goal yaw: proportional, clipped
    _, rate = simple_velocity(state([0, 0, 0]), Goal([0, 0, 0], yaw=0.3), 2.0, heading="goal", yaw_gain=1.0,
                              max_yaw_rate=1.0)
    assert rate == pytest.approx(0.3)
    _, rate = simple_velocity(state([0, 0, 0]), Goal([0, 0, 0], yaw=-2.0), 2.0, heading="goal", max_yaw_rate=0.5)
    assert rate == pytest.approx(-0.5)
    # no goal yaw: no turn
    assert simple_velocity(state([0, 0, 0]), Goal([5, 5, 0]), 2.0, heading="goal")[1] == 0.0
    # travel: face the direction of motion (here +y, 90 degrees left)
    _, rate = simple_velocity(state([0, 0, 0]), Goal([0, 5, 0]), 2.0, heading="travel", max_yaw_rate=10.0)
    assert rate == pytest.approx(math.pi / 2)
    assert simple_velocity(state([0, 0, 0]), Goal([0, 5, 0], yaw=1.0), 2.0, heading="none")[1] == 0.0
    # the short way round through +-pi
    assert heading_rate(3.0, -3.0, np.zeros(3), "goal", 1.0, 10.0) == pytest.approx(2 * math.pi - 6.0)
    assert wrap_angle(3 * math.pi) == pytest.approx(-math.pi)
    # travel when (nearly) stopped falls back to the goal's yaw
    assert heading_rate(0.0, 0.2, np.array([0.01, 0, 0]), "travel", 1.0, 1.0) == pytest.approx(0.2)
    with pytest.raises(ValueError, match="heading is 'spin': give one of none, goal, travel"):
        heading_rate(0.0, None, np.zeros(3), "spin")


def test_bad_arguments_and_goals_are_refused_naming_the_field():
    with pytest.raises(ValueError, match="max_speed is 0"):
        simple_velocity(state([0, 0, 0]), Goal([1, 0, 0]), 0.0)
    with pytest.raises(ValueError, match="braking_distance is -1"):
        simple_velocity(state([0, 0, 0]), Goal([1, 0, 0]), 1.0, -1.0)
    with pytest.raises(ValueError, match="Goal.role is 'orbit': give one of path, agent_ad, agent_ap, basic_move"):
        Goal([0, 0, 0], role="orbit")
    with pytest.raises(ValueError, match="Goal.distance is missing"):
        Goal([0, 0, 0], role="agent_ad")
    with pytest.raises(ValueError, match=r"Goal.position is \[nan, 0.0, 0.0\]: give finite numbers"):
        Goal([math.nan, 0, 0])
    with pytest.raises(ValueError, match="Goal.velocity is .*give three numbers"):
        Goal([0, 0, 0], velocity=[1, 2])
    with pytest.raises(ValueError, match="Goal.distance is -2.0"):
        Goal([0, 0, 0], role="agent_ad", distance=-2)
