"""The world designer's side of the studio: open, check, draw and describe a world document.

Every check is magna_worlds' own (`world_from_data`, `resolve_world`): a diagnostic is what
`magna world check` reports, on the field it names. The loader stops at a file's first error, so a
world shows at most one error at a time, and the warnings of what the original tolerated. The 3-D
scene is the rviz markers of magna_worlds.markers, as plain data for three.js.
"""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from magna_common.errors import UsageError
from magna_studio.documents import (
    Diagnostic,
    current_path,
    design_error,
    document_name,
    finding,
    in_current_schema,
    on_field,
    read_document,
    require_object,
)
from magna_worlds.cli import find_world, world_roots
from magna_worlds.errors import WorldError, WorldWarning
from magna_worlds.generate import PlacedGeometry, ResolvedWorld, resolve_world
from magna_worlds.loader import world_from_data
from magna_worlds.migrate import migrate
from magna_worlds.vocabulary import POSE_KINDS

# rviz marker types (visualization_msgs/Marker) -> the scene's shape names
_SHAPES = {1: "cube", 2: "sphere", 3: "cylinder", 4: "line", 7: "points", 11: "triangles"}
SCENE_DECIMALS = 6
_NAMESPACE_OF_KIND = {"geometry": "geometries", "pose_set": "poses", "zigzag": "poses", "obstacle": "obstacles"}


def world_folders_for(search_path: list[Path]) -> list[Path]:
    """Where included worlds are looked up (as `magna world check --search-path` does); DesignError for a search
    folder that does not exist."""
    try:
        return world_roots(search_path)
    except UsageError as error:
        raise design_error(error) from None


def include_base(source: str) -> Path | None:
    """The worlds root an included `{"name": "JSON", "world": W, "subworld": S}` is looked up in first: the
    including file's world folder's parent, as load_world takes it (None for a document with no folder)."""
    folder = Path(source).expanduser().parent
    return folder.parent if folder.is_dir() else None


def resolve_world_data(data: Any, source: str, search_path: list[Path], seed: int = 0) -> ResolvedWorld:
    """A world document (any schema) loaded, checked and laid out for `seed`; WorldError at its first problem."""
    world = world_from_data(data, source, base=include_base(source), search_path=world_folders_for(search_path))
    return resolve_world(world, seed)


def _error(error: WorldError, source: str) -> Diagnostic:
    text = str(error)
    if error.source != source:  # in an included file: about the document as a whole
        return on_field("error", "", text, text)
    return on_field("error", error.path, error.message, text)


def _warning(warning: str, source: str, data: Any) -> Diagnostic:
    if isinstance(warning, WorldWarning) and warning.source == source:
        return on_field("warning", warning.path, warning.message, warning)
    return finding("warning", warning, source, data)


def _checked(data: Any, source: str, search_path: list[Path], seed: int) -> tuple[list[Diagnostic],
                                                                                   ResolvedWorld | None]:
    try:
        resolved = resolve_world_data(data, source, search_path, seed)
    except WorldError as error:
        return [_error(error, source)], None
    return [_warning(w, source, data) for w in resolved.warnings], resolved


def check_world(data: dict[str, Any], source: str, search_path: list[Path], seed: int = 0) -> dict[str, Any]:
    """What `magna world check` says of the document, placed on its fields, and its 3-D scene (None when the
    world does not load). `source` names the document in the messages (its file)."""
    diagnostics, resolved = _checked(data, source, search_path, seed)
    return {"diagnostics": [d.to_json() for d in diagnostics],
            "scene": None if resolved is None else world_scene(resolved)}


def open_world(spec: str, search_path: list[Path], seed: int = 0) -> dict[str, Any]:
    """A world file (a path, or WORLD/SUBWORLD looked up as `magna run` does), in the current schema: an older
    one is migrated, its changes listed as `magna world check` lists them. The diagnostics are the command's on
    the file as it is written (same lines), placed on the migrated document's fields. DesignError for a file
    that is not found or not a JSON object."""
    try:
        path = find_world(spec, search_path)
    except UsageError as error:
        raise design_error(error) from None
    source = str(path)
    raw = read_document(path)
    migration = migrate(raw)
    data = require_object(migration.data, path, "world")
    diagnostics, resolved = _checked(raw, source, search_path, seed)
    scene = None if resolved is None else world_scene(resolved)
    for item in scene["items"] if scene is not None else []:
        item["path"] = current_path(migration.renamed, item["path"])
    return {"path": str(path.resolve()), "name": document_name(path), "data": data,
            "changes": [f"{source}: {change}" for change in migration.changes],
            "diagnostics": [in_current_schema(d, migration.renamed).to_json() for d in diagnostics],
            "scene": scene}


def new_world() -> dict[str, Any]:
    """A small world that loads without a warning under `magna world check --strict`: a ground station with four
    take-off pads (where legacy missions spawn: Ground_Station / Agents_take_off) and a box to fly in."""
    return {"scenario": {
        "world_boundaries": [[-10, 10], [-10, 10], [0, 8]],
        "volumes": [
            {"name": "Ground_Station", "prefix": "GS", "origin": [[0.0, -8.0, 0.0], [0, 0, 0]], "permits": "geofence",
             "geometries": [
                 {"name": "Agents_take_off", "prefix": "takeoff", "shape": "cube", "id": 0,
                  "origin": [[0, 0, 0.05], [0, 0, 0]], "dimensions": [8.0, 1.0, 0.1], "color": [30, 30, 30],
                  "alpha": 0.5,
                  "poses_sets": [{"type": "matrix", "matrix_type": "dimension", "use": "poses",
                                  "dimensions": [4, 1, 1], "poses_orientation": [0, 0, 1.570796]}]}]},
            {"name": "FlightZone", "prefix": "FZ", "origin": [[0.0, 0.0, 0.0], [0, 0, 0]], "permits": "geofence",
             "geometries": [
                 {"name": "Accessible", "prefix": "acc", "shape": "cube", "id": 0,
                  "origin": [[0, 0, 3.0], [0, 0, 0]], "dimensions": [10.0, 10.0, 4.0], "color": [0, 160, 80],
                  "alpha": 0.15,
                  "poses_sets": [{"type": "matrix", "matrix_type": "dimension", "use": "poses",
                                  "dimensions": [3, 3, 2]}]}]},
        ]}}


# --- the 3-D scene -------------------------------------------------------------------------------------------------

def world_scene(resolved: ResolvedWorld) -> dict[str, Any]:
    """The world for three.js: its boundaries and one item per rviz marker magna_worlds publishes, with the same
    geometry (map frame; rviz conventions: full sizes in `scale`, a cylinder's axis along z; a torus or prism as
    `triangles`, every three `points` one face in the item's frame; `points` and `line` in map). An item's
    `path` is the JSON path of the part that makes it ("" for a part of an included file, named by `file`)."""
    from magna_worlds.markers import world_markers

    markers = world_markers([resolved]).markers[1:]  # after the DELETEALL that clears stale ones
    parts = list(_parts(resolved))
    if len(parts) != len(markers):
        raise AssertionError(f"magna_worlds.markers drew {len(markers)} markers for {len(parts)} parts of "
                             f"{resolved.world.source}: world_scene no longer follows its order")
    items = [_item(kind, placed_geometry, part, marker, resolved.world.source)
             for (kind, placed_geometry, part), marker in zip(parts, markers, strict=True)]
    boundaries = resolved.world.boundaries
    return {"boundaries": boundaries.tolist() if np.isfinite(boundaries).all() else None, "items": items}


def _parts(resolved: ResolvedWorld) -> Iterator[tuple[str, PlacedGeometry, Any]]:
    """(kind, geometry, part) in the order magna_worlds.markers.world_markers draws them."""
    for placed_geometry in resolved.geometries:
        yield "geometry", placed_geometry, None
        for pose_set in placed_geometry.poses():
            yield "pose_set", placed_geometry, pose_set
            if pose_set.path_name and len(pose_set.positions) > 1:
                yield "zigzag", placed_geometry, pose_set
        for obstacle in placed_geometry.obstacles:
            yield "obstacle", placed_geometry, obstacle


def _item(kind: str, placed_geometry: PlacedGeometry, part: Any, marker: Any, document: str) -> dict[str, Any]:
    """One scene item from the marker drawn for `part`; AssertionError when the two do not belong together."""
    geometry = placed_geometry.geometry
    if marker.ns != _NAMESPACE_OF_KIND[kind] or (kind == "obstacle" and marker.text != part.name):
        raise AssertionError(f"{document}: the {kind} {getattr(part, 'name', geometry.name)} met a marker of "
                             f"{marker.ns} {marker.text!r}: world_scene no longer follows magna_worlds.markers")
    if kind == "geometry":
        name, frame, path = geometry.name, placed_geometry.frame_name, geometry.source_path
    elif kind == "obstacle":
        name, frame, path = part.name, part.name, _obstacles_path(placed_geometry)
    else:
        name = part.path_name if kind == "zigzag" else f"{geometry.name} {part.spec.type} poses"
        frame, path = placed_geometry.frame_name, part.spec.source_path
    pose = marker.pose
    item: dict[str, Any] = {
        "kind": kind, "name": name, "frame": frame, "shape": _SHAPES[marker.type],
        "position": _floats(pose.position.x, pose.position.y, pose.position.z),
        "orientation": _floats(pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w),
        "scale": _floats(marker.scale.x, marker.scale.y, marker.scale.z),
        "color": _floats(marker.color.r, marker.color.g, marker.color.b, marker.color.a),
        "path": path if placed_geometry.volume.source == document else "",
        "file": placed_geometry.volume.source,
    }
    if marker.points:
        item["points"] = [_floats(p.x, p.y, p.z) for p in marker.points]
    if kind == "pose_set":
        item["frames"] = list(part.frames)
    return item


def _obstacles_path(placed_geometry: PlacedGeometry) -> str:
    """The pose set an obstacle comes from; the geometry when it has several sets of obstacles (the lay-out does
    not say which set made which obstacle)."""
    sets = [s for s in placed_geometry.geometry.pose_sets if s.use == "obstacles"]
    return sets[0].source_path if len(sets) == 1 else placed_geometry.geometry.source_path


def _floats(*values: float) -> list[float]:
    """Plain floats to a micrometre (or a millionth): a world's meshes are megabytes of JSON at full precision."""
    return [round(float(v), SCENE_DECIMALS) for v in values]


# --- what missions may name ----------------------------------------------------------------------------------------

def pose_choices(data: dict[str, Any], source: str, search_path: list[Path], seed: int = 0) -> list[dict[str, Any]]:
    """What a mission's pose definition `[volume, geometry | "volume", kind, arg]` may name in this world, as
    magna_worlds.query resolves it (empty when the world does not load). One entry per volume (geometry
    "volume": coordinates in its frame) and per geometry: {"volume", "geometry", "frame", "kinds", "matrix_cells"
    (the cells of its first matrix set of poses, [i, j, k]), "paths" (its zigzags, by name), "pose_sets" (how many
    sets of poses; `poses` takes an index), "examples" (one definition per kind that resolves)}."""
    try:
        resolved = resolve_world_data(data, source, search_path, seed)
    except WorldError:
        return []
    choices = []
    for volume in resolved.world.volumes:
        choices.append(_choice(volume.name, "volume", volume.name, {"coordinates": _ORIGIN}))
        for placed_geometry in (g for g in resolved.geometries if g.volume is volume):
            choices.append(_geometry_choice(placed_geometry))
    return choices


_ORIGIN = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]  # a pose at the frame's origin: [[x, y, z], [roll, pitch, yaw]]


def _geometry_choice(placed_geometry: PlacedGeometry) -> dict[str, Any]:
    sets = placed_geometry.poses()
    matrix = next((s for s in sets if s.cells is not None), None)
    cells = sorted(matrix.cells) if matrix is not None and matrix.cells else []
    paths = [s.path_name for s in sets if s.path_name]
    args: dict[str, Any] = {"random": 1, "coordinates": _ORIGIN}
    if cells:
        args["matrix"] = list(cells[0])
    if paths:
        args["path"] = paths[0]
    if sets:
        args["poses"] = 0
    choice = _choice(placed_geometry.volume.name, placed_geometry.geometry.name, placed_geometry.frame_name, args)
    choice.update(matrix_cells=[list(c) for c in cells], paths=paths, pose_sets=len(sets))
    return choice


def _choice(volume: str, geometry: str, frame: str, args: dict[str, Any]) -> dict[str, Any]:
    kinds = [kind for kind in POSE_KINDS if kind in args]  # in the vocabulary's order
    return {"volume": volume, "geometry": geometry, "frame": frame, "kinds": kinds,
            "matrix_cells": [], "paths": [], "pose_sets": 0,
            "examples": [[volume, geometry, kind, args[kind]] for kind in kinds]}
