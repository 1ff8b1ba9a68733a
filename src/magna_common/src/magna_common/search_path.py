"""Where worlds and missions are found by name: the one search path every command uses.

A name `WORLD/SUBWORLD` (or `MISSION/SUBMISSION`, a trailing `.json` allowed) is the file
`<NAME>/<SUBNAME>.json` under one of the search folders, in this order:

1. each `--search-path DIR` given, in order;
2. each folder of `$MAGNA_WORLDS_PATH` (`$MAGNA_MISSIONS_PATH`), os.pathsep-separated;
3. the project's `worlds/` (`missions/`).

In each search folder F the file is looked for in `F/worlds/` (`F/missions/`) when F has that
folder (a folder laid out like this project), then in F itself, then in `F/Worlds/` (`F/Missions/`,
a tree laid out like ROS-MAGNA's Code/JSONs).
"""
from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from magna_common.errors import UsageError


@dataclass(frozen=True)
class Kind:
    """What is looked for: its project folder, its ROS-MAGNA folder and its environment variable."""

    folder: str  # "worlds": this project's layout
    corpus_folder: str  # "Worlds": ROS-MAGNA's layout
    env: str

    def project_folder(self) -> Path | None:
        from magna_common.workspace import WorkspaceNotFound, find_root

        try:
            return find_root() / self.folder
        except WorkspaceNotFound:
            return None


WORLDS = Kind("worlds", "Worlds", "MAGNA_WORLDS_PATH")
MISSIONS = Kind("missions", "Missions", "MAGNA_MISSIONS_PATH")


def search_folders(kind: Kind, search_dirs: Iterable[Path] = ()) -> list[Path]:
    """The search folders in order: the --search-path folders, $MAGNA_<KIND>_PATH's, the project's (module doc)."""
    folders = [Path(d).expanduser() for d in search_dirs]
    folders += [Path(p).expanduser() for p in os.environ.get(kind.env, "").split(os.pathsep) if p]
    project = kind.project_folder()
    if project is not None:
        folders.append(project)
    return list(dict.fromkeys(folders))


def world_folders(search_dirs: Iterable[Path] = ()) -> list[Path]:
    return search_folders(WORLDS, search_dirs)


def mission_folders(search_dirs: Iterable[Path] = ()) -> list[Path]:
    return search_folders(MISSIONS, search_dirs)


def check_search_dirs(search_dirs: Iterable[Path]) -> None:
    """UsageError for a --search-path folder that does not exist."""
    for directory in search_dirs:
        if not Path(directory).expanduser().is_dir():
            raise UsageError(f"--search-path {directory}: no such folder; give a folder holding worlds/ and "
                             "missions/ (or Worlds/ and Missions/, as ROS-MAGNA's Code/JSONs)")


def candidates(kind: Kind, name: str, folders: Iterable[Path]) -> list[Path]:
    """Every place `name` ("Gym/Four_Cylinders", ".json" optional) may be, in the order looked at."""
    relative = Path(name if name.endswith(".json") else f"{name}.json")
    places: list[Path] = []
    for folder in folders:
        folder = Path(folder)
        if (folder / kind.folder).is_dir():
            places.append(folder / kind.folder / relative)
        places += [folder / relative, folder / kind.corpus_folder / relative]
    return list(dict.fromkeys(places))


def find(kind: Kind, name: str, folders: Iterable[Path]) -> Path | None:
    """The first of `candidates` that is a file, or None."""
    return next((place for place in candidates(kind, name, folders) if place.is_file()), None)


def looked_at(places: Iterable[Path]) -> str:
    """The places looked at, for a message."""
    return ", ".join(str(p) for p in places) or "nowhere (no search path)"


def find_world_file(world: str, subworld: str, folders: Iterable[Path]) -> Path | None:
    return find(WORLDS, f"{world}/{subworld}", folders)


def world_candidates(world: str, subworld: str, folders: Iterable[Path]) -> str:
    """Where `find_world_file` looked, for a message."""
    return looked_at(candidates(WORLDS, f"{world}/{subworld}", folders))
