"""Missions name free-space poses as `[volume, geometry, kind, arg]`; this turns one such definition into map poses.

kinds:
  matrix [i, j, k]         the pose of that cell of the geometry's first matrix set of poses
  random N                 N new poses drawn uniformly inside the geometry (each call draws new ones)
  coordinates P or [P...]  P = [[x, y, z], [roll, pitch, yaw] or [qx, qy, qz, qw]] in the geometry's frame;
                           with geometry "volume", in the volume's frame
  path NAME|INDEX          the poses of a zigzag sweep in flying order ("Zigzag" is the first; default)
  poses INDEX              every pose of the geometry's INDEX-th set of poses
A fifth element (a spawn yaw) is allowed and ignored here. An
argument given as a string holding JSON (a ROS string[] request) is decoded first.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Any

import numpy as np

from magna_worlds.generate import PlacedGeometry, ResolvedWorld, set_rng
from magna_worlds.shapes import sample_uniform
from magna_worlds.transforms import Frame, quaternions_from_rpy, rotate_quaternions
from magna_worlds.vocabulary import POSE_KINDS

MAX_RANDOM = 100000


class QueryError(ValueError):
    """A definition that names nothing in the world; the message says which element and what exists."""


@dataclass
class QueryResult:
    positions: np.ndarray  # (N, 3) map
    quaternions: np.ndarray  # (N, 4) map
    frames: list[str]
    new_frames: list[tuple[str, str, Frame]] = field(default_factory=list)  # (parent, child, pose) to publish


class PoseQueries:
    """Resolves definitions against the worlds it is given; keeps the draw counter so random queries repeat per seed."""

    def __init__(self, seed: int = 0):
        self.seed = seed
        self._draws = 0

    def resolve(self, worlds: list[ResolvedWorld], definition: Any) -> QueryResult:
        items = list(definition) if isinstance(definition, (list, tuple)) else None
        if items is None or len(items) not in (4, 5):
            raise QueryError(f"definition: expected [volume, geometry, kind, arg], got {definition!r}")
        volume_name, geometry_name, kind, arg = items[0], items[1], items[2], _decode(items[3])
        found = next(((w, v) for w in worlds for v in w.world.volumes if v.name == volume_name), None)
        if found is None:
            known = sorted(v for w in worlds for v in w.volume_frames)
            raise QueryError(f"definition[0]: no volume named {volume_name!r}; volumes: {', '.join(known) or 'none'}")
        resolved, volume = found
        if kind not in POSE_KINDS:
            raise QueryError(f"definition[2]: unknown kind {kind!r}; use one of {', '.join(POSE_KINDS)}")
        if geometry_name == "volume":
            if kind != "coordinates":
                raise QueryError(f"definition[2]: a volume itself only takes coordinates, got {kind!r}")
            return self._coordinates(resolved.volume_frames[volume_name], volume.name, f"{volume.prefix}_pos", arg)
        placed = resolved.geometry(volume_name, geometry_name)
        if placed is None:
            names = [g.geometry.name for g in resolved.geometries if g.volume.name == volume_name]
            raise QueryError(f"definition[1]: volume {volume_name!r} has no geometry {geometry_name!r}; it has "
                             f"{', '.join(names) or 'none'} (or use \"volume\")")
        if kind == "matrix":
            return self._matrix(placed, arg)
        if kind == "random":
            return self._random(placed, arg)
        if kind == "coordinates":
            return self._coordinates(placed.frame, placed.frame_name, f"{placed.base_name}_query", arg)
        if kind == "path":
            return self._path(placed, arg)
        return self._poses(placed, arg)

    def _matrix(self, placed: PlacedGeometry, arg: Any) -> QueryResult:
        matrices = [(s, s.cells) for s in placed.poses() if s.cells is not None]
        if not matrices:
            raise QueryError(f"definition[2]: {placed.frame_name} has no matrix set of poses")
        if not (isinstance(arg, list) and len(arg) == 3 and all(isinstance(v, Integral) for v in arg)):
            raise QueryError(f"definition[3]: a matrix cell is [i, j, k] (whole numbers), got {arg!r}")
        pose_set, cells = matrices[0]
        row = cells.get((arg[0], arg[1], arg[2]))
        if row is None:
            top = np.max(np.array(list(cells)), axis=0).tolist()
            raise QueryError(f"definition[3]: {placed.frame_name} has no cell {arg}; its cells run up to {top} "
                             "(from 0; density may leave some out)")
        return QueryResult(pose_set.positions[[row]], pose_set.quaternions[[row]], [pose_set.frames[row]])

    def _random(self, placed: PlacedGeometry, arg: Any) -> QueryResult:
        if isinstance(arg, bool) or not isinstance(arg, int) or not 1 <= arg <= MAX_RANDOM:
            raise QueryError(f"definition[3]: random takes how many poses to draw, 1..{MAX_RANDOM}, got {arg!r}")
        rng = set_rng(self.seed, placed.volume.name, placed.geometry.name, 1000 + self._draws)
        first = self._draws
        self._draws += int(arg)
        local = sample_uniform(placed.geometry.spec, int(arg), rng)
        quaternions = np.tile([0.0, 0.0, 0.0, 1.0], (len(local), 1))
        names = [f"{placed.base_name}_rnd_{first + n}" for n in range(len(local))]
        new = [(placed.frame_name, n, Frame(p, np.eye(3))) for n, p in zip(names, local, strict=True)]
        map_quaternions = rotate_quaternions(placed.frame.rotation, quaternions)
        return QueryResult(placed.frame.apply(local), map_quaternions, names, new)

    def _coordinates(self, frame: Frame, parent: str, stem: str, arg: Any) -> QueryResult:
        poses = arg if isinstance(arg, list) and arg and isinstance(arg[0], list) and arg[0] and \
            isinstance(arg[0][0], list) else [arg]
        positions, quaternions = [], []
        for i, pose in enumerate(poses):
            where = "definition[3]" if len(poses) == 1 else f"definition[3][{i}]"
            if not (isinstance(pose, list) and len(pose) == 2 and isinstance(pose[0], list) and len(pose[0]) == 3
                    and isinstance(pose[1], list) and len(pose[1]) in (3, 4)
                    and all(isinstance(v, Real) and not isinstance(v, bool) for v in pose[0] + pose[1])):
                raise QueryError(f"{where}: a pose is [[x, y, z], [roll, pitch, yaw] or [qx, qy, qz, qw]], "
                                 f"got {pose!r}")
            q = np.array(pose[1], dtype=float)
            q = quaternions_from_rpy(q)[0] if len(q) == 3 else q
            if np.linalg.norm(q) < 1e-9:
                raise QueryError(f"{where}: a zero quaternion is no rotation; use [0, 0, 0, 1]")
            positions.append(pose[0])
            quaternions.append(q / np.linalg.norm(q))
        local_p, local_q = np.array(positions, dtype=float), np.array(quaternions)
        first = self._draws
        self._draws += len(poses)
        names = [f"{stem}_{first + n}" for n in range(len(poses))]
        new = [(parent, n, Frame.from_xyz_quaternion(p, q)) for n, p, q in zip(names, local_p, local_q, strict=True)]
        return QueryResult(frame.apply(local_p), rotate_quaternions(frame.rotation, local_q), names, new)

    def _path(self, placed: PlacedGeometry, arg: Any) -> QueryResult:
        paths = [(s, s.path_name) for s in placed.poses() if s.path_name]
        if not paths:
            raise QueryError(f"definition[2]: {placed.frame_name} has no zigzag path")
        if arg in (None, "", []):
            chosen = paths[0][0]
        elif isinstance(arg, int) and not isinstance(arg, bool) and 0 <= arg < len(paths):
            chosen = paths[arg][0]
        else:
            named = next((s for s, name in paths if isinstance(arg, str) and name.lower() == arg.lower()), None)
            if named is None:
                raise QueryError(f"definition[3]: no path {arg!r} in {placed.frame_name}; it has "
                                 f"{', '.join(name for _, name in paths)} (or their index from 0)")
            chosen = named
        return QueryResult(chosen.positions, chosen.quaternions, list(chosen.frames))

    def _poses(self, placed: PlacedGeometry, arg: Any) -> QueryResult:
        sets = placed.poses()
        if isinstance(arg, bool) or not isinstance(arg, int) or not 0 <= arg < len(sets):
            raise QueryError(f"definition[3]: {placed.frame_name} has {len(sets)} set(s) of poses; give an index "
                             f"0..{len(sets) - 1}, got {arg!r}")
        chosen = sets[arg]
        return QueryResult(chosen.positions, chosen.quaternions, list(chosen.frames))


def _decode(item: Any) -> Any:
    """ROS string[] requests carry each element as text: decode JSON where it parses, keep plain names."""
    if isinstance(item, str):
        try:
            return json.loads(item)
        except json.JSONDecodeError:
            return item
    return item
