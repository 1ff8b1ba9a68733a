"""Seeded random ORCA-3D situations for the property tests and the benchmark.

A scenario is one agent and its neighbours drawn around it: mixed radii, speeds and
headings, some neighbours non-cooperative (still obstacles or UAVs that keep course),
some already overlapping the agent, so every branch of the half-space and the
infeasible fallback is exercised.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magna_orca_cpp.model import Agent, Params, Problem


@dataclass
class Scenario(Problem):
    """A drawn problem (so a list of them can go to the many-call as it is)."""

    neighbors: list[Agent]


def random_agent(rng: np.random.Generator, centre: np.ndarray, spread: float, max_speed: float) -> Agent:
    position = centre + rng.uniform(-spread, spread, 3)
    velocity = rng.normal(0.0, max_speed / 2, 3)
    preferred = rng.normal(0.0, max_speed / 1.5, 3)
    cooperative = rng.random() > 0.25
    if not cooperative and rng.random() < 0.5:
        velocity[:] = 0.0  # a static obstacle
        preferred[:] = 0.0
    return Agent(position, velocity, preferred, radius=rng.uniform(0.2, 1.0),
                 max_speed=rng.uniform(0.5, 1.5) * max_speed, cooperative=cooperative)


def random_scenario(rng: np.random.Generator, n_neighbors: int, params: Params | None = None) -> Scenario:
    params = params or Params(max_neighbors=n_neighbors, neighbor_dist=8.0, time_horizon=rng.uniform(0.5, 6.0),
                              time_step=0.1, max_speed=2.0)
    agent = random_agent(rng, np.zeros(3), 0.0, params.max_speed)
    agent.cooperative = True
    spread = 2.0 + 0.5 * n_neighbors ** (1 / 3)  # denser with more neighbours, so programs get infeasible
    neighbors = [random_agent(rng, np.zeros(3), spread, params.max_speed) for _ in range(n_neighbors)]
    return Scenario(agent, neighbors, params)


def scenarios(seed: int, count: int, n_neighbors: int | tuple[int, int]) -> list[Scenario]:
    """`count` scenarios; n_neighbors fixed, or drawn from the inclusive range (low, high)."""
    rng = np.random.default_rng(seed)
    result = []
    for _ in range(count):
        n = n_neighbors if isinstance(n_neighbors, int) else int(rng.integers(n_neighbors[0], n_neighbors[1] + 1))
        result.append(random_scenario(rng, n))
    return result


def crowd(seed: int, n_agents: int, spacing: float = 2.0, params: Params | None = None) -> list[Agent]:
    """`n_agents` cooperative agents on a jittered cubic grid, each wanting to cross to the other side."""
    rng = np.random.default_rng(seed)
    params = params or Params()
    side = int(np.ceil(n_agents ** (1 / 3)))
    cells = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n_agents]
    positions = (cells - (side - 1) / 2) * spacing + rng.uniform(-0.2, 0.2, (n_agents, 3))
    agents = []
    for position in positions:
        to_centre = -position
        norm = np.linalg.norm(to_centre)
        preferred = to_centre / norm * params.max_speed if norm > 0 else np.zeros(3)
        agents.append(Agent(position, preferred * 0.5, preferred, radius=0.5, max_speed=params.max_speed))
    return agents
