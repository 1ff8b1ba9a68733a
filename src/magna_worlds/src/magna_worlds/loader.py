"""Read a world JSON file (the ROS-MAGNA world format) into `model` objects, checking every field once.

Every error is a `WorldError` naming the file and the JSON path. A volume written
`{"name": "JSON", "world": W, "subworld": S}` includes the volumes of
`<worlds root>/W/S.json`, looked up first next to the including file (its world
folder's parent), then in each folder of `search_path`.

Files of every era of the original ROS-MAGNA load: an older format is first brought to
the current one by `migrate` (each change listed in `World.changes`), and what the
original tolerated without a word gets one warning in `World.warnings` saying what
MAGNA does with it (`strict=True` refuses it instead):

- no `world_boundaries` in the file checked (files from before the field existed, and
  parts that other worlds include): the box around every geometry plus `BOUNDARY_MARGIN`;
- a volume without `prefix` (a part that added geometries to a volume of the running
  world): the volume's name;
- two geometries of one volume with the same name (the original's look-ups by name found
  the later one): the earlier is renamed `<name>_<index>`;
- two geometries of one volume with the same prefix (the original published their pose
  frames twice): the later one's pose and obstacle frames are named after its name;
- a pose set of type `path` (a zigzag through a grid in the oldest format; ignored from
  `poses_sets` on): skipped.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Never

import numpy as np

from magna_common.json_fields import (
    JsonFields,
    UnreadableJson,
    describe,
    join_path,
    read_json_document,
)
from magna_common.search_path import find_world_file, world_candidates, world_folders
from magna_worlds.errors import WorldError, WorldWarning
from magna_worlds.migrate import migrate
from magna_worlds.model import SHAPES_FOR_ZIGZAG, Geometry, ObstacleSpec, OrientationSpec, PoseSetSpec, Volume, World
from magna_worlds.shapes import ShapeError, half_extents, parse_shape
from magna_worlds.transforms import Frame, quaternions_from_rpy
from magna_worlds.vocabulary import MATRIX_TYPES, POSE_SET_TYPES, SENSES, SHAPES, USES, Shape

if TYPE_CHECKING:
    from magna_worlds.generate import ResolvedWorld  # generate imports this module

BOUNDARY_MARGIN = 10.0  # m around the geometries, when a file gives no world_boundaries
IGNORED_SET_TYPES = ("path",)  # read by the oldest format only; later code skipped it without a word
Fields = JsonFields[Never]  # a world file stops at its first error

# What a missing field holds, for the message that asks for it (the format in words).
FIELD_HELP = {
    "scenario": 'the top-level object {"scenario": {"world_boundaries": ..., "volumes": [...]}}',
    "volumes": "a list of volumes, each {name, prefix, origin, geometries}",
    "name": "a name (missions refer to it)",
    "prefix": "a short text that starts the names of its tf frames",
    "origin": "[[x, y, z], [roll, pitch, yaw]] in its parent's frame (m, radians)",
    "geometries": "a list of geometries, each {name, prefix, shape, origin, dimensions}",
    "shape": "one of cube, sphere, cylinder, prism, torus",
    "dimensions": "the sizes in the shape's convention (a cube [x, y, z]; a prism [height, [[x, y], ...]])",
    "type": "one of matrix, random, coordinates, zigzag",
    "quantity": "how many random poses, a whole number >= 1",
    "coordinates": "[[[x, y, z], [roll, pitch, yaw]], ...] in the geometry's frame",
    "height": "the sweep's height above the prism's base, in m",
    "spacing": "[along each line, between lines] in m",
    "obstacles_shape": "the obstacle shapes drawn from, e.g. [\"cube\"]",
    "obstacles_dimensions": "[d0, d1, d2] in the shape's convention, each fixed or [low, high]",
    "world": "the world folder of the included file",
    "subworld": "the included file's name without .json",
    "world_boundaries": "[[xmin, xmax], [ymin, ymax], [zmin, zmax]] in m",
}


@dataclass(frozen=True)
class CheckedWorld:
    """A world file loaded and laid out once: what `magna world check` reports."""

    world: World
    resolved: ResolvedWorld
    warnings: tuple[str, ...]  # of the file and of its lay-out
    changes: tuple[str, ...]  # what the migration of an older format changed


def load_world(path: str | Path, search_path: Iterable[Path] | None = None, strict: bool = False) -> World:
    """Load and check a world file; raises WorldError. `strict` refuses what would be a warning."""
    path = Path(path)
    data = _read_json(path, str(path))
    return world_from_data(data, str(path), base=path.parent.parent,
                           search_path=world_folders() if search_path is None else list(search_path),
                           strict=strict)


def load_world_checked(path: str | Path, search_path: Iterable[Path] | None = None, strict: bool = False,
                       seed: int = 0) -> CheckedWorld:
    """Load a world file and lay it out for `seed`: every warning (the file's and the lay-out's) and change."""
    from magna_worlds.generate import resolve_world  # generate imports this module

    world = load_world(path, search_path, strict=strict)
    resolved = resolve_world(world, seed, strict=strict)
    return CheckedWorld(world, resolved, tuple(resolved.warnings), world.changes)


def world_from_data(data: Any, source: str, base: Path | None = None,
                    search_path: Iterable[Path] = (), strict: bool = False) -> World:
    """Check already-parsed JSON (a whole `{"scenario": ...}` or a bare list of volumes, as missions inline it)."""
    reader = _Loader(list(search_path), strict)
    if isinstance(data, list):
        data = {"scenario": {"volumes": data}}
        boundaries_required = False
    else:
        boundaries_required = True
    try:
        return reader.world(data, source, base, boundaries_required)
    except RecursionError:  # lists inside lists, hundreds deep, where the format has a number
        raise WorldError(source, "", "nested too deeply (hundreds of levels of lists or objects); no world needs "
                         "that many: check how the file was made") from None


def _read_json(path: Path, source: str) -> Any:
    try:
        return read_json_document(path)
    except UnreadableJson as err:
        raise WorldError(source, "", str(err)) from None


def default_boundaries(volumes: Iterable[Volume], margin: float = BOUNDARY_MARGIN) -> np.ndarray:
    """The box around every geometry (a volume without any: its origin) in map, `margin` m larger on each side."""
    points = []
    for volume in volumes:
        if not volume.geometries:
            points.append(volume.origin.translation[None, :])
        for geometry in volume.geometries:
            low, high = half_extents(geometry.spec)
            corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                                for z in (low[2], high[2])])
            points.append(volume.origin.compose(geometry.origin).apply(corners))
    stacked = np.vstack(points) if points else np.zeros((1, 3))
    return np.column_stack([stacked.min(axis=0) - margin, stacked.max(axis=0) + margin]).round(3)


def format_box(box: np.ndarray) -> str:
    return "  ".join(f"{axis} {low:g}..{high:g}" for axis, (low, high) in zip("xyz", box.tolist(), strict=True)) + " m"


class _Loader:
    def __init__(self, search_path: list[Path], strict: bool = False):
        self.search_path = search_path
        self.strict = strict
        self.included: list[str] = []
        self.warnings: list[WorldWarning] = []
        self.changes: list[str] = []
        self._stack: list[str] = []

    def warn(self, f: Fields, where: str, message: str) -> None:
        """One warning: what the original tolerated and what MAGNA does with it; an error when strict."""
        where = f.original_path(where)
        if self.strict:
            raise WorldError(f.source, where, f"{message} (refused with --strict)")
        self.warnings.append(WorldWarning(f.source, where, message))

    # --- world and volumes ------------------------------------------------------------------------------------

    def world(self, data: Any, source: str, base: Path | None, boundaries_required: bool) -> World:
        self._stack.append(str(Path(source).resolve()) if base is not None else source)
        migration = migrate(data)
        self.changes += [f"{source}: {change}" for change in migration.changes]
        data = migration.data
        f = JsonFields.first_error(source, WorldError, migration.original_path)
        if not isinstance(data, dict):
            raise WorldError(source, "", "the top level must be an object {\"scenario\": {\"world_boundaries\": ..., "
                             f"\"volumes\": [...]}}}}, got {describe(data)}")
        scenario = f.object(_key(f, data, "", "scenario"), "scenario")
        boundaries = None
        if "world_boundaries" in scenario:
            boundaries = _boundaries(f, scenario["world_boundaries"], "scenario.world_boundaries")
        origin_geo = None
        if "origin_geo" in scenario:
            lat, lon, alt = f.numbers(scenario["origin_geo"], "scenario.origin_geo", 3,
                                      "[latitude, longitude, altitude]")
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                raise WorldError(source, "scenario.origin_geo", f"latitude must be -90..90 and longitude -180..180 "
                                 f"degrees, got {lat}, {lon}")
            origin_geo = (lat, lon, alt)
        self._unknown(f, scenario, "scenario", {"world_boundaries", "origin_geo", "volumes"})
        try:
            volumes = self.volumes(f, f.list(_key(f, scenario, "scenario", "volumes"), "scenario.volumes"),
                                   "scenario.volumes", base)
        except WorldError as err:  # name the path as the file writes it, before any migration renamed a key
            if err.source != source or migration.original_path(err.path) == err.path:
                raise
            raise WorldError(source, migration.original_path(err.path), err.message) from None
        names: dict[str, str] = {}
        for volume in volumes:
            if volume.name in names:
                raise WorldError(volume.source, join_path(volume.source_path, "name"),
                                 f"volume {volume.name!r} is defined twice (also {names[volume.name]}); "
                                 "give each volume its own name")
            names[volume.name] = f"{volume.source}: {volume.source_path}"
        self._stack.pop()
        defaulted = False
        if boundaries is None and boundaries_required:
            boundaries, defaulted = default_boundaries(volumes), True
            self.warn(f, "scenario.world_boundaries", "missing (files older than the field have none, and so have "
                      "parts that other worlds include); MAGNA uses the box around every geometry plus "
                      f"{BOUNDARY_MARGIN:g} m on each side, {format_box(boundaries)}, and aborts a UAV that leaves "
                      "it. Add world_boundaries [[xmin, xmax], [ymin, ymax], [zmin, zmax]] to choose it")
        if boundaries is None:
            boundaries = np.array([[-math.inf, math.inf]] * 3)
        return World(source, boundaries, origin_geo, tuple(volumes), tuple(self.included), tuple(self.warnings),
                     tuple(self.changes), defaulted)

    def volumes(self, f: Fields, items: list, path: str, base: Path | None) -> list[Volume]:
        volumes: list[Volume] = []
        for index, item in enumerate(items):
            where = join_path(path, index)
            obj = f.object(item, where)
            if obj.get("name") == "JSON":
                volumes.extend(self.include(f, obj, where, base))
            else:
                volumes.append(self.volume(f, obj, where))
        return volumes

    def include(self, f: Fields, obj: dict, where: str, base: Path | None) -> list[Volume]:
        world = f.text(_key(f, obj, where, "world"), join_path(where, "world"))
        subworld = f.text(_key(f, obj, where, "subworld"), join_path(where, "subworld"))
        roots = ([base] if base is not None else []) + self.search_path
        found = find_world_file(world, subworld, roots)
        if found is None:
            looked = world_candidates(world, subworld, roots)
            raise WorldError(f.source, where, f"included world {world}/{subworld} not found; looked at {looked}. "
                             "Fix world/subworld or add its folder to MAGNA_WORLDS_PATH")
        key = str(found.resolve())
        if key in self._stack:
            chain = " -> ".join(self._stack)
            raise WorldError(f.source, where, f"{world}/{subworld} includes itself (through {chain}); remove the loop")
        self.included.append(str(found))
        nested = self.world(_read_json(found, str(found)), str(found), found.parent.parent, boundaries_required=False)
        return list(nested.volumes)

    def volume(self, f: Fields, obj: dict, where: str) -> Volume:
        name = f.text(_key(f, obj, where, "name"), join_path(where, "name"))
        if "prefix" in obj:
            prefix = f.text(obj["prefix"], join_path(where, "prefix"))
        else:
            prefix = name
            self.warn(f, join_path(where, "prefix"), f"missing; the original took the prefix of the volume {name!r} "
                      "already in the running world when this file was added to it as a part (and stopped with an "
                      f"error when there was none); MAGNA uses the volume's name, {name!r}, to name its frames")
        origin = _origin(f, _key(f, obj, where, "origin"), join_path(where, "origin"))
        permits = f.text(obj.get("permits", ""), join_path(where, "permits"), allow_empty=True)
        self._unknown(f, obj, where, {"name", "prefix", "origin", "permits", "geometries"})
        geometries: list[Geometry] = []
        items = f.list(_key(f, obj, where, "geometries"), join_path(where, "geometries"))
        for index, item in enumerate(items):
            at = join_path(join_path(where, "geometries"), index)
            geometries.append(self.geometry(f, f.object(item, at), at))
        return Volume(name, prefix, origin, permits, self._distinct(f, name, prefix, geometries), f.source, where)

    def _distinct(self, f: Fields, volume: str, prefix: str, geometries: list[Geometry]) -> tuple[Geometry, ...]:
        """Geometries that repeat a name or a prefix of their volume, made distinct (the original let them clash)."""
        out = list(geometries)
        for index, geometry in enumerate(out):
            later = next((g for g in out[index + 1:] if g.name == geometry.name), None)
            if later is not None:
                taken = {g.name for g in out}
                new, n = f"{geometry.name}_{index}", index
                while new in taken:
                    n += 1
                    new = f"{geometry.name}_{n}"
                same_prefix = later.prefix == geometry.prefix and bool(geometry.pose_sets)
                out[index] = replace(geometry, name=new, frame_prefix=new if same_prefix else geometry.frame_prefix)
                frames = f"frames {prefix}_{new} and {prefix}_{new}_pos_..." if same_prefix else f"frame {prefix}_{new}"
                self.warn(f, join_path(geometry.source_path, "name"), f"volume {volume!r} defines a geometry "
                          f"{geometry.name!r} again at {f.original_path(later.source_path)}; the original's "
                          f"look-ups by name found that later one, and so do MAGNA's; this one is kept as {new!r} "
                          f"({frames})")
        for index, geometry in enumerate(out):
            earlier = next((g for g in out[:index] if (g.frame_prefix or g.prefix) == geometry.prefix and g.pose_sets),
                           None)
            if earlier is not None and geometry.pose_sets:
                out[index] = replace(geometry, frame_prefix=geometry.name)
                self.warn(f, join_path(geometry.source_path, "prefix"), f"{geometry.prefix!r} is also the prefix of "
                          f"{earlier.name!r} in volume {volume!r}, so the original published their pose frames "
                          f"under the same names; MAGNA names this geometry's pose and obstacle frames "
                          f"{prefix}_{geometry.name}_pos_... and {prefix}_{geometry.name}_obs_...")
        return tuple(out)

    # --- geometries ---------------------------------------------------------------------------------------------

    def geometry(self, f: Fields, obj: dict, where: str) -> Geometry:
        name = f.text(_key(f, obj, where, "name"), join_path(where, "name"))
        prefix = f.text(_key(f, obj, where, "prefix"), join_path(where, "prefix"))
        shape = _key(f, obj, where, "shape")
        try:
            spec = parse_shape(shape, _key(f, obj, where, "dimensions"))
        except ShapeError as err:
            raise _shape_error(f.source, where, err) from None
        gid = f.integer(obj.get("id", 0), join_path(where, "id"), "an integer")
        origin = _origin(f, _key(f, obj, where, "origin"), join_path(where, "origin"))
        color = f.numbers(obj.get("color", [128, 128, 128]), join_path(where, "color"), 3, "[r, g, b], each 0-255")
        if any(c < 0 or c > 255 for c in color):
            raise WorldError(f.source, join_path(where, "color"), f"each component must be 0-255, got {list(color)}")
        alpha = f.number(obj.get("alpha", 1.0), join_path(where, "alpha"))
        if not 0.0 <= alpha <= 1.0:
            raise WorldError(f.source, join_path(where, "alpha"), f"must be 0..1 (0 invisible, 1 opaque), got {alpha}")
        self._unknown(f, obj, where, {"name", "prefix", "shape", "id", "origin", "dimensions", "color", "alpha",
                                      "poses_sets"})
        sets_path = join_path(where, "poses_sets")
        sets: list[PoseSetSpec] = []
        for i, item in enumerate(f.list(obj.get("poses_sets", []), sets_path)):
            at = join_path(sets_path, i)
            item = f.object(item, at)
            if item.get("type") in IGNORED_SET_TYPES:
                if f.original_path(sets_path) != sets_path:  # written as divisions: the oldest format
                    what = ("in this format (divisions) the original laid a zigzag through a grid of `dimensions` "
                            "cells of the geometry, flown as its path; MAGNA has no such set and skips it, so a "
                            "mission asking for this geometry's path is refused")
                else:
                    what = ("the original skipped it without a word (the grid zigzag of the older format, dropped "
                            "when divisions became poses_sets); MAGNA skips it too")
                self.warn(f, join_path(at, "type"), f"{item['type']!r}: {what}. For a sweep, use a zigzag pose set "
                          "over a prism")
                continue
            sets.append(self.pose_set(f, item, at, spec.shape))
        red, green, blue = (c / 255.0 for c in color)
        return Geometry(name, prefix, spec, gid, origin, (red, green, blue), alpha, tuple(sets), where)

    # --- pose sets ------------------------------------------------------------------------------------------------

    def pose_set(self, f: Fields, obj: dict[str, Any], where: str, shape: Shape) -> PoseSetSpec:
        kind = f.choice(_key(f, obj, where, "type"), join_path(where, "type"), POSE_SET_TYPES, noun="value")
        use = f.choice(obj.get("use", "poses"), join_path(where, "use"), USES, noun="value")
        common: dict[str, Any] = {"type": kind, "use": use, "source_path": f.original_path(where)}
        known = {"type", "use", "poses_orientation", "set_orientation", "obstacles_shape", "obstacles_dimensions"}
        if "poses_orientation" in obj:
            common["orientation"] = _orientation(f, obj["poses_orientation"], join_path(where, "poses_orientation"))
        if "set_orientation" in obj:
            common["set_yaw"] = f.numbers(obj["set_orientation"], join_path(where, "set_orientation"), 3,
                                          "[roll, pitch, yaw] in radians")[2]
        if use == "obstacles":
            common["obstacle"] = self.obstacle(f, obj, where)
        if kind == "matrix":
            known |= {"matrix_type", "dimensions", "density"}
            matrix_type = f.choice(obj.get("matrix_type", "dimension"), join_path(where, "matrix_type"), MATRIX_TYPES,
                                   noun="value")
            dims_path = join_path(where, "dimensions")
            if matrix_type == "dimension":
                dims = f.numbers(_key(f, obj, where, "dimensions"), dims_path, 3, "[count_x, count_y, count_z]")
                for axis, n in enumerate(dims):
                    if n != int(n) or n < 1:
                        raise WorldError(f.source, join_path(dims_path, axis), "a dimension matrix counts poses per "
                                         f"axis: a whole number >= 1, got {n}")
            else:
                dims = f.numbers(_key(f, obj, where, "dimensions"), dims_path, 3,
                                 "[spacing_x, spacing_y, spacing_z] in m")
                for axis, s in enumerate(dims):
                    if s <= 0:
                        raise WorldError(f.source, join_path(dims_path, axis), f"a spacing must be positive, got {s}")
            density = f.number(obj.get("density", 1.0), join_path(where, "density"))
            if not 0.0 < density <= 1.0:
                raise WorldError(f.source, join_path(where, "density"), "the share of cells kept must be in (0, 1], "
                                 f"got {density}")
            common.update(matrix_type=matrix_type, matrix_dimensions=tuple(dims), density=density)
        elif kind == "random":
            known |= {"quantity"}
            common["quantity"] = f.integer(_key(f, obj, where, "quantity"), join_path(where, "quantity"),
                                           "a whole number >= 1", minimum=1)
        elif kind == "coordinates":
            known |= {"coordinates"}
            common["coordinates"] = _poses(f, _key(f, obj, where, "coordinates"), join_path(where, "coordinates"))
        else:
            known |= {"height", "spacing", "sweep_angle", "margins", "initial_sense", "orientation"}
            if shape not in SHAPES_FOR_ZIGZAG:
                raise WorldError(f.source, join_path(where, "type"), f"a zigzag sweeps a prism's polygon; this "
                                 f"geometry is a {shape}. Make the geometry a prism or use another pose-set type")
            spacing = f.numbers(_key(f, obj, where, "spacing"), join_path(where, "spacing"), 2,
                                "[along each line (0: its ends only), between lines] in m")
            if spacing[1] <= 0 or spacing[0] < 0:
                raise WorldError(f.source, join_path(where, "spacing"), "the distance between lines must be positive "
                                 f"and the one along a line >= 0, got {list(spacing)}")
            margins = f.numbers(obj.get("margins", [0.0, 0.0]), join_path(where, "margins"), 2,
                                "[at the ends of each line, from the outer lines to the edge] in m")
            if min(margins) < 0:
                raise WorldError(f.source, join_path(where, "margins"), f"margins must be >= 0, got {list(margins)}")
            if "orientation" in obj and "poses_orientation" not in obj:
                common["orientation"] = _orientation(f, obj["orientation"], join_path(where, "orientation"))
            common.update(height=f.number(_key(f, obj, where, "height"), join_path(where, "height")),
                          spacing=tuple(spacing),
                          sweep_angle=f.number(obj.get("sweep_angle", 0.0), join_path(where, "sweep_angle")),
                          margins=tuple(margins),
                          initial_sense=f.choice(obj.get("initial_sense", "right"), join_path(where, "initial_sense"),
                                                 SENSES, noun="value"))
        self._unknown(f, obj, where, known)
        return PoseSetSpec(**common)

    def obstacle(self, f: Fields, obj: dict, where: str) -> ObstacleSpec:
        shapes_path, dims_path = join_path(where, "obstacles_shape"), join_path(where, "obstacles_dimensions")
        raw_shapes = _key(f, obj, where, "obstacles_shape")
        listed = [raw_shapes] if isinstance(raw_shapes, str) else f.list(raw_shapes, shapes_path)
        if not listed:
            raise WorldError(f.source, shapes_path, f"give at least one of {', '.join(SHAPES)}")
        shapes = [f.choice(s, join_path(shapes_path, i), SHAPES, noun="value") for i, s in enumerate(listed)]
        dims = f.list(_key(f, obj, where, "obstacles_dimensions"), dims_path)
        if "prism" in shapes:
            if shapes != ["prism"] * len(shapes):
                raise WorldError(f.source, shapes_path, "a prism obstacle needs its own vertices; do not mix it with "
                                 "other shapes in one set")
            try:
                spec = parse_shape("prism", dims)
            except ShapeError as err:
                raise _shape_error(f.source, where, err, rename={"dimensions": "obstacles_dimensions"}) from None
            return ObstacleSpec(("prism",), ((spec.dimensions[0], spec.dimensions[0]),), spec.polygon)
        if len(dims) != 3:
            raise WorldError(f.source, dims_path, "give [d0, d1, d2] (fixed) or [[low, high], x3] (drawn per "
                             f"obstacle) in the shape's convention, got {len(dims)} value(s)")
        ranges = []
        for axis, d in enumerate(dims):
            at = join_path(dims_path, axis)
            low, high = (d, d) if not isinstance(d, list) else f.numbers(d, at, 2, "[low, high]")
            low, high = f.number(low, join_path(dims_path, axis)), f.number(high, join_path(dims_path, axis))
            if not 0 < low <= high:
                raise WorldError(f.source, join_path(dims_path, axis), f"need 0 < low <= high, got {low}, {high}")
            ranges.append((low, high))
        if "torus" in shapes and all(low == high for low, high in ranges):
            try:  # a fixed torus must be one: [2R, 2R + 2r, 2r]; the other shapes take the sizes they need from it
                parse_shape("torus", [low for low, _ in ranges])
            except ShapeError as err:
                raise WorldError(f.source, dims_path, f"for the torus obstacles: {err}") from None
        return ObstacleSpec(tuple(shapes), tuple(ranges))

    def _unknown(self, f: Fields, obj: dict, where: str, known: set[str]) -> None:
        for key in obj:
            if key not in known:
                self.warn(f, join_path(where, key), "unknown field, ignored")


def _shape_error(source: str, where: str, err: ShapeError, rename: dict[str, str] | None = None) -> WorldError:
    """A ShapeError reads `dimensions[1]: ...`; put its field under the geometry's JSON path."""
    field, _, message = str(err).partition(": ")
    head, bracket, rest = field.partition("[")
    head = (rename or {}).get(head, head)
    return WorldError(source, f"{where}.{head}{bracket}{rest}", message)


def _key(f: Fields, obj: Any, where: str, key: str) -> Any:
    """A required key; the message asks for it in the format's words (FIELD_HELP)."""
    what = FIELD_HELP.get(key)
    return f.key(obj, where, key, f"add it: {what}" if what else "add it")


def _origin(f: Fields, value: Any, where: str) -> Frame:
    items = f.list(value, where)
    if len(items) != 2:
        f.fail(where, f"expected [[x, y, z], [roll, pitch, yaw]], got {len(items)} item(s)")
    xyz = f.numbers(items[0], join_path(where, 0), 3, "[x, y, z] in m")
    rpy = f.numbers(items[1], join_path(where, 1), 3, "[roll, pitch, yaw] in radians")
    return Frame.from_xyz_rpy(xyz, rpy)


def _boundaries(f: Fields, value: Any, where: str) -> np.ndarray:
    items = f.list(value, where)
    if len(items) != 3:
        f.fail(where, f"expected [[xmin, xmax], [ymin, ymax], [zmin, zmax]], got {len(items)} item(s)")
    rows = [f.numbers(item, join_path(where, i), 2, "[min, max]") for i, item in enumerate(items)]
    for i, (low, high) in enumerate(rows):
        if low >= high:
            f.fail(join_path(where, i), f"min must be below max, got [{low}, {high}]")
    return np.array(rows)


def _orientation(f: Fields, value: Any, where: str) -> OrientationSpec:
    if value == "random":
        return OrientationSpec(any_rotation=True)
    if value == "random_yaw":
        return OrientationSpec(((0.0, 0.0), (0.0, 0.0), (-math.pi, math.pi)))
    items = f.list(value, where)
    if len(items) != 3:
        f.fail(where, "expected [roll, pitch, yaw], [[low, high] x3], \"random_yaw\" or \"random\", "
               f"got {len(items)} value(s)")
    ranges = []
    for axis, item in enumerate(items):
        if isinstance(item, list):
            low, high = f.numbers(item, join_path(where, axis), 2, "[low, high] in radians")
            if low > high:
                f.fail(join_path(where, axis), f"low must not exceed high, got [{low}, {high}]")
        else:
            low = high = f.number(item, join_path(where, axis))
        ranges.append((low, high))
    return OrientationSpec(tuple(ranges))


def _poses(f: Fields, value: Any, where: str) -> tuple[tuple[tuple[float, ...], tuple[float, ...]], ...]:
    """[[[x, y, z], [roll, pitch, yaw] or [qx, qy, qz, qw]], ...] -> ((xyz, quaternion), ...)."""
    positions, turns = [], []
    for i, item in enumerate(f.list(value, where)):
        at = join_path(where, i)
        pair = f.list(item, at)
        if len(pair) != 2:
            f.fail(at, f"expected [[x, y, z], [roll, pitch, yaw]], got {len(pair)} item(s)")
        positions.append(f.numbers(pair[0], join_path(at, 0), 3, "[x, y, z] in m"))
        turn = f.list(pair[1], join_path(at, 1))
        if len(turn) == 3:
            turns.append(f.numbers(turn, join_path(at, 1), 3, "[roll, pitch, yaw]"))
        else:
            q = np.array(f.numbers(turn, join_path(at, 1), 4, "[roll, pitch, yaw] or [qx, qy, qz, qw]"))
            if np.linalg.norm(q) < 1e-9:
                f.fail(join_path(at, 1), "a zero quaternion is no rotation; use [0, 0, 0, 1]")
            turns.append(q / np.linalg.norm(q))
    if not positions:
        f.fail(where, "give at least one pose [[x, y, z], [roll, pitch, yaw]]")
    rpy_rows = [n for n, turn in enumerate(turns) if len(turn) == 3]
    quaternions = [tuple(float(v) for v in turn) for turn in turns]
    if rpy_rows:  # converted together: scipy's per-call overhead dominates a file of thousands of poses
        for n, quaternion in zip(rpy_rows, quaternions_from_rpy([turns[n] for n in rpy_rows]), strict=True):
            quaternions[n] = tuple(float(v) for v in quaternion)
    return tuple(zip(positions, quaternions, strict=True))
