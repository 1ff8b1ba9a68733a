"""The world and the mission of a run: found by name or path, loaded and checked before anything starts.

    inputs = resolve_inputs("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [corpus])
    inputs.world_file, inputs.mission_file, inputs.worlds_path

Each spec is a name (WORLD/SUBWORLD, MISSION/SUBMISSION), looked up along magna_common.search_path,
or the path of a .json file (its folder names the world or the mission). `magna run`, `magna port`
and `mlr fly` start from here; every problem is an `InputError` saying what and the fix.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from magna_common.errors import UserError
from magna_common.search_path import (
    check_search_dirs,
    find_world_file,
    mission_folders,
    world_candidates,
    world_folders,
)
from magna_gs.mission.loader import find_mission, load_mission
from magna_gs.mission.model import MissionError
from magna_gs.mission.world_check import check_in_world
from magna_worlds.errors import WorldError
from magna_worlds.loader import load_world_checked


class InputError(UserError):
    """A world or a mission that cannot be found or does not load; nothing has started (exit status 2)."""


@dataclass(frozen=True)
class Inputs:
    world: str
    subworld: str
    mission: str
    submission: str
    world_file: Path
    mission_file: Path

    @property
    def worlds_path(self) -> Path:
        """The folder that holds <world>/<subworld>.json (simulation.launch's worlds_path)."""
        return self.world_file.parent.parent


def split_spec(value: str, what: str, example: str) -> tuple[str, str]:
    """'Gym/1Obs_Central_Cylinder' -> ('Gym', '1Obs_Central_Cylinder'); a trailing .json is dropped."""
    parts = value.strip().removesuffix(".json").split("/")
    if len(parts) != 2 or not all(p.strip() for p in parts) or any(p in (".", "..") for p in parts):
        raise InputError(f"--{what} {value!r}: expected {what.upper()}/SUB{what.upper()}, e.g. {example}")
    return parts[0], parts[1]


def _as_file(spec: str) -> Path | None:
    """A --world/--mission value that is a path to an existing .json file (its folder names the world/mission)."""
    path = Path(spec).expanduser()
    return path if spec.endswith(".json") and path.is_file() else None


def resolve_inputs(world_spec: str, mission_spec: str, search_dirs: Sequence[Path] = (), check: bool = True,
                   strict: bool = False) -> Inputs:
    """Find and (with `check`) load the world and the mission (`strict`: refuse what only warns); InputError
    names what was searched."""
    try:
        check_search_dirs(search_dirs)
    except UserError as err:
        raise InputError(str(err)) from None
    world_search = world_folders(search_dirs)
    world_file = _as_file(world_spec)
    if world_file is not None:
        world, subworld = world_file.resolve().parent.name, world_file.stem
    else:
        world, subworld = split_spec(world_spec, "world", "Gym/1Obs_Central_Cylinder")
        world_file = find_world_file(world, subworld, world_search)
        if world_file is None:
            raise InputError(f"world {world}/{subworld} not found; looked at "
                             f"{world_candidates(world, subworld, world_search)}. "
                             "Fix --world WORLD/SUBWORLD or add the folder holding it with --search-path DIR")
    mission_file = _as_file(mission_spec)
    if mission_file is not None:
        mission, submission = mission_file.resolve().parent.name, mission_file.stem
    else:
        mission, submission = split_spec(mission_spec, "mission", "Gym/2UAVs_2paths_Central_Cylinder")
        mission_file = find_mission_file(mission, submission, search_dirs)
    inputs = Inputs(world, subworld, mission, submission, world_file.resolve(), mission_file.resolve())
    if check:
        check_inputs(inputs, world_search, strict)
    return inputs


def find_mission_file(mission: str, submission: str, search_dirs: Sequence[Path] = ()) -> Path:
    """The file of MISSION/SUBMISSION; InputError naming every place looked at."""
    try:
        return Path(find_mission(f"{mission}/{submission}", mission_folders(search_dirs)))
    except MissionError as err:
        raise InputError(f"mission {' '.join(str(err).split())}") from None


def check_inputs(inputs: Inputs, world_search: Sequence[Path], strict: bool = False) -> None:
    """Load the world and the mission, and check the mission in the world, so bad files stop the run before it
    starts: what the ground station would refuse is refused now. With `strict`, what would be a warning (what
    the original tolerated) stops it too."""
    try:
        world = load_world_checked(inputs.world_file, search_path=world_search, strict=strict)
    except WorldError as err:
        raise InputError(" ".join(str(err).split())) from None
    try:
        loaded = load_mission(inputs.mission_file, strict=strict)
    except MissionError as err:
        raise InputError(_first_of(err.problems)) from None
    problems = check_in_world(loaded.mission, world.resolved, search_path=world_search, strict=strict).problems
    if problems:
        raise InputError(_first_of(problems) + f"; in the world {inputs.world_file}")


def _first_of(problems: Sequence[str]) -> str:
    more = f" (and {len(problems) - 1} more problem(s))" if len(problems) > 1 else ""
    return " ".join(problems[0].split()) + more
