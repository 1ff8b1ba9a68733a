"""Value types shared by the numpy reference, the ctypes binding and the service clients.

An agent is a sphere that moves; non-cooperative agents (static obstacles, UAVs that do
not avoid) keep their course and leave the whole avoidance to whoever meets them.
The row layouts match the C interface (include/magna_orca_cpp/c_api.h).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

AGENT_FIELDS = 12  # px py pz vx vy vz pvx pvy pvz radius max_speed cooperative
PARAM_FIELDS = 6  # max_neighbors time_step neighbor_dist time_horizon agent_radius max_speed
PLANE_FIELDS = 6  # point xyz, unit normal xyz

# algorithm_control names (as missions write them) -> Params fields
ALGORITHM_CONTROL_NAMES = {
    "N_neighbors_aware": "max_neighbors",
    "timeStep": "time_step",
    "neighborDist": "neighbor_dist",
    "timeHorizon": "time_horizon",
    "agent_radius": "agent_radius",
    "maxSpeed": "max_speed",
}


def _vector(value) -> np.ndarray:
    return np.array(value, dtype=float).reshape(3)


@dataclass
class Agent:
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    preferred_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radius: float = 0.0  # 0 takes Params.agent_radius
    max_speed: float = 0.0  # 0 takes Params.max_speed
    cooperative: bool = True

    def __post_init__(self) -> None:
        self.position = _vector(self.position)
        self.velocity = _vector(self.velocity)
        self.preferred_velocity = _vector(self.preferred_velocity)
        self.radius = float(self.radius)
        self.max_speed = float(self.max_speed)
        self.cooperative = bool(self.cooperative)

    def row(self) -> np.ndarray:
        return np.concatenate([self.position, self.velocity, self.preferred_velocity,
                               [self.radius, self.max_speed, 1.0 if self.cooperative else 0.0]])

    @classmethod
    def from_row(cls, row: Sequence[float]) -> Agent:
        values = np.asarray(row, dtype=float)
        return cls(values[0:3], values[3:6], values[6:9], values[9], values[10], bool(values[11]))


@dataclass
class Params:
    """Solver parameters, named after the mission's algorithm_control keys."""

    max_neighbors: int = 10  # N_neighbors_aware
    time_step: float = 1.0 / 60.0  # timeStep (s): used when two agents already overlap
    neighbor_dist: float = 6.0  # neighborDist (m): largest gap between surfaces that is looked at
    time_horizon: float = 5.0  # timeHorizon (s)
    agent_radius: float = 0.5  # agent_radius (m): radius of agents that give none
    max_speed: float = 2.0  # maxSpeed (m/s): speed limit of agents that give none

    def row(self) -> np.ndarray:
        return np.array([self.max_neighbors, self.time_step, self.neighbor_dist, self.time_horizon,
                         self.agent_radius, self.max_speed], dtype=float)

    @classmethod
    def from_algorithm_control(cls, values: Mapping[str, float], base: Params | None = None) -> Params:
        """Params from an algorithm_control mapping such as {"timeHorizon": 5.0}; unknown names are refused."""
        merged = dict(vars(base if base is not None else cls()))
        for name, value in values.items():
            if name not in ALGORITHM_CONTROL_NAMES:
                known = ", ".join(ALGORITHM_CONTROL_NAMES)
                raise ValueError(f"algorithm_control parameter {name!r} is not an ORCA-3D parameter; known: {known}")
            merged[ALGORITHM_CONTROL_NAMES[name]] = value
        merged["max_neighbors"] = int(merged["max_neighbors"])
        return cls(**merged)


@dataclass
class Solution:
    velocity: np.ndarray
    feasible: bool  # False: no velocity met every half-space; the least violating one is given


@dataclass
class Problem:
    """One agent's own one-shot problem: the agent, the agents it sees, its parameters.

    Several go in one call to the many service (OrcaComputeVelocityMany), each solved as if alone.
    """

    agent: Agent
    neighbors: Sequence[Agent]
    params: Params


def agent_rows(agents: Sequence[Agent]) -> np.ndarray:
    """(n, 12) rows in the C interface's layout (`Agent.row` of each), filled column by column: twice
    as fast as stacking rows, which counts for the hundreds of agents of a many-call."""
    if not agents:
        return np.zeros((0, AGENT_FIELDS))
    rows = np.empty((len(agents), AGENT_FIELDS))
    rows[:, 0:3] = [agent.position for agent in agents]
    rows[:, 3:6] = [agent.velocity for agent in agents]
    rows[:, 6:9] = [agent.preferred_velocity for agent in agents]
    rows[:, 9:] = [(agent.radius, agent.max_speed, 1.0 if agent.cooperative else 0.0) for agent in agents]
    return rows


def with_defaults(agent: Agent, params: Params) -> Agent:
    """A copy whose radius and max speed of 0 take the defaults in `params`."""
    return Agent(agent.position, agent.velocity, agent.preferred_velocity,
                 agent.radius if agent.radius != 0.0 else params.agent_radius,
                 agent.max_speed if agent.max_speed != 0.0 else params.max_speed,
                 agent.cooperative)
