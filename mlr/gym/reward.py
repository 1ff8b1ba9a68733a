"""The gym's reward for one UAV and one control step, term by term.

    progress   + progress_weight * (distance to goal before the step - after), in metres
    goal       + goal_bonus when the UAV comes within goal_radius of its goal
    collision  - collision_penalty when it collides, as the UAV manager counts it (mlr.gym.swarm); its episode ends
    near_miss  - near_miss_weight * (1 - gap / near_miss_distance) while the gap to the nearest UAV or
                 obstacle surface, beyond both safety radii, is below near_miss_distance (all of it on a collision)
    smoothness - smoothness_weight * |command - previous command|^2 / max_speed^2
    time       - time_penalty every step, so that hovering never pays

Progress rewards flying towards the goal at any speed the airframe allows, and sums over an episode to
the distance covered towards it: no shaping that a policy could farm by circling. The near-miss term
starts where ORCA-3D's margin ends (its agent_radius beyond the safety radius) and is what separates
keeping ORCA-3D's margin from grazing a sphere; the collision term is what ends an episode.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class RewardWeights:
    progress_weight: float = 1.0  # per metre closer to the goal
    goal_bonus: float = 10.0
    goal_radius: float = 0.5  # m
    collision_penalty: float = 20.0
    near_miss_weight: float = 0.5
    near_miss_distance: float = 0.2  # m of gap: ORCA-3D's margin, its agent_radius 0.5 less the 0.3 safety radius
    smoothness_weight: float = 0.05
    time_penalty: float = 0.01

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class StepOutcome:
    """What one control step did to one UAV, as the reward needs it."""

    distance_before: float  # m to its goal
    distance_after: float
    gap: float  # m from its surface to the nearest other UAV's or obstacle's, inf when none; <= 0 touching
    collided: bool
    command: np.ndarray  # (3,) m/s sent this step
    previous_command: np.ndarray  # (3,) m/s sent the step before (zeros at the first)
    max_speed: float  # m/s


def reward_terms(outcome: StepOutcome, weights: RewardWeights = RewardWeights()) -> dict[str, float]:
    """Each term of the module docstring, signed as it enters the reward; their sum is the reward."""
    reached = outcome.distance_after <= weights.goal_radius
    if outcome.collided or not np.isfinite(outcome.gap) or outcome.gap >= weights.near_miss_distance:
        closeness = 0.0 if not outcome.collided else 1.0
    else:
        closeness = 1.0 - max(outcome.gap, 0.0) / weights.near_miss_distance
    change = np.asarray(outcome.command, dtype=float) - np.asarray(outcome.previous_command, dtype=float)
    return {
        "progress": weights.progress_weight * (outcome.distance_before - outcome.distance_after),
        "goal": weights.goal_bonus if reached and not outcome.collided else 0.0,
        "collision": -weights.collision_penalty if outcome.collided else 0.0,
        "near_miss": -weights.near_miss_weight * closeness,
        "smoothness": -weights.smoothness_weight * float(change @ change) / outcome.max_speed ** 2,
        "time": -weights.time_penalty,
    }


def reward(outcome: StepOutcome, weights: RewardWeights = RewardWeights()) -> float:
    return float(sum(reward_terms(outcome, weights).values()))
