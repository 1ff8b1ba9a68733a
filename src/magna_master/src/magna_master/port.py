"""Porting report: walk a folder of ROS-MAGNA worlds and missions, pair them, and say what loads.

    report = port_folder(Path("my_lab/Code/JSONs"))
    print(format_report(report))

A folder is read the way the original laid it out: worlds in `Worlds/<family>/<name>.json`
and missions in `Missions/<family>/<name>.json` (lower-case `worlds/`, `missions/` too, or
the folder itself when it holds both kinds). Each file is loaded through the same steps
`magna world check` and `magna mission check` take, so what this report says a file does
is what `magna run` will do with it.

A mission is paired with one world whose volumes and geometries hold every place the
mission names (spawn poses, paths). Several worlds may qualify; they are preferred in this
order: the world of the mission's own family with the mission's name; then worlds of its
family before others, and worlds of a family named in the mission's family (LPS for
TestCrazyflieLPS) before the rest; among those, the world more of whose name's words the mission's
name contains (the original named missions after their world: 1UAVs_cropfield_inspection
flies in CropField, 1FW in Complete_FW); then, for a mission that flies a fixed wing, the
roomiest world (it loiters and lands over hundreds of metres); then the smallest world (the
original flew its family-less missions in Empty worlds), and of equally small ones the
roomiest. The first of those in which the mission validates without a warning is its pair
(else the first in which it validates). A mission no world can hold is listed, but is not a
pair.

Nothing here starts ROS: flying the pairs is `fly_pairs`, which runs one `magna run`
simulation each through the batch Master.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the loaders are imported where they are used, not with this module
    from magna_gs.mission.loader import LoadedMission
    from magna_worlds.generate import ResolvedWorld
    from magna_worlds.model import World

WORLD_FOLDERS = ("Worlds", "worlds")
MISSION_FOLDERS = ("Missions", "missions")


class PortError(ValueError):
    """The folder cannot be read as a tree of worlds and missions."""


@dataclass
class FileReport:
    """What happened to one file."""

    path: Path
    label: str  # family/name, as `magna run --world/--mission` takes it
    kind: str  # "world" or "mission"
    changes: list[str] = field(default_factory=list)  # what the migration of an older schema changed
    warnings: list[str] = field(default_factory=list)  # tolerated, as the original did
    problems: list[str] = field(default_factory=list)  # refusals: the file cannot be used as it is
    # missions only
    world: FileReport | None = None  # the paired world
    pair_problems: list[str] = field(default_factory=list)  # refusals of the mission in its world
    pair_warnings: list[str] = field(default_factory=list)  # what the original tolerated of it in its world
    flight: str | None = None  # the outcome when flown, "success" when it succeeded
    flight_message: str = ""

    @property
    def loads(self) -> bool:
        return not self.problems

    @property
    def paired(self) -> bool:
        return self.world is not None

    @property
    def validates(self) -> bool:
        return self.loads and self.paired and not self.pair_problems

    @property
    def flew(self) -> bool:
        return self.flight == "success"


@dataclass
class PortReport:
    folder: Path
    worlds: list[FileReport]
    missions: list[FileReport]
    strict: bool = False

    @property
    def pairs(self) -> list[FileReport]:
        return [m for m in self.missions if m.paired]

    @property
    def refused(self) -> bool:
        """Any file refused, or any pair that does not validate: the exit status says so."""
        return any(not w.loads for w in self.worlds) or any(not m.loads or (m.paired and not m.validates)
                                                            for m in self.missions)


# --- finding the files --------------------------------------------------------------------------------------------

def discover(folder: Path) -> tuple[list[Path], list[Path], Path | None]:
    """(world files, mission files, the worlds root) under `folder`; PortError when it holds neither."""
    folder = Path(folder).expanduser()
    if not folder.is_dir():
        raise PortError(f"{folder}: no such folder; give the folder holding Worlds/ and Missions/ (the original's "
                        "Code/JSONs)")
    worlds_root = next((folder / name for name in WORLD_FOLDERS if (folder / name).is_dir()), None)
    missions_root = next((folder / name for name in MISSION_FOLDERS if (folder / name).is_dir()), None)
    worlds = sorted(worlds_root.rglob("*.json")) if worlds_root else []
    missions = sorted(missions_root.rglob("*.json")) if missions_root else []
    if worlds_root is None and missions_root is None:  # a flat folder: tell the kinds apart by their content
        for path in sorted(folder.rglob("*.json")):
            kind = _kind_of(path)
            if kind == "world":
                worlds.append(path)
            elif kind == "mission":
                missions.append(path)
        worlds_root = folder
    if not worlds and not missions:
        raise PortError(f"{folder}: no world or mission files found; a world file has \"scenario\", a mission "
                        "\"State_Machine\" (looked in Worlds/ and Missions/, else in every *.json below)")
    return worlds, missions, worlds_root


def _kind_of(path: Path) -> str:
    import json

    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return ""
    if isinstance(data, dict) and "scenario" in data:
        return "world"
    if isinstance(data, dict) and "State_Machine" in data:
        return "mission"
    return ""


def _label(path: Path) -> str:
    return f"{path.parent.name}/{path.stem}"


# --- loading ------------------------------------------------------------------------------------------------------

@dataclass
class _World:
    report: FileReport
    model: World | None = None
    resolved: ResolvedWorld | None = None  # laid out once
    places: set[tuple[str, str]] = field(default_factory=set)  # (volume, geometry or "volume")


def check_world(path: Path, search_path: Iterable[Path], strict: bool = False, seed: int = 0) -> _World:
    from magna_worlds.errors import WorldError
    from magna_worlds.loader import load_world_checked

    report = FileReport(Path(path), _label(Path(path)), "world")
    try:
        checked = load_world_checked(path, search_path=list(search_path), strict=strict, seed=seed)
    except WorldError as error:
        report.problems.append(" ".join(str(error).split()))
        return _World(report)
    report.changes, report.warnings = list(checked.changes), list(checked.warnings)
    places = set()
    for volume in checked.world.volumes:
        places.add((volume.name, "volume"))
        places |= {(volume.name, geometry.name) for geometry in volume.geometries}
    return _World(report, checked.world, checked.resolved, places)


@dataclass
class _Mission:
    report: FileReport
    loaded: LoadedMission | None = None
    places: set[tuple[str, str]] = field(default_factory=set)


def check_mission(path: Path, strict: bool = False) -> _Mission:
    from magna_gs.mission.loader import load_mission
    from magna_gs.mission.model import MissionError
    from magna_gs.mission.world_check import pose_definitions

    report = FileReport(Path(path), _label(Path(path)), "mission")
    try:
        loaded = load_mission(path, strict=strict)
    except MissionError as error:
        report.problems += [" ".join(p.split()) for p in error.problems]
        return _Mission(report)
    report.changes, report.warnings = list(loaded.changes), list(loaded.warnings)
    places = {(d.volume, d.geometry) for d in pose_definitions(loaded.mission)}
    return _Mission(report, loaded, places)


def candidate_worlds(mission: _Mission, worlds: list[_World]) -> list[_World]:
    """The loaded worlds that hold every place the mission names, preferred first (see the module doc)."""
    family, name = mission.report.path.parent.name, mission.report.path.stem
    assert mission.loaded is not None  # pair_mission asks only for a mission that loads
    holding = [w for w in worlds if w.model is not None and mission.places <= w.places]
    # a fixed wing cannot hover: it needs room to loiter and to land, so room comes before size for it
    fixed_wing = any(agent.airframe.is_fixed_wing for agent in mission.loaded.mission.agents)

    def preference(world: _World):
        assert world.model is not None  # one of `holding`
        same_family = world.report.path.parent.name == family
        size = sum(1 + len(v.geometries) for v in world.model.volumes)
        return (not (same_family and world.report.path.stem == name), not same_family,
                -_shared_words(world.report.path.parent.name, family), -_shared_words(world.report.path.stem, name),
                -_room(world.model) if fixed_wing else 0.0, size, -_room(world.model), world.report.label)

    return sorted(holding, key=preference)


def _room(world) -> float:
    """The volume inside the world's boundaries (m^3): between equally small worlds, the roomier one (a fixed wing
    needs hundreds of metres to loiter and land; Empty/Empty holds it, a 200 m gym does not)."""
    import numpy as np

    bounds = np.asarray(world.boundaries, dtype=float)
    spans = bounds[:, 1] - bounds[:, 0]
    return float(np.prod(spans)) if np.isfinite(spans).all() else 0.0


def _shared_words(world_name: str, mission_name: str) -> int:
    """How many words of the world's name the mission's name contains: the original named missions after the
    world they fly in (1UAVs_cropfield_inspection in CropField, 1FW in Complete_FW)."""
    words = re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+", world_name)  # numbers say little: 1Obs is not 1UAVs
    flat = re.sub(r"[^a-z0-9]", "", mission_name.lower())
    return sum(1 for word in words if word.lower() in flat)


def pair_mission(mission: _Mission, worlds: list[_World], search_path: Iterable[Path], seed: int = 0,
                 strict: bool = False) -> None:
    """Pick the mission's world and check the mission in it (sets report.world and report.pair_problems)."""
    from magna_gs.mission.world_check import check_in_world

    if mission.loaded is None:
        return
    # the first world in which the mission is clean, else the first in which it only warns, else the first
    best = None  # (rank, world, findings): rank 0 clean, 1 warnings only, 2 problems
    for world in candidate_worlds(mission, worlds):
        found = check_in_world(mission.loaded.mission, world.resolved, seed, search_path=list(search_path),
                               strict=strict)
        rank = 2 if found.problems else (1 if found.warnings else 0)
        if best is None or rank < best[0]:
            best = (rank, world, found)
        if rank == 0:
            break
    if best is not None:
        _, world, found = best
        mission.report.world = world.report
        mission.report.pair_problems = [" ".join(p.split()) for p in found.problems]
        mission.report.pair_warnings = [" ".join(w.split()) for w in found.warnings]


def port_folder(folder: Path, strict: bool = False, seed: int = 0,
                progress: Callable[[str], None] | None = None) -> PortReport:
    """Load every world and mission under `folder` and pair them (no flying)."""
    world_files, mission_files, worlds_root = discover(folder)
    from magna_common.search_path import world_folders

    search_path = [p for p in (worlds_root,) if p is not None] + world_folders()
    worlds = []
    for path in world_files:
        if progress:
            progress(f"world {_label(path)}")
        worlds.append(check_world(path, search_path, strict, seed))
    missions = []
    for path in mission_files:
        if progress:
            progress(f"mission {_label(path)}")
        mission = check_mission(path, strict)
        pair_mission(mission, worlds, search_path, seed, strict)
        missions.append(mission)
    return PortReport(Path(folder), [w.report for w in worlds], [m.report for m in missions], strict)


# --- flying -------------------------------------------------------------------------------------------------------

def fly_pairs(report: PortReport, make_config: Callable, run: Callable,
              progress: Callable[[int, int, FileReport], None] | None = None) -> None:
    """Fly each validated pair once: `make_config(mission_report)` gives the BatchConfig, `run(config)` the
    BatchResult (injected, so the report logic is tested without ROS). Sets `flight` on each mission flown."""
    pairs = [m for m in report.missions if m.validates]
    for index, mission in enumerate(pairs, 1):
        if progress:
            progress(index, len(pairs), mission)
        try:
            result = run(make_config(mission))
        except Exception as error:  # one pair that cannot start must not stop the report
            mission.flight, mission.flight_message = "not started", " ".join(str(error).split())
            continue
        simulations = list(result.simulations)
        if not simulations:
            mission.flight, mission.flight_message = "not run", "the batch ran no simulation"
        elif result.interrupted:
            mission.flight, mission.flight_message = "interrupted", simulations[-1].message
            break
        else:
            last = simulations[-1]
            mission.flight = "success" if last.success else (last.outcome or "failed")
            mission.flight_message = last.message


# --- the table ----------------------------------------------------------------------------------------------------

def _cell(value: bool | None, yes: str = "yes", no: str = "REFUSED") -> str:
    return "-" if value is None else (yes if value else no)


def format_report(report: PortReport, details: bool = True) -> str:
    """One table row per file, then (with `details`) what changed, what warns and what was refused, per file."""
    rows = [("file", "kind", "loads", "migrated", "warnings", "world", "validates", "flies")]
    flown = any(m.flight is not None for m in report.missions)
    for world in report.worlds:
        rows.append((world.label, "world", _cell(world.loads), str(len(world.changes)), str(len(world.warnings)),
                     "", "", ""))
    for mission in report.missions:
        validates = _cell(mission.validates) if mission.loads and mission.paired else "-"
        world_label = mission.world.label if mission.world else ("no world holds it" if mission.loads else "")
        flies = "-" if mission.flight is None else ("yes" if mission.flew else mission.flight)
        rows.append((mission.label, "mission", _cell(mission.loads), str(len(mission.changes)),
                     str(len(mission.warnings) + len(mission.pair_warnings)), world_label, validates,
                     flies if flown else ""))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    if details:
        for item in [*report.worlds, *report.missions]:
            notes = ([f"  migrated: {c}" for c in item.changes] + [f"  warning: {w}" for w in item.warnings]
                     + [f"  warning in {item.world.label}: {w}" for w in item.pair_warnings if item.world]
                     + [f"  refused: {p}" for p in item.problems] + [f"  refused in {item.world.label}: {p}"
                                                                      for p in item.pair_problems if item.world])
            if item.flight is not None and not item.flew:
                notes.append(f"  flight: {item.flight}: {item.flight_message}")
            if notes:
                lines += ["", f"{item.label} ({item.kind}, {item.path})", *notes]
    lines += ["", totals(report)]
    return "\n".join(lines)


def totals(report: PortReport) -> str:
    worlds_ok = sum(w.loads for w in report.worlds)
    missions_ok = sum(m.loads for m in report.missions)
    pairs = report.pairs
    line = (f"worlds loaded {worlds_ok} of {len(report.worlds)}; missions loaded {missions_ok} of "
            f"{len(report.missions)}; pairs validated {sum(m.validates for m in pairs)} of {len(pairs)}")
    if any(m.flight is not None for m in report.missions):
        line += f"; pairs flown to success {sum(m.flew for m in pairs)} of {len(pairs)}"
    unpaired = [m for m in report.missions if m.loads and not m.paired]
    if unpaired:
        line += f"; {len(unpaired)} mission(s) with no world that holds the places they name"
    return line


def as_json(report: PortReport) -> dict:
    def item(r: FileReport) -> dict:
        out = {"file": str(r.path), "label": r.label, "kind": r.kind, "loads": r.loads, "changes": r.changes,
               "warnings": r.warnings, "problems": r.problems}
        if r.kind == "mission":
            out.update(world=r.world.label if r.world else None, validates=r.validates,
                       pair_problems=r.pair_problems, pair_warnings=r.pair_warnings, flight=r.flight,
                       flight_message=r.flight_message)
        return out

    return {"folder": str(report.folder), "strict": report.strict, "totals": totals(report),
            "worlds": [item(w) for w in report.worlds], "missions": [item(m) for m in report.missions]}
