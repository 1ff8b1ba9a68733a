"""Older ROS-MAGNA world JSON -> the current format, in one step that says what it changed.

The world format changed over the original's history; its files of every era are read:

- a geometry's pose sets were a list called `divisions` (Jan 2019) -> `poses_sets`;
- a pose set turned its poses with `orientation` -> `poses_orientation` (a zigzag still
  takes `orientation`, it is part of the current zigzag format);
- a matrix had no `matrix_type`: it was always laid by counts per axis -> `matrix_type: dimension`;
- the ground station's take-off geometry was called `UAVs_take_off` until March 2019, when it became
  `Agents_take_off` (the name legacy missions' `spawn_uavs` migrates to) -> renamed, unless the
  volume already has an `Agents_take_off`.

`migrate(data)` never changes its argument and never fails: what it does not recognise is
left for the loader to report. It renames and fills in, never adds or removes volumes,
geometries or pose sets, so JSON paths stay those of the file (`original_path` maps the
renamed keys back).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from magna_common.json_fields import copy_json, join_path

LEGACY_SETS_KEY, SETS_KEY = "divisions", "poses_sets"
LEGACY_ORIENTATION_KEY, ORIENTATION_KEY = "orientation", "poses_orientation"
KEEPS_ORIENTATION = ("zigzag",)  # its own `orientation` field is current format
LEGACY_TAKE_OFF, TAKE_OFF = "UAVs_take_off", "Agents_take_off"


@dataclass
class Migration:
    data: Any  # the migrated JSON (a deep copy; the input is untouched)
    original: Any = None  # the input, as read
    changes: list[str] = field(default_factory=list)  # human-readable, each starting with the JSON path
    renamed: dict[str, str] = field(default_factory=dict)  # JSON path now -> JSON path in the file

    @property
    def changed(self) -> bool:
        return bool(self.changes)

    def original_path(self, path: str) -> str:
        """The file's JSON path for a path of the migrated data (renamed keys mapped back)."""
        best = ""
        for new in self.renamed:
            if (path == new or path.startswith(new + ".") or path.startswith(new + "[")) and len(new) > len(best):
                best = new
        return self.renamed[best] + path[len(best):] if best else path


def migrate(data: Any) -> Migration:
    """Bring a world (`{"scenario": ...}` or a bare list of volumes) to the current format."""
    result = Migration(copy_json(data), data)
    if isinstance(result.data, list):
        volumes, path = result.data, ""
    elif isinstance(result.data, dict) and isinstance(result.data.get("scenario"), dict):
        volumes, path = result.data["scenario"].get("volumes"), "scenario.volumes"
    else:
        return result
    if not isinstance(volumes, list):
        return result
    for v, volume in enumerate(volumes):
        geometries = volume.get("geometries") if isinstance(volume, dict) else None
        if not isinstance(geometries, list):
            continue
        names = [g.get("name") for g in geometries if isinstance(g, dict)]  # a name may be anything here
        for g, geometry in enumerate(geometries):
            if isinstance(geometry, dict):
                where = join_path(join_path(join_path(path, v), "geometries"), g)
                if geometry.get("name") == LEGACY_TAKE_OFF and TAKE_OFF not in names:
                    geometry["name"] = TAKE_OFF
                    result.changes.append(f"{join_path(where, 'name')}: {LEGACY_TAKE_OFF} -> {TAKE_OFF} (the "
                                          "take-off geometry's later name, where legacy missions spawn)")
                _geometry(result, geometry, where)
    return result


def _geometry(result: Migration, geometry: dict[str, Any], where: str) -> None:
    if LEGACY_SETS_KEY in geometry and SETS_KEY not in geometry:
        geometry[SETS_KEY] = geometry.pop(LEGACY_SETS_KEY)
        result.changes.append(f"{join_path(where, LEGACY_SETS_KEY)} -> {SETS_KEY}")
        result.renamed[join_path(where, SETS_KEY)] = join_path(where, LEGACY_SETS_KEY)
    sets = geometry.get(SETS_KEY)
    if not isinstance(sets, list):
        return
    for s, pose_set in enumerate(sets):
        if not isinstance(pose_set, dict):
            continue
        at = join_path(join_path(where, SETS_KEY), s)
        shown = result.original_path(at)
        kind = pose_set.get("type")
        if (LEGACY_ORIENTATION_KEY in pose_set and ORIENTATION_KEY not in pose_set
                and kind not in KEEPS_ORIENTATION):
            pose_set[ORIENTATION_KEY] = pose_set.pop(LEGACY_ORIENTATION_KEY)
            result.changes.append(f"{join_path(shown, LEGACY_ORIENTATION_KEY)} -> {ORIENTATION_KEY}")
            result.renamed[join_path(at, ORIENTATION_KEY)] = join_path(shown, LEGACY_ORIENTATION_KEY)
        if kind == "matrix" and "matrix_type" not in pose_set:
            pose_set["matrix_type"] = "dimension"
            result.changes.append(f"{shown}: matrix_type \"dimension\" added (a matrix without it was laid by "
                                  "counts per axis)")
