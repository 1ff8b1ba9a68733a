"""mlr.gym.evaluate: whole missions flown in the gym, counted as succeeded, collided or timed out."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from magna_uav.nai.inputs import input_names
from mlr.gym.evaluate import evaluate
from mlr.gym.scenario import load_scenario
from tests.support import CORPUS

NAMES = input_names("path", 1, 0)
GOAL = [NAMES.index(f"goal_pose_rel.{axis}") for axis in "xyz"]


@pytest.fixture(scope="module")
def four():
    return load_scenario("Gym/Empty_4_Cylinders", "Gym/2UAVs_2paths_4_Cylinders", [CORPUS])


def straight_to_the_goal(inputs: np.ndarray) -> np.ndarray:
    return 2.0 * inputs[:, GOAL]  # saturated to the airframe's max speed by the gym


def test_a_lone_uav_flying_straight_reaches_every_goal_of_its_mission(four):
    alone = dataclasses.replace(four, uavs=four.uavs[:1])
    found = evaluate(straight_to_the_goal, alone, flights=3, n_obstacles=0)
    assert (found.succeeded, found.collided, found.timed_out) == (3, 0, 0)
    assert found.success_rate == 1.0 and found.min_gap == np.inf  # nobody to come near


def test_hovering_times_out_and_two_straight_flyers_meet_in_some_missions(four):
    hovering = evaluate(lambda x: np.zeros((len(x), 3)), four, flights=2, n_obstacles=0, steps_per_goal=20)
    assert (hovering.succeeded, hovering.collided, hovering.timed_out) == (0, 0, 2)
    start_gap = float(np.linalg.norm(four.uavs[0].start - four.uavs[1].start)) - 2 * four.uavs[0].safety_radius
    assert hovering.min_gap == pytest.approx(start_gap, abs=0.05)

    blind = evaluate(straight_to_the_goal, four, flights=16, n_obstacles=0)
    assert blind.succeeded + blind.collided + blind.timed_out == 16
    assert blind.collided >= 1 and blind.min_gap < 0  # no avoidance: some paths cross at the same time
    assert blind.as_dict()["success_rate"] == blind.succeeded / 16
