"""THE definition of the neural networks' input vector, per role (mlr imports it; so does the NAI).

Every quantity is in the map frame, metres and m/s. Blocks, in this order ("-": not in
the role's vector):

| block | size | path | agent_ad | agent_ap | meaning |
|---|---|---|---|---|---|
| own_vel | 3 | 1st | 1st | 1st | own velocity |
| goal_pose_rel | 3 | 2nd | 2nd | 2nd | Goal.position - own position (the point the role flies to) |
| goal_vel | 3 | - | 3rd | 3rd | the target's velocity, Goal.velocity (zeros if None) |
| distance | 1 | - | 4th | - | the distance kept from the target, Goal.distance (m) |
| others_pos_rel | 3 N | 3rd | 5th | 4th | other UAVs' positions - own position |
| others_vel | 3 N | 4th | 6th | 5th | other UAVs' velocities (absolute, not relative) |
| obstacles_pos_rel | 3 M | 5th | 7th | 6th | obstacles' bounding-sphere centres - own position |

Sizes: path 6 + 6 N + 3 M, agent_ad 10 + 6 N + 3 M, agent_ap 9 + 6 N + 3 M.

Names: "own_vel.x", "goal_pose_rel.z", "distance", "others_pos_rel[0].x", "others_pos_rel[0].y",
..., "others_pos_rel[N-1].z", "others_vel[0].x", ..., "obstacles_pos_rel[M-1].z". The output
is one block, `OUTPUT` = "sel_vel" (3): the selected velocity (m/s, map frame).

Neighbours (`select_neighbors`, also what ORCA-3D avoids): the N other UAVs and the M
obstacles nearest by their gap (between safety spheres for UAVs; from the own safety sphere
to the obstacle's real shape for obstacles: `WorldView.nearest_agents`, `nearest_obstacles`),
only those with a gap below `neighbor_dist`, nearest first (ties by id / list order).

Padding: a missing neighbour or obstacle (fewer than N / M within `neighbor_dist`) is
filled with the relative position (PAD_FACTOR * neighbor_dist, 0, 0) = (2 neighbor_dist,
0, 0) and, for UAVs, velocity (0, 0, 0): a still thing straight along +x, well beyond
the neighbour distance, so it never needs avoiding. Padding always follows the real
entries. With the default neighbor_dist of 6 m the filler is (12, 0, 0). The filler depends
on neighbor_dist: train and fly a network with the same value.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from magna_orca_cpp.model import Params
from magna_uav.nai.goal import Goal
from magna_uav.world_view import AgentState, Obstacle, WorldView

INPUT_ROLES = ("path", "agent_ad", "agent_ap")
OUTPUT = "sel_vel"
OUTPUT_SIZE = 3
AXES = ("x", "y", "z")
PAD_FACTOR = 2.0  # padding sits at PAD_FACTOR * neighbor_dist along +x
DEFAULT_NEIGHBOR_DIST = Params().neighbor_dist  # m, the same default as ORCA-3D's neighborDist

ROLE_BLOCKS: dict[str, tuple[str, ...]] = {
    "path": ("own_vel", "goal_pose_rel", "others_pos_rel", "others_vel", "obstacles_pos_rel"),
    "agent_ad": ("own_vel", "goal_pose_rel", "goal_vel", "distance", "others_pos_rel", "others_vel",
                 "obstacles_pos_rel"),
    "agent_ap": ("own_vel", "goal_pose_rel", "goal_vel", "others_pos_rel", "others_vel", "obstacles_pos_rel"),
}
_PER_NEIGHBOR = ("others_pos_rel", "others_vel")
_PER_OBSTACLE = ("obstacles_pos_rel",)


def _check_role(role: str) -> None:
    if role not in ROLE_BLOCKS:
        raise ValueError(f"role {role!r} has no neural network inputs: give one of {', '.join(INPUT_ROLES)}")


def _check_count(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ValueError(f"{name} is {value!r}: give a whole number >= 0")
    return int(value)


def _check_neighbor_dist(neighbor_dist: float) -> float:
    neighbor_dist = float(neighbor_dist)
    if not math.isfinite(neighbor_dist) or neighbor_dist <= 0.0:
        raise ValueError(f"neighbor_dist is {neighbor_dist}: give a finite positive distance in metres "
                         "(the padding sits at twice it)")
    return neighbor_dist


def input_names(role: str, n_neighbors: int, n_obstacles: int) -> list[str]:
    """The input vector's element names, in order (module table)."""
    _check_role(role)
    n_neighbors = _check_count(n_neighbors, "n_neighbors")
    n_obstacles = _check_count(n_obstacles, "n_obstacles")
    names: list[str] = []
    for block in ROLE_BLOCKS[role]:
        if block == "distance":
            names.append(block)
        elif block in _PER_NEIGHBOR or block in _PER_OBSTACLE:
            count = n_neighbors if block in _PER_NEIGHBOR else n_obstacles
            names.extend(f"{block}[{i}].{axis}" for i in range(count) for axis in AXES)
        else:
            names.extend(f"{block}.{axis}" for axis in AXES)
    return names


def input_size(role: str, n_neighbors: int, n_obstacles: int) -> int:
    _check_role(role)
    fixed = {"path": 6, "agent_ad": 10, "agent_ap": 9}[role]
    return fixed + 6 * _check_count(n_neighbors, "n_neighbors") + 3 * _check_count(n_obstacles, "n_obstacles")


def output_names() -> list[str]:
    return [f"{OUTPUT}.{axis}" for axis in AXES]


def pad_position(neighbor_dist: float) -> np.ndarray:
    """The relative position that fills a missing neighbour or obstacle."""
    return np.array([PAD_FACTOR * _check_neighbor_dist(neighbor_dist), 0.0, 0.0])


@dataclass(frozen=True)
class Neighbors:
    """The UAVs and obstacles an algorithm takes into account, nearest first."""

    agents: tuple[AgentState, ...]
    obstacles: tuple[Obstacle, ...]

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(agent.id for agent in self.agents)

    @property
    def obstacle_names(self) -> tuple[str, ...]:
        return tuple(obstacle.name for obstacle in self.obstacles)


def select_neighbors(view: WorldView, n_neighbors: int, n_obstacles: int,
                     neighbor_dist: float = DEFAULT_NEIGHBOR_DIST) -> Neighbors:
    """The nearest `n_neighbors` UAVs and `n_obstacles` obstacles with a gap below `neighbor_dist`."""
    n_neighbors = _check_count(n_neighbors, "n_neighbors")
    n_obstacles = _check_count(n_obstacles, "n_obstacles")
    neighbor_dist = float(neighbor_dist)
    agents = tuple(a for a, _ in view.nearest_agents(n_neighbors, neighbor_dist)) if n_neighbors else ()
    obstacles = tuple(o for o, _ in view.nearest_obstacles(n_obstacles, neighbor_dist)) if n_obstacles else ()
    return Neighbors(agents, obstacles)


def _padded(rows: Sequence[np.ndarray], count: int, filler: np.ndarray, name: str) -> np.ndarray:
    if len(rows) > count:
        raise ValueError(f"{name} has {len(rows)} entries: the vector holds {count}; select at most {count}")
    out = np.tile(filler, (count, 1))
    if len(rows):
        out[:len(rows)] = np.asarray(rows, dtype=float).reshape(len(rows), 3)
    return out.reshape(-1)


def assemble_inputs(role: str, own_vel, goal_pose_rel, others_pos_rel, others_vel, obstacles_pos_rel,
                    n_neighbors: int, n_obstacles: int, neighbor_dist: float = DEFAULT_NEIGHBOR_DIST,
                    goal_vel=None, distance: float | None = None) -> np.ndarray:
    """The input vector from the quantities of the module table (rows nearest first; padding added here).

    For callers without a WorldView (mlr reading recorded rows); `build_inputs` computes the
    quantities from a WorldView and a Goal and calls this.
    """
    _check_role(role)
    n_neighbors = _check_count(n_neighbors, "n_neighbors")
    n_obstacles = _check_count(n_obstacles, "n_obstacles")
    pad = pad_position(neighbor_dist)
    if len(others_pos_rel) != len(others_vel):
        raise ValueError(f"others_pos_rel has {len(others_pos_rel)} rows but others_vel {len(others_vel)}: "
                         "give one velocity per neighbour")
    blocks = {
        "own_vel": np.asarray(own_vel, dtype=float).reshape(3),
        "goal_pose_rel": np.asarray(goal_pose_rel, dtype=float).reshape(3),
        "others_pos_rel": _padded(others_pos_rel, n_neighbors, pad, "others_pos_rel"),
        "others_vel": _padded(others_vel, n_neighbors, np.zeros(3), "others_vel"),
        "obstacles_pos_rel": _padded(obstacles_pos_rel, n_obstacles, pad, "obstacles_pos_rel"),
    }
    if "goal_vel" in ROLE_BLOCKS[role]:
        blocks["goal_vel"] = np.zeros(3) if goal_vel is None else np.asarray(goal_vel, dtype=float).reshape(3)
    if "distance" in ROLE_BLOCKS[role]:
        if distance is None:
            raise ValueError("distance is missing: role 'agent_ad' inputs hold the distance to keep (Goal.distance)")
        blocks["distance"] = np.array([float(distance)])
    return np.concatenate([blocks[block] for block in ROLE_BLOCKS[role]])


def build_inputs(view: WorldView, goal: Goal, role: str, n_neighbors: int, n_obstacles: int,
                 neighbor_dist: float = DEFAULT_NEIGHBOR_DIST, neighbors: Neighbors | None = None) -> np.ndarray:
    """The input vector (float64, `input_size` long) of the UAV `view.own` for `goal`.

    `neighbors` defaults to `select_neighbors(view, n_neighbors, n_obstacles, neighbor_dist)`.
    """
    _check_role(role)
    own = view.own
    if neighbors is None:
        neighbors = select_neighbors(view, n_neighbors, n_obstacles, neighbor_dist)
    return assemble_inputs(
        role, own.velocity, goal.position - own.position,
        [a.position - own.position for a in neighbors.agents], [a.velocity for a in neighbors.agents],
        [o.position - own.position for o in neighbors.obstacles], n_neighbors, n_obstacles, neighbor_dist,
        goal_vel=goal.target_velocity, distance=goal.distance)
