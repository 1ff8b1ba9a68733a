"""`SwarmVecEnv`: every UAV of K copies of a scenario as one sub-environment of a stable-baselines3 VecEnv.

One policy then flies every UAV (the shared policy of issue 31), and the K copies share one magna_sim
world, which is how the gym reaches its speed (mlr.gym.fleet). Sub-environment i is UAV i % M of copy
i // M, M being the scenario's UAV count. Observation, action and reward are MagnaNavEnv's.

Episodes, per sub-environment:
- a UAV that reaches its goal earns the goal bonus and flies on to its next goal in the same episode, as
  along a mission's path. (Ending the episode there would hide from the policy a collision just after
  a goal: the bonus would be its last reward, whatever came next.);
- a collision (mlr.gym.swarm) ends the episode of every UAV of that copy: terminated for those that collided, truncated
  for the others (their episode was cut, not finished), and the copy starts again;
- after `max_steps` control steps the copy's episodes are truncated and it starts again;
- a share `encounters` of the copies' starts puts the first two UAVs on a collision course instead of at
  their take-off points (Swarm.encounter_starts), for a policy to meet often what a mission holds rarely.
Ended episodes give SB3's `terminal_observation` and `TimeLimit.truncated` in their info.
"""
from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from magna_uav.nai.simple import saturate
from mlr.gym.reward import RewardWeights, StepOutcome, reward_terms
from mlr.gym.scenario import Scenario
from mlr.gym.swarm import Swarm


class SwarmVecEnv(VecEnv):
    def __init__(self, scenario: Scenario, copies: int = 4, n_neighbors: int = 1, n_obstacles: int = 2,
                 neighbor_dist: float = 6.0, max_steps: int = 600, weights: RewardWeights = RewardWeights(),
                 seed: int = 0, encounters: float = 0.0):
        if not 0.0 <= encounters <= 1.0:
            raise ValueError(f"encounters: {encounters!r} is the share of episodes started on a collision course; "
                             "give a number in 0..1")
        speeds = {uav.max_speed for uav in scenario.uavs}
        if len(speeds) != 1:
            raise ValueError(f"scenario {scenario.mission_name}: its UAVs have max speeds {sorted(speeds)}; one "
                             "shared policy needs one action space, so one airframe speed")
        self.swarm = Swarm(scenario, n_neighbors, n_obstacles, neighbor_dist, copies)
        self.copies, self.uav_count = copies, len(scenario.uavs)
        self.max_speed = speeds.pop()
        self.max_steps, self.weights, self.encounters = max_steps, weights, encounters
        observation_space = gym.spaces.Box(-np.inf, np.inf, (self.swarm.observation_size,), np.float32)
        action_space = gym.spaces.Box(-self.max_speed, self.max_speed, (3,), np.float32)
        super().__init__(copies * self.uav_count, observation_space, action_space)
        self._rngs = [np.random.default_rng([seed, c]) for c in range(copies)]  # one per copy: restarts apart
        self._steps = np.zeros(copies, dtype=int)
        self._previous = np.zeros((copies, self.uav_count, 3))
        self._actions = np.zeros((self.num_envs, 3))

    # --- VecEnv -------------------------------------------------------------------------------------------------
    def reset(self):
        for c in range(self.copies):
            given = self._seeds[c * self.uav_count]
            self._start(c, int(given) if given is not None else None)
        self._reset_seeds()
        return self._observations()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=float).reshape(self.num_envs, 3)

    def step_wait(self):
        swarm, m = self.swarm, self.uav_count
        clipped = np.clip(self._actions, -self.max_speed, self.max_speed)
        commands = np.array([saturate(a, self.max_speed) for a in clipped]).reshape(self.copies, m, 3)
        before = np.array([[swarm.distance(j, c) for j in range(m)] for c in range(self.copies)])
        collisions = swarm.fly(commands)
        self._steps += 1
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        restart = []
        for c in range(self.copies):
            crashed = any((c, j) in collisions for j in range(m))
            out_of_time = self._steps[c] >= self.max_steps
            for j in range(m):
                i, collided, after = c * m + j, (c, j) in collisions, swarm.distance(j, c)
                terms = reward_terms(StepOutcome(before[c, j], after, swarm.gap(j, c), collided, commands[c, j],
                                                 self._previous[c, j], self.max_speed), self.weights)
                rewards[i] = sum(terms.values())
                # a UAV that reached its goal flies on to the next, in the same episode, as along a mission's path
                reached = not collided and swarm.arrive(j, self.weights.goal_radius, c)
                infos[i] = {"reward_terms": terms, "collided": collided, "reached": reached}
                if crashed or out_of_time:
                    dones[i] = True
                    infos[i]["terminal_observation"] = swarm.observation(j, c)
                    infos[i]["TimeLimit.truncated"] = not collided
            self._previous[c] = commands[c]
            if crashed or out_of_time:
                restart.append(c)
        for c in restart:
            self._start(c, None)
        return self._observations(), rewards, dones, infos

    def close(self) -> None:
        self.swarm.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self, attr_name, None) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list:
        return [getattr(self, method_name)(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    # --- helpers ------------------------------------------------------------------------------------------------
    def _start(self, copy: int, seed: int | None) -> None:
        if seed is not None:
            self._rngs[copy] = np.random.default_rng(seed)
        rng = self._rngs[copy]
        episode_seed = int(rng.integers(2 ** 31))
        self.swarm.start(episode_seed, copy, encounter=bool(rng.random() < self.encounters))
        self._steps[copy] = 0
        self._previous[copy] = 0.0

    def _observations(self) -> np.ndarray:
        return np.array([self.swarm.observation(j, c) for c in range(self.copies) for j in range(self.uav_count)])
