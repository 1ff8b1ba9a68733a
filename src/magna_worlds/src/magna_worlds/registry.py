"""The worlds a running node holds: parts added and deleted by id, queried together, recorded as one JSON.

A part is a whole world file, a `world/subworld` pair looked up in the search path,
or an inline definition (a list of volumes, as missions write `world_part_def`).
Volume names are unique across parts, so a mission's `[volume, ...]` names one place.
"""
from __future__ import annotations

import json
from pathlib import Path

from magna_common.search_path import find_world_file, world_candidates, world_folders
from magna_worlds.errors import WorldError
from magna_worlds.generate import ResolvedWorld, resolve_world, world_record
from magna_worlds.loader import load_world, world_from_data
from magna_worlds.query import PoseQueries, QueryResult
from magna_worlds.transforms import Frame


class WorldRegistry:
    def __init__(self, seed: int = 0, search_path: list[Path] | None = None):
        self.search_path = world_folders() if search_path is None else list(search_path)
        self.reset(seed)

    def reset(self, seed: int) -> None:
        """Forget every part and query, as a new registry with `seed` (and this search path) would be: the random
        poses and obstacles of the next parts, and the draws of random queries, repeat those of a fresh start."""
        self.seed = seed
        self.parts: dict[str, ResolvedWorld] = {}
        self.queries = PoseQueries(seed)
        self.query_frames: dict[str, list[tuple[str, str, Frame]]] = {}  # part id -> frames made by queries

    # --- adding and deleting ------------------------------------------------------------------------------------

    def add_file(self, part_id: str, path) -> ResolvedWorld:
        return self._add(part_id, load_world(path, self.search_path))

    def add_named(self, part_id: str, world: str, subworld: str) -> ResolvedWorld:
        found = find_world_file(world, subworld, self.search_path)
        if found is None:
            looked = world_candidates(world, subworld, self.search_path)
            raise WorldError(f"{world}/{subworld}", "", f"no such world; looked at {looked}")
        return self.add_file(part_id, found)

    def add_inline(self, part_id: str, definition_json: str) -> ResolvedWorld:
        source = f"world part {part_id!r} (inline)"
        try:
            data = json.loads(definition_json)
        except json.JSONDecodeError as err:
            raise WorldError(source, "", f"not valid JSON: {err.msg} at column {err.colno}") from None
        return self._add(part_id, world_from_data(data, source, search_path=self.search_path))

    def _add(self, part_id: str, world) -> ResolvedWorld:
        if not part_id:
            raise WorldError(world.source, "", "id: give the part an id (deleting uses it)")
        if part_id in self.parts:
            raise WorldError(world.source, "", f"id: a part {part_id!r} exists already; delete it first or "
                             "pick another id")
        taken = {v: pid for pid, part in self.parts.items() for v in part.volume_frames}
        for volume in world.volumes:
            if volume.name in taken:
                raise WorldError(volume.source, f"{volume.source_path}.name", f"volume {volume.name!r} is already in "
                                 f"part {taken[volume.name]!r}; delete that part or rename the volume")
        resolved = resolve_world(world, self.seed)
        self.parts[part_id] = resolved
        return resolved

    def delete(self, part_id: str) -> ResolvedWorld:
        if part_id not in self.parts:
            raise KeyError(f"id: no world part {part_id!r}; parts: {', '.join(self.parts) or 'none'}")
        self.query_frames.pop(part_id, None)
        return self.parts.pop(part_id)

    # --- reading -----------------------------------------------------------------------------------------------

    def resolve(self, definition) -> QueryResult:
        worlds = list(self.parts.values())
        result = self.queries.resolve(worlds, definition)
        if result.new_frames:
            owner = next(pid for pid, w in self.parts.items() if definition[0] in w.volume_frames)
            self.query_frames.setdefault(owner, []).extend(result.new_frames)
        return result

    def static_transforms(self) -> list[tuple[str, str, Frame]]:
        out = []
        for pid, part in self.parts.items():
            out += part.static_transforms() + self.query_frames.get(pid, [])
        return out

    def record(self) -> dict:
        return {"seed": self.seed, "parts": {pid: world_record(part) for pid, part in self.parts.items()}}
