"""Check a mission against a world: every place it names exists there, nothing is spawned or flown.

`check_against_world(mission, resolved_world)` resolves every pose definition of the
mission (spawn_agents initial poses, follow_path and set_mission paths) with
`magna_worlds.query.PoseQueries`, as the world node will at run time, and reports:

- a definition naming a volume, geometry, matrix cell, zigzag path or set of poses the
  world does not have (the query's own message, placed at the definition's JSON path);
- a pose outside the world boundaries: a warning (the original loaded such missions, and a UAV
  that flew there ended its role), a problem in strict mode;
- two agents spawned closer than the sum of their safety radii.

World parts a mission adds inline (world_config add with a list of volumes) are loaded
and laid out too, and count as part of the world (`world_part_def: from_hyperparameters`
is the world given here).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magna_gs.mission.model import (
    FollowPathParams,
    Mission,
    PoseDefinition,
    SetMissionParams,
    SpawnAgentsParams,
    WorldConfigParams,
)


def pose_definitions(mission: Mission) -> list[PoseDefinition]:
    """Every pose definition the mission writes, in file order."""
    out: list[PoseDefinition] = []
    for node in mission.nodes():
        params = node.parameters
        if isinstance(params, FollowPathParams | SetMissionParams):
            out += params.path
        elif isinstance(params, SpawnAgentsParams):
            out += params.initial_poses
    return out


def inline_world_parts(mission: Mission, seed: int = 0, search_path: Iterable[Path] | None = None):
    """(resolved parts, problems) for the world parts the mission writes inline."""
    from magna_common.search_path import world_folders
    from magna_worlds.errors import WorldError
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import world_from_data

    folders = world_folders() if search_path is None else list(search_path)
    parts, problems = [], []
    for node in mission.nodes():
        params = node.parameters
        if isinstance(params, WorldConfigParams) and params.world_part_def and params.world_part_def.volumes:
            where = mission.where(params.world_part_def.json_path)
            try:
                world = world_from_data(list(params.world_part_def.volumes), where, search_path=folders)
                parts.append(resolve_world(world, seed))
            except WorldError as error:
                problems.append(" ".join(str(error).split()))
    return parts, problems


@dataclass
class WorldFindings:
    problems: list[str]  # `file: JSON.path: message`: the mission cannot fly in this world
    warnings: list[str]  # what the original tolerated (a place outside the world boundaries)


def check_against_world(mission: Mission, resolved_world, seed: int = 0,
                        search_path: Iterable[Path] | None = None) -> list[str]:
    """Problems (`file: JSON.path: message`) of the mission in `resolved_world` (a ResolvedWorld or a list),
    a place outside the world boundaries among them (as `check_in_world` in strict mode)."""
    return check_in_world(mission, resolved_world, seed, search_path, strict=True).problems


def check_in_world(mission: Mission, resolved_world, seed: int = 0, search_path: Iterable[Path] | None = None,
                   strict: bool = False) -> WorldFindings:
    """Problems and warnings of the mission in `resolved_world`. A place outside the world boundaries is a
    warning (the original loaded such missions; a UAV that got there ended its role), a problem when `strict`."""
    from magna_worlds.query import PoseQueries, QueryError

    worlds = list(resolved_world) if isinstance(resolved_world, Sequence) else [resolved_world]
    parts, problems = inline_world_parts(mission, seed, search_path)
    warnings: list[str] = []
    worlds += parts
    queries = PoseQueries(seed)
    positions: dict[str, np.ndarray] = {}  # definition's JSON path -> map positions
    for definition in pose_definitions(mission):
        try:
            result = queries.resolve(worlds, definition.as_list())
        except QueryError as error:
            problems.append(_placed(mission, definition, str(error)))
            continue
        positions[definition.json_path] = result.positions
        owner = next(w for w in worlds if definition.volume in w.volume_frames)
        outside = _outside(owner.world.boundaries, result.positions)
        if outside is not None:
            where = (f"{mission.where(definition.json_path)}: {definition} gives a pose at "
                     f"({', '.join(f'{v:.2f}' for v in outside)}), outside the world boundaries "
                     f"{_bounds(owner.world.boundaries)}")
            if strict:
                problems.append(f"{where}; UAVs may not fly there (refused with --strict)")
            else:
                warnings.append(f"{where}; loaded as the original did: a UAV that flies there ends its role "
                                f"'aborted' (out of the world boundaries) and the mission takes that branch")
    problems += _spawn_spacing(mission, positions)
    return WorldFindings(problems, warnings)


def _placed(mission: Mission, definition: PoseDefinition, message: str) -> str:
    """A query message `definition[1]: ...` placed at the definition's own JSON path."""
    if message.startswith("definition"):
        return f"{mission.where(definition.json_path)}{message[len('definition'):]}"
    return f"{mission.where(definition.json_path)}: {message}"


def _outside(boundaries: np.ndarray, positions: np.ndarray):
    if not np.isfinite(boundaries).all() or not len(positions):
        return None
    low, high = boundaries[:, 0], boundaries[:, 1]
    bad = np.any((positions < low - 1e-9) | (positions > high + 1e-9), axis=1)
    return positions[np.argmax(bad)] if bad.any() else None


def _bounds(boundaries: np.ndarray) -> str:
    return " ".join(f"{axis} {lo:g}..{hi:g}" for axis, (lo, hi) in zip("xyz", boundaries, strict=True)) + " m"


def _spawn_spacing(mission: Mission, positions: dict[str, np.ndarray]) -> list[str]:
    """Agents spawned closer than the sum of their safety radii (first pose of each definition)."""
    problems = []
    by_id = {agent.id: agent for agent in mission.agents}
    for node in mission.nodes():
        params = node.parameters
        if not isinstance(params, SpawnAgentsParams):
            continue
        if node.ids is None or node.ids == "all":
            ids = mission.agent_ids
        else:
            ids = [node.ids] if isinstance(node.ids, int) else list(node.ids)
        placed = [(by_id[i], d, positions[d.json_path][0]) for i, d in zip(ids, params.initial_poses, strict=False)
                  if i in by_id and d.json_path in positions]
        for index, (first, _, p) in enumerate(placed):
            for second, definition, q in placed[index + 1:]:
                gap = float(np.linalg.norm(p - q))
                needed = first.safety_radius + second.safety_radius
                if gap < needed:
                    problems.append(f"{mission.where(definition.json_path)}: agents {first.id} and {second.id} would "
                                    f"spawn {gap:.2f} m apart, closer than their safety radii "
                                    f"({first.safety_radius:g} + {second.safety_radius:g} m); give them other places")
    return problems
