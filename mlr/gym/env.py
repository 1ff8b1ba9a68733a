"""`MagnaNavEnv`: a Gymnasium environment in which one UAV of a MAGNA scenario learns to fly to its goals.

The learning UAV is the scenario's first; the others fly ORCA-3D (the NAI, with the mission's
parameters) to goals of their own, as in the thesis's missions. An episode starts with every UAV
hovering where the mission's take-off leaves it and ends when the learner reaches its goal
(terminated), collides (terminated; a collision as the UAV manager counts it, mlr.gym.swarm) or has
flown `max_steps` control steps (truncated).

- Observation: the NAI's input vector for the path role (magna_uav.nai.inputs, the one the supervised
  networks take), float32: own velocity, the goal relative to the UAV, the nearest `n_neighbors` UAVs'
  relative positions and velocities and the nearest `n_obstacles` obstacles' relative positions, padded.
- Action: the velocity command (m/s, map frame), each axis within ±max_speed and the whole saturated to
  max_speed, as the NAI saturates any command; sent at the control rate (10 Hz) through the UAL.
- Reward: mlr.gym.reward, term by term in `info["reward_terms"]`.
- With `depth=(width, height)`, the observation is a Dict: {"vector": the input vector, "depth": the UAV's
  forward depth image from magna_sim's camera model} (mlr.gym.depth).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from magna_uav.nai.goal import Goal
from magna_uav.nai.simple import saturate
from mlr.gym.depth import SwarmObservation
from mlr.gym.reward import RewardWeights, StepOutcome, reward_terms
from mlr.gym.scenario import Scenario, load_scenario
from mlr.gym.swarm import Swarm

LEARNER = 0  # index of the learning UAV in scenario.uavs


class MagnaNavEnv(gym.Env):
    metadata = {"render_modes": []}

    def __init__(self, world: str = "Gym/1Obs_Central_Cylinder", mission: str = "Gym/2UAVs_2paths_Central_Cylinder",
                 search_path: Sequence[Path] = (), n_neighbors: int = 1, n_obstacles: int = 2,
                 neighbor_dist: float = 6.0, max_steps: int = 600, weights: RewardWeights = RewardWeights(),
                 scenario: Scenario | None = None, depth: tuple[int, int] | None = None, depth_fov: float = 90.0):
        self.scenario = scenario if scenario is not None else load_scenario(world, mission, list(search_path))
        self.swarm = Swarm(self.scenario, n_neighbors, n_obstacles, neighbor_dist)
        self.max_steps, self.weights = max_steps, weights
        self.max_speed = self.scenario.uavs[LEARNER].max_speed
        self._observe = SwarmObservation(self.swarm, depth, depth_fov)
        self.observation_space = self._observe.space
        self.action_space = gym.spaces.Box(-self.max_speed, self.max_speed, (3,), np.float32)
        self._others = {j: self.swarm.orca(j) for j in range(len(self.scenario.uavs)) if j != LEARNER}
        self._previous_command = np.zeros(3)
        self._steps = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.swarm.start(int(self.np_random.integers(2 ** 31)))
        self._previous_command = np.zeros(3)
        self._steps = 0
        return self._observe(LEARNER), {"goal": self.swarm.goal(LEARNER).copy()}

    def step(self, action):
        swarm = self.swarm
        command = saturate(np.clip(np.asarray(action, dtype=float).reshape(3), -self.max_speed, self.max_speed),
                           self.max_speed)  # as the UAV is sent it
        before = swarm.distance(LEARNER)
        commands = np.zeros((len(self.scenario.uavs), 3))
        commands[LEARNER] = command
        for j, nav in self._others.items():
            commands[j] = nav.velocity(swarm.view(j), Goal(swarm.goal(j))).velocity
        collisions = swarm.fly(commands)
        self._steps += 1
        for j in self._others:  # the others go on to their next goal
            swarm.arrive(j, self.weights.goal_radius)
        collided = (0, LEARNER) in collisions
        after = swarm.distance(LEARNER)
        terms = reward_terms(StepOutcome(before, after, swarm.gap(LEARNER), collided, command, self._previous_command,
                                         self.max_speed), self.weights)
        self._previous_command = command
        reached = after <= self.weights.goal_radius and not collided
        info = {"reward_terms": terms, "goal": swarm.goal(LEARNER).copy(), "collided": collided, "reached": reached}
        return (self._observe(LEARNER), float(sum(terms.values())), collided or reached,
                self._steps >= self.max_steps and not (collided or reached), info)

    def close(self) -> None:
        self.swarm.close()
