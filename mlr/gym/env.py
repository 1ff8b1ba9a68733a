"""`MagnaNavEnv`: a Gymnasium environment in which one UAV of a MAGNA scenario learns to fly to its goals.

The learning UAV is the scenario's first; the others fly ORCA-3D (the NAI, with the mission's
parameters) to goals of their own, as in the thesis's missions. An episode starts with every UAV
hovering where the mission's take-off leaves it and ends when the learner reaches its goal
(terminated), touches anything (terminated) or has flown `max_steps` control steps (truncated).

- Observation: the NAI's input vector for the path role (magna_uav.nai.inputs, the one the supervised
  networks take), float32: own velocity, the goal relative to the UAV, the nearest `n_neighbors` UAVs'
  relative positions and velocities and the nearest `n_obstacles` obstacles' relative positions, padded.
- Action: the velocity command (m/s, map frame), each axis within ±max_speed and the whole saturated to
  max_speed, as the NAI saturates any command; sent at the control rate (10 Hz) through the UAL.
- Reward: mlr.gym.reward, term by term in `info["reward_terms"]`.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs, input_size
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.simple import saturate
from magna_uav.world_view import AgentState, WorldView
from mlr.gym.fleet import Fleet
from mlr.gym.reward import RewardWeights, StepOutcome, reward_terms
from mlr.gym.scenario import Scenario, load_scenario

ROLE = "path"
LEARNER = 0  # index of the learning UAV in scenario.uavs
GOALS_PER_EPISODE = 64  # goals drawn per UAV at reset; the others take the next on arrival


class MagnaNavEnv(gym.Env):
    metadata = {"render_modes": []}

    def __init__(self, world: str = "Gym/1Obs_Central_Cylinder", mission: str = "Gym/2UAVs_2paths_Central_Cylinder",
                 search_path: Sequence[Path] = (), n_neighbors: int = 1, n_obstacles: int = 2,
                 neighbor_dist: float = 6.0, max_steps: int = 600, weights: RewardWeights = RewardWeights(),
                 scenario: Scenario | None = None):
        self.scenario = scenario if scenario is not None else load_scenario(world, mission, list(search_path))
        self.n_neighbors, self.n_obstacles, self.neighbor_dist = n_neighbors, n_obstacles, neighbor_dist
        self.max_steps, self.weights = max_steps, weights
        self.fleet = Fleet(self.scenario)
        learner = self.scenario.uavs[LEARNER]
        self.max_speed = learner.max_speed
        size = input_size(ROLE, n_neighbors, n_obstacles)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (size,), np.float32)
        self.action_space = gym.spaces.Box(-self.max_speed, self.max_speed, (3,), np.float32)
        self._teachers = [self._orca(uav) for uav in self.scenario.uavs]
        self._goals = np.zeros((len(self.scenario.uavs), GOALS_PER_EPISODE, 3))
        self._next_goal = np.zeros(len(self.scenario.uavs), dtype=int)
        self._previous_command = np.zeros(3)
        self._steps = 0

    def _orca(self, uav) -> NavigationInterface:
        nav = NavigationInterface(uav.max_speed, uav.safety_radius)
        nav.control("orca3d", "set", *self.scenario.orca_params)
        return nav

    # --- gymnasium API ------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        episode_seed = int(self.np_random.integers(2 ** 31))
        for j, uav in enumerate(self.scenario.uavs):
            self._goals[j] = self.scenario.goals(uav, episode_seed + j, GOALS_PER_EPISODE)
        self._next_goal[:] = 0
        lift = np.array([0.0, 0.0, self.scenario.take_off_height])
        self.fleet.place(0, np.array([uav.start + lift for uav in self.scenario.uavs]))
        self._previous_command = np.zeros(3)
        self._steps = 0
        return self._observation(), {"goal": self._goal(LEARNER).copy()}

    def step(self, action):
        command = saturate(np.clip(np.asarray(action, dtype=float).reshape(3), -self.max_speed, self.max_speed),
                           self.max_speed)
        before = self._distance(LEARNER)
        commands = np.zeros((1, len(self.scenario.uavs), 3))
        commands[0, LEARNER] = command
        for j in range(len(self.scenario.uavs)):
            if j != LEARNER:
                commands[0, j] = self._teachers[j].velocity(self._view(j), Goal(self._goal(j))).velocity
        touches = self.fleet.control_step(commands)
        self._steps += 1
        for j in range(len(self.scenario.uavs)):  # the others go on to their next goal
            if j != LEARNER and self._distance(j) <= self.weights.goal_radius:
                self._next_goal[j] = min(self._next_goal[j] + 1, GOALS_PER_EPISODE - 1)
        collided = any(t.uav == LEARNER for t in touches)
        after = self._distance(LEARNER)
        terms = reward_terms(StepOutcome(before, after, self._gap(LEARNER), collided, command,
                                         self._previous_command, self.max_speed), self.weights)
        self._previous_command = command
        reached = after <= self.weights.goal_radius and not collided
        info = {"reward_terms": terms, "goal": self._goal(LEARNER).copy(), "collided": collided,
                "reached": reached}
        return (self._observation(), float(sum(terms.values())), collided or reached,
                self._steps >= self.max_steps and not (collided or reached), info)

    def close(self) -> None:
        self.fleet.close()

    # --- helpers ------------------------------------------------------------------------------------------------
    def _goal(self, j: int) -> np.ndarray:
        return self._goals[j, self._next_goal[j]]

    def _distance(self, j: int) -> float:
        return float(np.linalg.norm(self.fleet.positions()[0, j] - self._goal(j)))

    def _view(self, j: int) -> WorldView:
        positions, velocities = self.fleet.positions()[0], self.fleet.velocities()[0]
        view = WorldView(j + 1, self.scenario.boundaries)
        for k, uav in enumerate(self.scenario.uavs):
            view.update_agent(AgentState(k + 1, positions[k], velocity=velocities[k],
                                         safety_radius=uav.safety_radius))
        view.set_obstacles(self.scenario.obstacles)
        return view

    def _gap(self, j: int) -> float:
        view = self._view(j)
        gaps = [gap for _, gap in view.nearest_agents(1)] + [gap for _, gap in view.nearest_obstacles(1)]
        return min(gaps) if gaps else float("inf")

    def _observation(self) -> np.ndarray:
        vector = build_inputs(self._view(LEARNER), Goal(self._goal(LEARNER)), ROLE, self.n_neighbors,
                              self.n_obstacles, self.neighbor_dist)
        return vector.astype(np.float32)
