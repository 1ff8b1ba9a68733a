"""A checked World plus a seed -> every frame, free-space pose and obstacle, in the geometry frame and in `map`.

Frames (the original ros_magna names): volume `{name}` under `map`; geometry
`{volPrefix}_{geomName}` under its volume; pose `{volPrefix}_{geomPrefix}_pos_{i}_{j}_{k}`
(matrix) or `..._pos_{n}` (the other sets, numbered on through the geometry) and
obstacle `..._obs_{n}` under their geometry. A geometry's second and later matrix
sets of poses add `_set{s}` before `_pos`.

Randomness: each pose set draws from its own stream seeded by (seed, volume name,
geometry name, set index), so a world repeats exactly for a seed, and editing one
geometry does not move the random poses of another.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from magna_common.json_fields import join_path
from magna_worlds.errors import WorldError, WorldWarning
from magna_worlds.model import Geometry, ObstacleSpec, PoseSetSpec, Volume, World
from magna_worlds.posesets import (
    LayoutError,
    coordinates_layout,
    matrix_layout,
    orientations,
    random_layout,
    zigzag_layout,
)
from magna_worlds.transforms import Frame, rotate_quaternions


@dataclass
class PoseSet:
    """The poses of one set, in the geometry frame (`local_*`) and in `map`."""

    spec: PoseSetSpec
    index: int  # position among the geometry's sets
    frames: list[str]
    local_positions: np.ndarray  # (N, 3)
    local_quaternions: np.ndarray  # (N, 4) [x, y, z, w]
    positions: np.ndarray  # (N, 3) in map
    quaternions: np.ndarray  # (N, 4) in map
    cells: dict[tuple[int, int, int], int] | None = None  # matrix: (i, j, k) -> row
    path_name: str | None = None  # zigzag: "Zigzag", "Zigzag_1", ...

    def __len__(self) -> int:
        return len(self.frames)


@dataclass
class Obstacle:
    name: str  # its tf frame and its simulator model name
    shape: str
    dimensions: tuple[float, ...]  # the world-file convention; prism: (height,)
    polygon: tuple[tuple[float, float], ...]  # prism base vertices, else ()
    local_position: np.ndarray
    local_quaternion: np.ndarray
    position: np.ndarray  # map
    quaternion: np.ndarray  # map


@dataclass
class PlacedGeometry:
    volume: Volume
    geometry: Geometry
    frame_name: str
    base_name: str  # prefix of its pose and obstacle frames
    frame: Frame  # geometry -> map
    pose_sets: list[PoseSet] = field(default_factory=list)
    obstacles: list[Obstacle] = field(default_factory=list)

    def poses(self) -> list[PoseSet]:
        return [s for s in self.pose_sets if s.spec.use == "poses"]


@dataclass
class ResolvedWorld:
    world: World
    seed: int
    volume_frames: dict[str, Frame]  # volume -> map
    geometries: list[PlacedGeometry]
    warnings: list[str] = field(default_factory=list)  # the world's, then the lay-out's

    def geometry(self, volume: str, name: str) -> PlacedGeometry | None:
        return next((g for g in self.geometries if g.volume.name == volume and g.geometry.name == name), None)

    def obstacles(self) -> list[Obstacle]:
        return [o for g in self.geometries for o in g.obstacles]

    def pose_count(self) -> int:
        return sum(len(s) for g in self.geometries for s in g.poses())

    def frame_links(self) -> list[tuple[str, str]]:
        """(parent, child) of every frame of the world, parents first (names only: cheap)."""
        out = [("map", v.name) for v in self.world.volumes]
        for g in self.geometries:
            out.append((g.volume.name, g.frame_name))
            out += [(g.frame_name, name) for s in g.poses() for name in s.frames]
            out += [(g.frame_name, o.name) for o in g.obstacles]
        return out

    def static_transforms(self) -> list[tuple[str, str, Frame]]:
        """(parent, child, child-in-parent) for every frame of the world, parents first."""
        out = [("map", v.name, self.volume_frames[v.name]) for v in self.world.volumes]
        for g in self.geometries:
            out.append((g.volume.name, g.frame_name, g.geometry.origin))
            for s in g.poses():
                rotations = Rotation.from_quat(s.local_quaternions).as_matrix() if len(s) else []
                out += [(g.frame_name, name, Frame(p, r))
                        for name, p, r in zip(s.frames, s.local_positions, rotations, strict=True)]
            out += [(g.frame_name, o.name, Frame.from_xyz_quaternion(o.local_position, o.local_quaternion))
                    for o in g.obstacles]
        return out


def set_rng(seed: int, volume: str, geometry: str, index: int) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(volume.encode()), zlib.crc32(geometry.encode()), index])


def resolve_world(world: World, seed: int = 0, strict: bool = False) -> ResolvedWorld:
    """Lay out every pose set and obstacle; raises WorldError for a set that cannot be laid out. Poses or
    obstacles outside the world boundaries are kept with a warning (the original never checked them); `strict`
    refuses them instead."""
    volume_frames = {v.name: v.origin for v in world.volumes}
    placed = [_place_geometry(v, g, seed) for v in world.volumes for g in v.geometries]
    resolved = ResolvedWorld(world, seed, volume_frames, placed, list(world.warnings))
    _check_unique_frames(resolved)
    _check_inside_boundaries(resolved, strict)
    return resolved


def _check_inside_boundaries(resolved: ResolvedWorld, strict: bool) -> None:
    """One warning per pose set with poses outside the boundaries: a UAV there is out of the world."""
    low, high = resolved.world.boundaries[:, 0], resolved.world.boundaries[:, 1]
    for g in resolved.geometries:
        for s in g.poses():
            positions = s.positions
            outside = np.flatnonzero(np.any((positions < low - 1e-9) | (positions > high + 1e-9), axis=1))
            if not len(outside):
                continue
            point = ", ".join(f"{v:g}" for v in positions[outside[0]].round(3))
            box = ", ".join(f"[{a:g}, {b:g}]" for a, b in resolved.world.boundaries.tolist())
            message = (f"puts {len(outside)} of its {len(positions)} poses outside scenario.world_boundaries "
                       f"[{box}], e.g. ({point}) in map; they are kept (the original did not check), and a UAV "
                       "there is out of the world and aborted. Move the geometry or widen the boundaries")
            if strict:
                raise WorldError(g.volume.source, s.spec.source_path, f"{message} (refused with --strict)")
            resolved.warnings.append(WorldWarning(g.volume.source, s.spec.source_path, message))


def _place_geometry(volume: Volume, geometry: Geometry, seed: int) -> PlacedGeometry:
    frame = volume.origin.compose(geometry.origin)
    placed = PlacedGeometry(volume, geometry, f"{volume.prefix}_{geometry.name}",
                            f"{volume.prefix}_{geometry.frame_prefix or geometry.prefix}", frame)
    listed, obstacles, matrices, zigzags = 0, 0, 0, 0
    for index, spec in enumerate(geometry.pose_sets):
        rng = set_rng(seed, volume.name, geometry.name, index)
        try:
            positions, quaternions, cells = _layout(geometry, spec, rng)
        except LayoutError as err:
            field_name, _, message = str(err).partition(": ")
            raise WorldError(volume.source, join_path(spec.source_path, field_name), message) from None
        if spec.use == "obstacles":
            assert spec.obstacle is not None, "the loader gives every set of obstacles its ObstacleSpec"
            placed.obstacles += _obstacles(placed, spec.obstacle, positions, quaternions, obstacles, rng)
            obstacles += len(positions)
            continue
        if cells is not None:
            tag = "" if matrices == 0 else f"_set{index}"
            names = [f"{placed.base_name}{tag}_pos_{i}_{j}_{k}" for i, j, k in cells]
            cell_rows = {(int(i), int(j), int(k)): row for row, (i, j, k) in enumerate(cells)}
            matrices += 1
        else:
            names = [f"{placed.base_name}_pos_{listed + n}" for n in range(len(positions))]
            listed += len(positions)
            cell_rows = None
        path_name = None
        if spec.type == "zigzag":
            path_name = "Zigzag" if zigzags == 0 else f"Zigzag_{zigzags}"
            zigzags += 1
        placed.pose_sets.append(PoseSet(spec, index, names, positions, quaternions, frame.apply(positions),
                                        rotate_quaternions(frame.rotation, quaternions), cell_rows, path_name))
    return placed


def _layout(geometry: Geometry, spec: PoseSetSpec,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Positions (N, 3) and quaternions (N, 4) of a set, in the geometry frame, and a matrix's cells (N, 3)."""
    cells = None
    if spec.type == "matrix":
        positions, cells = matrix_layout(geometry.spec, spec)
        if spec.density < 1.0:
            keep = rng.random(len(positions)) < spec.density
            positions, cells = positions[keep], cells[keep]
    elif spec.type == "random":
        positions = random_layout(geometry.spec, spec.quantity, rng)
    elif spec.type == "coordinates":
        positions, quaternions = coordinates_layout(geometry.spec, spec)
        return positions, quaternions, None
    else:
        positions = zigzag_layout(geometry.spec, spec)
    return positions, orientations(spec.orientation, len(positions), rng), cells


def _obstacles(placed: PlacedGeometry, spec: ObstacleSpec, positions: np.ndarray, quaternions: np.ndarray, first: int,
               rng: np.random.Generator) -> list[Obstacle]:
    frame = placed.frame
    map_positions = frame.apply(positions)
    map_quaternions = rotate_quaternions(frame.rotation, quaternions)
    out = []
    for n in range(len(positions)):
        shape = spec.shapes[int(rng.integers(len(spec.shapes)))] if len(spec.shapes) > 1 else spec.shapes[0]
        out.append(Obstacle(f"{placed.base_name}_obs_{first + n}", shape, _draw_dimensions(shape, spec, rng),
                            spec.prism_polygon, positions[n], quaternions[n], map_positions[n], map_quaternions[n]))
    return out


def _draw_dimensions(shape: str, spec: ObstacleSpec, rng: np.random.Generator) -> tuple[float, ...]:
    """One obstacle's dimensions in the world convention, each drawn in its [low, high] (equal ends: fixed)."""
    draws = [low if low == high else float(rng.uniform(low, high)) for low, high in spec.dimension_ranges]
    if shape == "cube":
        return tuple(draws)
    if shape == "sphere":
        return (draws[0],) * 3
    if shape == "cylinder":
        return (draws[0], draws[0], draws[2])
    if shape == "torus":
        tube = min(draws[2], draws[0])  # a tube wider than the ring would overlap itself
        return (draws[0], draws[0] + tube, tube)
    return (draws[0],)


def _check_unique_frames(resolved: ResolvedWorld) -> None:
    seen: dict[str, str] = {}
    for parent, child in resolved.frame_links():
        if child in seen or child == "map":
            # the geometry publishing the second copy: a pose or obstacle under it, else its own frame (volume prefix
            # and geometry name) under its volume
            where = next((g for g in resolved.geometries if g.frame_name == parent), None)
            field_name = "prefix"
            if where is None:
                where = next((g for g in resolved.geometries if g.volume.name == parent and g.frame_name == child),
                             None)
                field_name = "name"
            source = where.volume.source if where else resolved.world.source
            path = join_path(where.geometry.source_path, field_name) if where else ""
            raise WorldError(source, path, f"frame {child!r} would be published twice (under {seen.get(child, 'map')} "
                             f"and {parent}); give the volumes distinct prefixes or the geometries distinct "
                             f"{field_name}s")
        seen[child] = parent


def world_record(resolved: ResolvedWorld) -> dict[str, Any]:
    """The resolved world as JSON-ready data: what the simulation flew in (every pose and obstacle, in map)."""
    w = resolved.world
    geometries = []
    for g in resolved.geometries:
        geometries.append({
            "volume": g.volume.name, "geometry": g.geometry.name, "frame": g.frame_name, "shape": g.geometry.spec.shape,
            "dimensions": list(g.geometry.spec.dimensions), "polygon": [list(v) for v in g.geometry.spec.polygon],
            "position": g.frame.translation.tolist(), "orientation": g.frame.quaternion().tolist(),
            "pose_sets": [{
                "type": s.spec.type, "path": s.path_name, "frames": s.frames,
                "cells": None if s.cells is None else [list(c) for c in s.cells],
                "positions": s.positions.round(6).tolist(), "orientations": s.quaternions.round(9).tolist(),
            } for s in g.pose_sets],
        })
    return {
        "source": w.source, "included": list(w.included), "seed": resolved.seed,
        "world_boundaries": w.boundaries.tolist() if np.isfinite(w.boundaries).all() else None,
        "origin_geo": list(w.origin_geo) if w.origin_geo else None,
        "geometries": geometries,
        "obstacles": [{"name": o.name, "shape": o.shape, "dimensions": list(o.dimensions),
                       "polygon": [list(v) for v in o.polygon], "position": o.position.round(6).tolist(),
                       "orientation": o.quaternion.round(9).tolist()} for o in resolved.obstacles()],
    }
