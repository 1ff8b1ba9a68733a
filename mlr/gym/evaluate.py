"""How often a policy flies a whole mission's paths in the gym: the success rate `magna learn rl` states.

A training episode ends at a UAV's first goal; a mission is longer. Its follow_path states send each UAV
through one goal per path definition (seven each in the thesis's four-cylinder mission), with the other
UAVs on their own paths. So an evaluation flight starts every UAV where the take-off leaves it, sends it
through as many goals as its mission has path definitions, and is a success when every UAV has reached
all of its goals and none has collided (mlr.gym.swarm counts collisions as the UAV manager does). The
policy acts deterministically; a UAV that is done hovers at its last goal, in the others' way, as in a
mission. Flights run side by side as copies of one Swarm, so an evaluation costs seconds.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from mlr.gym.scenario import Scenario
from mlr.gym.swarm import Swarm

Policy = Callable[[np.ndarray], np.ndarray]  # (N, inputs) raw NAI input vectors -> (N, 3) velocity commands
STEPS_PER_GOAL = 300  # control steps (30 s) a flight is given per goal before it counts as timed out


@dataclass(frozen=True)
class Evaluation:
    flights: int
    succeeded: int  # every UAV through all its goals, no collision
    collided: int
    timed_out: int
    min_gap: float  # m, the smallest gap between safety spheres (UAVs or obstacles) seen in any flight

    @property
    def success_rate(self) -> float:
        return self.succeeded / self.flights

    def as_dict(self) -> dict:
        return asdict(self) | {"success_rate": self.success_rate}


def evaluate(policy: Policy, scenario: Scenario, flights: int = 16, seed: int = 10_000, n_neighbors: int = 1,
             n_obstacles: int = 2, neighbor_dist: float = 6.0, goal_radius: float = 0.5,
             steps_per_goal: int = STEPS_PER_GOAL) -> Evaluation:
    """Fly `flights` whole missions with `policy` (flight f draws its goals from seed + f)."""
    swarm = Swarm(scenario, n_neighbors, n_obstacles, neighbor_dist, copies=flights)
    try:
        uav_count = len(scenario.uavs)
        goals = np.array([len(uav.goal_definitions) for uav in scenario.uavs])
        for c in range(flights):
            swarm.start(seed + c * uav_count, c)  # Swarm.start seeds UAV j with seed + j: no two flights share one
        reached = np.zeros((flights, uav_count), dtype=int)
        collided = np.zeros(flights, dtype=bool)
        min_gap = np.inf
        for _ in range(steps_per_goal * int(goals.max())):
            flying = ~collided & (reached < goals).any(axis=1)
            if not flying.any():
                break
            inputs = np.array([swarm.observation(j, c) for c in range(flights) for j in range(uav_count)])
            commands = np.asarray(policy(inputs), dtype=float).reshape(flights, uav_count, 3)
            commands[(reached >= goals) | ~flying[:, None]] = 0.0  # done UAVs and ended flights hover
            hits = swarm.fly(commands)
            for c in map(int, np.flatnonzero(flying)):
                min_gap = min(min_gap, *(swarm.gap(j, c) for j in range(uav_count)))
                if any((c, j) in hits for j in range(uav_count)):
                    collided[c] = True
                    continue
                for j in range(uav_count):
                    if reached[c, j] < goals[j] and swarm.arrive(j, goal_radius, c):
                        reached[c, j] += 1
        succeeded = int(np.sum(~collided & (reached >= goals).all(axis=1)))
        return Evaluation(flights, succeeded, int(collided.sum()), flights - succeeded - int(collided.sum()),
                          float(min_gap))
    finally:
        swarm.close()
