"""What both gym environments share: one copy of a scenario in flight, its goals, and each UAV's view of it.

`Swarm` places the UAVs where the mission's take-off leaves them, draws every UAV's goals from the
mission's path definitions for an episode's seed, sends one control step of velocity commands, and
answers per UAV: the NAI's input vector, the distance to its goal, the gap to the nearest UAV or
obstacle, whether it touched anything. The single-agent environment (env.py) and the PettingZoo one
(parallel.py) differ only in who commands which UAV.
"""
from __future__ import annotations

import numpy as np

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs, input_size
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.simple import saturate
from magna_uav.world_view import AgentState, WorldView
from mlr.gym.fleet import Fleet
from mlr.gym.scenario import GymUav, Scenario

ROLE = "path"
GOALS_PER_EPISODE = 64  # drawn per UAV at reset; a UAV moves on to its next goal on arrival


class Swarm:
    def __init__(self, scenario: Scenario, n_neighbors: int = 1, n_obstacles: int = 2, neighbor_dist: float = 6.0):
        self.scenario = scenario
        self.n_neighbors, self.n_obstacles, self.neighbor_dist = n_neighbors, n_obstacles, neighbor_dist
        self.fleet = Fleet(scenario)
        self.uavs: tuple[GymUav, ...] = scenario.uavs
        self.observation_size = input_size(ROLE, n_neighbors, n_obstacles)
        self._goals = np.zeros((len(self.uavs), GOALS_PER_EPISODE, 3))
        self._next_goal = np.zeros(len(self.uavs), dtype=int)

    def close(self) -> None:
        self.fleet.close()

    def start(self, seed: int) -> None:
        """A new episode: goals drawn for `seed`, every UAV hovering at its take-off point."""
        for j, uav in enumerate(self.uavs):
            self._goals[j] = self.scenario.goals(uav, seed + j, GOALS_PER_EPISODE)
        self._next_goal[:] = 0
        lift = np.array([0.0, 0.0, self.scenario.take_off_height])
        self.fleet.place(0, np.array([uav.start + lift for uav in self.uavs]))

    def fly(self, commands: np.ndarray) -> set[int]:
        """Send (M, 3) velocity commands (each saturated to its UAV's max speed) for one control step; the
        indices of the UAVs that began touching something."""
        sent = np.array([saturate(np.asarray(c, dtype=float), uav.max_speed)
                         for c, uav in zip(commands, self.uavs, strict=True)])
        return {touch.uav for touch in self.fleet.control_step(sent[None])}

    def goal(self, j: int) -> np.ndarray:
        return self._goals[j, self._next_goal[j]]

    def next_goal(self, j: int) -> None:
        self._next_goal[j] = min(self._next_goal[j] + 1, GOALS_PER_EPISODE - 1)

    def distance(self, j: int) -> float:
        return float(np.linalg.norm(self.fleet.positions()[0, j] - self.goal(j)))

    def view(self, j: int) -> WorldView:
        """UAV j's WorldView: every UAV's true state and the obstacles as the NAI has them."""
        positions, velocities = self.fleet.positions()[0], self.fleet.velocities()[0]
        view = WorldView(j + 1, self.scenario.boundaries)
        for k, uav in enumerate(self.uavs):
            view.update_agent(AgentState(k + 1, positions[k], velocity=velocities[k],
                                         safety_radius=uav.safety_radius))
        view.set_obstacles(self.scenario.obstacles)
        return view

    def gap(self, j: int) -> float:
        """m from UAV j's safety sphere to the nearest other UAV's or obstacle's; inf when there is none."""
        view = self.view(j)
        gaps = [gap for _, gap in view.nearest_agents(1)] + [gap for _, gap in view.nearest_obstacles(1)]
        return min(gaps) if gaps else float("inf")

    def observation(self, j: int) -> np.ndarray:
        vector = build_inputs(self.view(j), Goal(self.goal(j)), ROLE, self.n_neighbors, self.n_obstacles,
                              self.neighbor_dist)
        return vector.astype(np.float32)

    def orca(self, j: int) -> NavigationInterface:
        """An ORCA-3D NAI for UAV j with the mission's parameters (the UAVs no policy flies)."""
        nav = NavigationInterface(self.uavs[j].max_speed, self.uavs[j].safety_radius)
        nav.control("orca3d", "set", *self.scenario.orca_params)
        return nav
