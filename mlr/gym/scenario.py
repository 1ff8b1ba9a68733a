"""A gym scenario: what a MAGNA world and mission give a learning environment, without ROS.

From the mission (magna_gs.mission.loader, both schemas, as `magna run` reads it):
- the UAVs: ids and airframes (max speed, safety radius);
- where each one spawns (the spawn_agents state's initial poses) and the height it takes off to;
- the pose definitions its follow_path states draw waypoints from, e.g.
  ["CentralZone", "Accessible", "random", 20];
- the ORCA-3D parameters the mission sets (what the teacher flies with).

From the world (magna_worlds): the obstacles, both as solids for the physics and as the bounding
spheres the NAI gives ORCA-3D and the networks (magna_uav.ros_data.obstacles_from_markers, what the
UAV managers hear).

Goals are drawn with magna_worlds.query.PoseQueries, seeded, as the world node draws them.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magna_common.airframes import Airframe
from magna_common.search_path import find_world_file, world_candidates, world_folders
from magna_gs.mission.loader import find_mission, load_mission
from magna_gs.mission.model import (
    AlgorithmControlParams,
    FollowPathParams,
    PoseDefinition,
    SpawnAgentsParams,
    TakeOffParams,
)
from magna_uav.world_view import Obstacle as NaiObstacle
from magna_worlds.generate import Obstacle as WorldObstacle
from magna_worlds.generate import ResolvedWorld, resolve_world
from magna_worlds.loader import load_world
from magna_worlds.query import PoseQueries

ORCA_NAMES = ("orca3", "orca3d")


class ScenarioError(ValueError):
    """A world or mission the gym cannot make an environment of; the message names the file and what is missing."""


@dataclass(frozen=True)
class GymUav:
    """One UAV of the scenario."""

    id: int
    airframe: Airframe
    start: np.ndarray  # (3,) map, where it spawns
    goal_definitions: tuple[PoseDefinition, ...]  # what its follow_path states draw goals from, in file order

    @property
    def max_speed(self) -> float:
        return float(self.airframe.max_speed)

    @property
    def safety_radius(self) -> float:
        return float(self.airframe.safety_radius)


@dataclass(frozen=True)
class Scenario:
    world_name: str  # WORLD/SUBWORLD
    mission_name: str  # MISSION/SUBMISSION
    world: ResolvedWorld
    uavs: tuple[GymUav, ...]
    take_off_height: float  # m above the start
    orca_params: tuple[tuple[str, ...], tuple[float, ...]]  # the mission's ORCA-3D set: names, values
    solids: tuple[WorldObstacle, ...]  # the obstacles' real shapes, for the physics
    obstacles: tuple[NaiObstacle, ...]  # the same as the NAI sees them (bounding spheres and parts)

    @property
    def boundaries(self) -> np.ndarray | None:
        """[[xmin, xmax], [ymin, ymax], [zmin, zmax]] of the world, or None when it has none."""
        bounds = self.world.world.boundaries
        return None if bounds is None else np.asarray(bounds, dtype=float).reshape(3, 2)

    def goals(self, uav: GymUav, seed: int, count: int) -> np.ndarray:
        """`count` goals (map, (count, 3)) for `uav`, drawn from its definitions in turn, reproducible by `seed`."""
        queries = PoseQueries(seed)
        out: list[np.ndarray] = []
        while len(out) < count:
            for definition in uav.goal_definitions:
                items = list(definition.as_list())
                if items[2] == "random":  # one at a time, so that every definition takes its turn
                    items[3] = 1
                out.extend(queries.resolve([self.world], items).positions)
        return np.asarray(out[:count], dtype=float).reshape(count, 3)


def load_scenario(world: str, mission: str, search_path: Sequence[Path] = (), seed: int = 0) -> Scenario:
    """The scenario of WORLD/SUBWORLD and MISSION/SUBMISSION (names as `magna run` takes them); the world is laid
    out for `seed`. ScenarioError, or the loaders' own errors (which name file and JSON path), when it cannot be."""
    world_file = _world_file(world, search_path)
    resolved = resolve_world(load_world(world_file, list(search_path)), seed)
    mission_file = find_mission(mission, _mission_folders(search_path))
    loaded = load_mission(mission_file)
    if loaded.plan is None:  # validate=True gives a plan; refuse rather than guess if that ever changes
        raise ScenarioError(f"{mission_file}: the mission could not be planned")
    leaves = list(loaded.plan.root.leaves())

    def parameters_of(kind):
        return [(state, state.parameters) for state in leaves if isinstance(state.parameters, kind)]

    spawns = parameters_of(SpawnAgentsParams)
    if not spawns:
        raise ScenarioError(f"{mission_file}: no spawn_agents state, so the UAVs have no start poses; the gym "
                            "starts each UAV where the mission spawns it")
    initial = spawns[0][1].initial_poses
    agents = loaded.mission.agents
    if len(initial) < len(agents):
        raise ScenarioError(f"{mission_file}: {spawns[0][0].json_path}: {len(initial)} initial poses for "
                            f"{len(agents)} UAVs")
    queries = PoseQueries(seed)
    uavs = []
    for agent, pose in zip(agents, initial, strict=False):
        start = queries.resolve([resolved], list(pose.as_list())[:4]).positions[0]
        goals = tuple(definition for state, params in parameters_of(FollowPathParams)
                      if state.uav == agent.id for definition in params.path)
        if not goals:
            raise ScenarioError(f"{mission_file}: UAV {agent.id} flies no follow_path state with a path; the gym "
                                "draws each UAV's goals from its paths")
        uavs.append(GymUav(agent.id, agent.airframe, np.asarray(start, dtype=float), goals))
    take_offs = [params.height for _, params in parameters_of(TakeOffParams)]
    orca = [params for _, params in parameters_of(AlgorithmControlParams) if params.name in ORCA_NAMES]
    orca_params = (tuple(orca[0].params), tuple(float(v) for v in orca[0].values)) if orca else ((), ())
    solids = tuple(resolved.obstacles())
    return Scenario(world, mission, resolved, tuple(uavs), float(take_offs[0]) if take_offs else 1.0, orca_params,
                    solids, tuple(_nai_obstacles(resolved)))


def _world_file(world: str, search_path: Sequence[Path]) -> Path:
    name, _, subworld = world.partition("/")
    folders = world_folders(search_path)
    found = find_world_file(name, subworld, folders) if subworld else None
    if found is None:
        raise ScenarioError(f"world {world!r}: no such WORLD/SUBWORLD; {world_candidates(name, subworld, folders)}")
    return found


def _mission_folders(search_path: Sequence[Path]) -> list[Path]:
    from magna_common.search_path import mission_folders

    return mission_folders(search_path)


def _nai_obstacles(resolved: ResolvedWorld) -> list[NaiObstacle]:
    """The obstacles as the UAV managers hear them: the world node's markers, read back."""
    from magna_uav.ros_data import obstacles_from_markers
    from magna_worlds.markers import world_markers

    return obstacles_from_markers(world_markers([resolved]))
