"""mlr.gym.reward: each term on hand-made steps."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mlr.gym.reward import RewardWeights, StepOutcome, reward, reward_terms

W = RewardWeights()


def step(**change) -> StepOutcome:
    cruising = StepOutcome(distance_before=5.0, distance_after=4.8, gap=math.inf, collided=False,
                           command=np.array([2.0, 0.0, 0.0]), previous_command=np.array([2.0, 0.0, 0.0]),
                           max_speed=2.0)
    return dataclasses.replace(cruising, **change)


def test_free_flight_towards_the_goal_earns_the_distance_gained_less_the_time():
    terms = reward_terms(step())
    assert terms["progress"] == pytest.approx(0.2)
    assert terms["goal"] == terms["collision"] == terms["near_miss"] == terms["smoothness"] == 0.0
    assert reward(step()) == pytest.approx(0.2 - W.time_penalty)
    # flying away loses what flying towards gains: circling earns nothing
    assert reward_terms(step(distance_before=4.8, distance_after=5.0))["progress"] == pytest.approx(-0.2)


def test_reaching_the_goal_pays_the_bonus_once_inside_its_radius():
    assert reward_terms(step(distance_after=0.5))["goal"] == W.goal_bonus
    assert reward_terms(step(distance_after=0.51))["goal"] == 0.0
    assert reward_terms(step(distance_after=0.1, collided=True, gap=-0.01))["goal"] == 0.0  # not by crashing in


def test_a_collision_costs_the_penalty_and_the_whole_near_miss():
    terms = reward_terms(step(collided=True, gap=-0.02))
    assert terms["collision"] == -W.collision_penalty
    assert terms["near_miss"] == -W.near_miss_weight


@pytest.mark.parametrize("gap,share", [(0.2, 0.0), (0.3, 0.0), (0.1, 0.5), (0.05, 0.75), (0.0, 1.0)])
def test_the_near_miss_grows_linearly_inside_orca3ds_margin(gap, share):
    assert reward_terms(step(gap=gap))["near_miss"] == pytest.approx(-W.near_miss_weight * share)


def test_smoothness_costs_the_squared_change_of_command_relative_to_max_speed():
    turned = step(command=np.array([0.0, 2.0, 0.0]))  # a right-angle turn at full speed: |change|^2 = 8
    assert reward_terms(turned)["smoothness"] == pytest.approx(-W.smoothness_weight * 8 / 4)
    assert reward_terms(step(previous_command=np.zeros(3)))["smoothness"] == pytest.approx(-W.smoothness_weight)
