"""Read a mission file: JSON -> migration (legacy schema) -> typed `Mission` -> validation.

    loaded = load_mission("missions/Gym/Two_Paths.json")
    loaded.mission, loaded.changes, loaded.warnings, loaded.plan
    load_mission(path, strict=True)   # warnings are problems too (MissionError)

Missions are also found by name, `<mission>/<submission>` as the hyperparameters give
them (`find_mission("Gym/2UAVs_2paths_Central_Cylinder")`), along the search path of
magna_common.search_path: `--search-path` folders first, then `$MAGNA_MISSIONS_PATH`, then
the project's `missions/`; a folder may also be a ROS-MAGNA tree whose missions sit in `Missions/`.
Every problem is a `MissionError` line `file: JSON.path: message`.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.json_fields import UnreadableJson, read_json_document
from magna_common.search_path import MISSIONS, candidates, find, looked_at, mission_folders
from magna_gs.mission.migrate import migrate
from magna_gs.mission.model import Mission, MissionError
from magna_gs.mission.parse import parse_mission
from magna_gs.mission.plan import Plan

STRICT_NOTE = "[refused: strict mode turns warnings into errors]"


@dataclass
class LoadedMission:
    mission: Mission
    changes: list[str]  # what the migration from the legacy schema changed (empty for a current file)
    warnings: list[str] = field(default_factory=list)  # findings that do not stop the mission
    plan: Plan | None = None  # the expanded states (None when loaded with validate=False)


def find_mission(name: str, search_path: Iterable[Path] | None = None) -> Path:
    """The file of mission `name` ("Gym/2UAVs_2paths_Central_Cylinder"); MissionError saying where it looked."""
    folders = mission_folders() if search_path is None else list(search_path)
    found = find(MISSIONS, name, folders)
    if found is not None:
        return found
    looked = looked_at(candidates(MISSIONS, name, folders))
    raise MissionError(f"{name}: no such mission; looked at {looked}. Give a file path, or add the folder holding "
                       "<mission>/<submission>.json with --search-path or $MAGNA_MISSIONS_PATH")


def resolve_mission_path(mission: str, search_path: Iterable[Path] | None = None) -> Path:
    """A file path as it is when the file exists, else a name looked up with `find_mission`."""
    path = Path(mission)
    if path.is_file():
        return path
    try:
        return find_mission(mission, search_path)
    except MissionError as error:
        if mission.endswith(".json"):
            raise MissionError(f"{mission}: no such file (nor a mission of that name: "
                               f"{error.problems[0].split(': ', 1)[1]})") from None
        raise


def read_mission_json(path: Path, source: str):
    try:
        return read_json_document(Path(path))
    except UnreadableJson as err:
        raise MissionError(f"{source}: {err}") from None


def mission_from_data(data, source: str, validate: bool = True, airframe_dir: Path | None = None,
                      strict: bool = False) -> LoadedMission:
    """Migrate, parse and (by default) validate already-read JSON; MissionError lists every problem found.
    `strict`: the warnings (what the original tolerated and MAGNA works around) are problems too."""
    try:
        return _mission_from_data(data, source, validate, airframe_dir, strict)
    except RecursionError:  # containers inside containers, hundreds deep: the readers recurse per level
        raise MissionError(f"{source}: State_Machine: states are nested too deeply (hundreds of containers inside "
                           "each other); no mission needs that many levels: check how the file was made") from None


def _mission_from_data(data, source: str, validate: bool, airframe_dir: Path | None, strict: bool) -> LoadedMission:
    migration = migrate(data)
    parsed = parse_mission(migration, source, airframe_dir)
    loaded = LoadedMission(parsed.mission, list(migration.changes), list(parsed.warnings))
    problems = list(parsed.problems)
    if validate and parsed.complete:  # with a node missing, its siblings' transitions would fail for nothing
        from magna_gs.mission.validate import validate_mission

        report = validate_mission(parsed.mission)
        problems += report.problems
        loaded.warnings += report.warnings
        loaded.plan = report.plan
    if strict:
        problems += [f"{warning} {STRICT_NOTE}" for warning in loaded.warnings]
    if problems:
        raise MissionError(problems)
    return loaded


def load_mission(path, validate: bool = True, airframe_dir: Path | None = None,
                 strict: bool = False) -> LoadedMission:
    """Load a mission file (either schema); MissionError lists every problem, each with file and JSON path.
    `strict=True` refuses what would otherwise be a warning (for authors of new files; `--strict`)."""
    source = str(path)
    return mission_from_data(read_mission_json(Path(path), source), source, validate, airframe_dir, strict)
