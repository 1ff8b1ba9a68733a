"""`MagnaNavParallelEnv`: every UAV of a MAGNA scenario learns at once, as a PettingZoo parallel environment.

The agents are the scenario's UAVs, named "uav_<id>" as MAGNA names them. Each has the observation,
action and reward of the single-agent environment (env.py). An agent is done when it reaches its goal
or collides (terminated, as mlr.gym.swarm counts it); the UAV then hovers where it is and stays in the others' way. All
are truncated after `max_steps` control steps. A shared policy for every UAV is the usual use.
With `depth=(width, height)`, each agent's observation is a Dict with its depth image (mlr.gym.depth).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np
from pettingzoo import ParallelEnv

from magna_uav.nai.simple import saturate
from mlr.gym.depth import SwarmObservation
from mlr.gym.reward import RewardWeights, StepOutcome, reward_terms
from mlr.gym.scenario import Scenario, load_scenario
from mlr.gym.swarm import Swarm


class MagnaNavParallelEnv(ParallelEnv):
    metadata = {"name": "magna_nav_v0", "render_modes": []}

    def __init__(self, world: str = "Gym/1Obs_Central_Cylinder", mission: str = "Gym/2UAVs_2paths_Central_Cylinder",
                 search_path: Sequence[Path] = (), n_neighbors: int = 1, n_obstacles: int = 2,
                 neighbor_dist: float = 6.0, max_steps: int = 600, weights: RewardWeights = RewardWeights(),
                 scenario: Scenario | None = None, depth: tuple[int, int] | None = None, depth_fov: float = 90.0):
        self.scenario = scenario if scenario is not None else load_scenario(world, mission, list(search_path))
        self.swarm = Swarm(self.scenario, n_neighbors, n_obstacles, neighbor_dist)
        self.max_steps, self.weights = max_steps, weights
        self.possible_agents = [f"uav_{uav.id}" for uav in self.scenario.uavs]
        self._index = {name: j for j, name in enumerate(self.possible_agents)}
        self._observe = SwarmObservation(self.swarm, depth, depth_fov)
        self._observation_spaces = {name: self._observe.space for name in self.possible_agents}
        self._action_spaces = {
            name: gym.spaces.Box(-uav.max_speed, uav.max_speed, (3,), np.float32)
            for name, uav in zip(self.possible_agents, self.scenario.uavs, strict=True)}
        self.agents: list[str] = []
        self._previous = np.zeros((len(self.possible_agents), 3))
        self._steps = 0
        self._rng = np.random.default_rng()

    def observation_space(self, agent: str) -> gym.spaces.Space:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> gym.spaces.Box:
        return self._action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.swarm.start(int(self._rng.integers(2 ** 31)))
        self.agents = list(self.possible_agents)
        self._previous[:] = 0.0
        self._steps = 0
        observations = {name: self._observe(self._index[name]) for name in self.agents}
        return observations, {name: {"goal": self.swarm.goal(self._index[name]).copy()} for name in self.agents}

    def step(self, actions: dict):
        swarm = self.swarm
        commands = np.zeros((len(self.possible_agents), 3))  # done UAVs hover
        for name in self.agents:
            j = self._index[name]
            limit = self.scenario.uavs[j].max_speed
            commands[j] = saturate(np.clip(np.asarray(actions[name], dtype=float).reshape(3), -limit, limit), limit)
        before = {name: swarm.distance(self._index[name]) for name in self.agents}
        collisions = swarm.fly(commands)
        self._steps += 1
        observations, rewards, terminations, truncations, infos = {}, {}, {}, {}, {}
        for name in self.agents:
            j = self._index[name]
            collided, after = (0, j) in collisions, swarm.distance(j)
            terms = reward_terms(StepOutcome(before[name], after, swarm.gap(j), collided, commands[j],
                                             self._previous[j], self.scenario.uavs[j].max_speed), self.weights)
            reached = after <= self.weights.goal_radius and not collided
            observations[name] = self._observe(j)
            rewards[name] = float(sum(terms.values()))
            terminations[name] = collided or reached
            truncations[name] = self._steps >= self.max_steps and not terminations[name]
            infos[name] = {"reward_terms": terms, "goal": swarm.goal(j).copy(), "collided": collided,
                           "reached": reached}
        self._previous = commands
        self.agents = [name for name in self.agents if not (terminations[name] or truncations[name])]
        return observations, rewards, terminations, truncations, infos

    def close(self) -> None:
        self.swarm.close()
