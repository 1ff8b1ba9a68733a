"""The world a simulation flew in, as solids to draw: from its `world.json` record, or the bag's obstacle markers.

`world.json` is the world node's record (magna_worlds.registry.WorldRegistry.record, kept by the
node for every part the run had, deleted ones too), read as magna_common.records.WorldRecord.
A record holds every geometry's shape and pose and every obstacle, but not the geometries' colours.
So each part is re-resolved from its source file with its seed (magna_worlds.loader + resolve_world),
looked up again by `<world>/<subworld>` in the worlds search path when the recorded path no longer
exists (another clone, another machine), and used when its obstacles match the record; otherwise
(inline parts, edited or lost files) the record's own shapes are drawn, geometries in a neutral grey.
Without world.json, the obstacles are the bounding spheres of the bag's obstacle markers
(`magna_uav.ros_data.ObstacleMarkers`, as the UAV managers saw them).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np

from magna_common.records import RecordedGeometry, RecordedObstacle, RecordedWorldPart, WorldRecord
from magna_common.search_path import find_world_file, world_folders
from magna_worlds.draw import OBSTACLE_COLOR, obstacle_spec
from magna_worlds.errors import WorldError
from magna_worlds.generate import ResolvedWorld, resolve_world
from magna_worlds.loader import load_world
from magna_worlds.shapes import ShapeSpec
from magna_worlds.transforms import Frame
from magna_worlds.vocabulary import Shape

RECORD_COLOR = (0.55, 0.57, 0.62)  # geometries known only from the record, which keeps no colours
RECORD_ALPHA = 0.3
MATCH_TOLERANCE = 1e-3  # m: the record rounds positions to 1e-6


@dataclass(frozen=True)
class WorldShape:
    """One solid: a geometry of the world (translucent, its own colour) or an obstacle (opaque)."""

    name: str
    kind: str  # "geometry" | "obstacle"
    spec: ShapeSpec  # in its own frame, as magna_worlds.draw.shape_mesh takes it
    frame: Frame  # own frame -> map
    color: tuple[float, float, float]  # 0..1
    alpha: float  # 0..1, as the world file gives it (obstacles: 1)


@dataclass
class RecordedWorld:
    shapes: list[WorldShape] = field(default_factory=list)
    boundaries: np.ndarray | None = None  # (3, 2) union of the parts' boundaries, None when none has any
    source: str = "none"  # where the shapes came from, for captions and notes
    notes: list[str] = field(default_factory=list)

    @property
    def geometries(self) -> list[WorldShape]:
        return [s for s in self.shapes if s.kind == "geometry"]

    @property
    def obstacles(self) -> list[WorldShape]:
        return [s for s in self.shapes if s.kind == "obstacle"]


def world_from_record(record_file: Path, search_path: list[Path] | None = None) -> RecordedWorld:
    """The shapes of every part of a world.json record (module docstring); RecordError (a ValueError naming
    the file) if it is not one."""
    record = WorldRecord.read(record_file)
    search = world_folders() if search_path is None else list(search_path)
    world = RecordedWorld()
    sources = []
    boxes = []
    for part_id, part in record.parts.items():
        resolved, why = _re_resolve(part, search)
        if resolved is not None:
            world.shapes += _resolved_shapes(resolved)
            sources.append(f"{part_id}: {resolved.world.source} (seed {resolved.seed})")
        else:
            world.shapes += _record_shapes(part)
            sources.append(f"{part_id}: world.json record")
            world.notes.append(f"world part {part_id!r} drawn from the record, geometries without their colours: "
                               f"{why}")
        if part.world_boundaries:
            boxes.append(np.asarray(part.world_boundaries, dtype=float).reshape(3, 2))
    if boxes:
        stacked = np.stack(boxes)
        world.boundaries = np.column_stack([stacked[:, :, 0].min(axis=0), stacked[:, :, 1].max(axis=0)])
    world.source = "; ".join(sources) or "world.json (no parts)"
    return world


def world_from_markers(markers: list) -> RecordedWorld:
    """Obstacles as bounding spheres: every obstacle any of the MarkerArrays (in order) ever showed."""
    from magna_uav.ros_data import ObstacleMarkers  # needs only the message classes

    table = ObstacleMarkers()
    seen: dict[str, WorldShape] = {}
    for message in markers:
        table.apply(message)
        for obstacle in table.obstacles():
            d = 2.0 * float(obstacle.radius)
            seen[obstacle.name] = WorldShape(obstacle.name, "obstacle", ShapeSpec("sphere", (d, d, d)),
                                             Frame(np.asarray(obstacle.position, dtype=float), np.eye(3)),
                                             OBSTACLE_COLOR, 1.0)
    return RecordedWorld(list(seen.values()), None, "obstacle markers of the bag (bounding spheres)")


def _re_resolve(part: RecordedWorldPart, search_path: list[Path]) -> tuple[ResolvedWorld | None, str]:
    source = Path(part.source)
    candidates = [source] if source.suffix == ".json" else []
    if source.suffix == ".json" and source.parent.name:
        found = find_world_file(source.parent.name, source.stem, search_path)
        if found is not None:
            candidates.append(found)
    candidates = [c for c in dict.fromkeys(candidates) if c.is_file()]
    if not candidates:
        return None, f"its source {str(source)!r} is not a world file found here"
    why = ""
    for candidate in candidates:
        try:
            resolved = resolve_world(load_world(candidate, search_path), part.seed)
        except WorldError as err:
            why = f"re-resolving {candidate} failed: {err}"
            continue
        if _same_obstacles(resolved, part.obstacles):
            return resolved, ""
        why = f"{candidate} resolves to other obstacles than the record (edited since?)"
    return None, why


def _same_obstacles(resolved: ResolvedWorld, recorded: tuple[RecordedObstacle, ...]) -> bool:
    mine = resolved.obstacles()
    if [o.name for o in mine] != [o.name for o in recorded]:
        return False
    return all(np.allclose(o.position, r.position, atol=MATCH_TOLERANCE) for o, r in zip(mine, recorded, strict=True))


def _resolved_shapes(resolved: ResolvedWorld) -> list[WorldShape]:
    shapes = [WorldShape(f"{g.volume.name}/{g.geometry.name}", "geometry", g.geometry.spec, g.frame,
                         _rgb(g.geometry.color), float(g.geometry.alpha))
              for g in resolved.geometries]
    shapes += [WorldShape(o.name, "obstacle", obstacle_spec(o), Frame.from_xyz_quaternion(o.position, o.quaternion),
                          OBSTACLE_COLOR, 1.0) for o in resolved.obstacles()]
    return shapes


def _rgb(color: Sequence[float]) -> tuple[float, float, float]:
    r, g, b = color
    return float(r), float(g), float(b)


def _record_spec(item: RecordedGeometry | RecordedObstacle) -> ShapeSpec:
    polygon = tuple((v[0], v[1]) for v in item.polygon)
    # world.json holds the shapes of checked ShapeSpecs (magna_worlds.generate); the record reads plain text
    return ShapeSpec(cast(Shape, item.shape), tuple(item.dimensions), polygon)


def _record_shapes(part: RecordedWorldPart) -> list[WorldShape]:
    shapes = []
    for g in part.geometries:
        frame = Frame.from_xyz_quaternion(g.position, g.orientation)
        shapes.append(WorldShape(f"{g.volume or '?'}/{g.geometry or '?'}", "geometry", _record_spec(g), frame,
                                 RECORD_COLOR, RECORD_ALPHA))
    for o in part.obstacles:
        frame = Frame.from_xyz_quaternion(o.position, o.orientation)
        shapes.append(WorldShape(o.name or "obstacle", "obstacle", _record_spec(o), frame, OBSTACLE_COLOR, 1.0))
    return shapes


__all__ = ["RecordedWorld", "WorldShape", "world_from_markers", "world_from_record"]
