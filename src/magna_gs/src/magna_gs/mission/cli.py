"""`magna mission`: check a mission file (structure, and against a world), or draw its state machine.

    magna mission check MISSION [--world WORLD] [--search-path DIR ...] [--seed N] [--strict]
    magna mission draw MISSION -o mission.png [--search-path DIR ...] [--title T] [--force]

MISSION and WORLD are files, or names as the hyperparameters give them
(`Gym/2UAVs_2paths_Central_Cylinder`, `Gym/1Obs_Central_Cylinder`). Every problem is one
line on stderr, `magna mission: <file>: <JSON path>: <message>`, and the exit status is 2;
nothing is written.
"""
from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

HELP = "check a mission file (structure, and against a world) or draw its state machine"

_EPILOG = """\
examples:
  magna mission check Gym/2UAVs_2paths_Central_Cylinder --world Gym/1Obs_Central_Cylinder \\
      --search-path ../shared/ros_magna_corpus
  magna mission check missions/Gym/Two_Paths.json --world worlds/Gym/Four_Cylinders.json --seed 3
  magna mission draw Delivery/2UAVs_follow_ap_safe --search-path ../shared/ros_magna_corpus -o delivery.png
"""

_CHECK_EPILOG = """\
The mission is loaded (a legacy file is migrated first: the changes are listed),
validated (states, transitions with the {id}_{name} naming, outcome maps, callbacks,
agent ids, follow targets, ...) and its state machine built and checked. With --world,
every pose definition (spawn poses, paths) is resolved in that world as the world node
will, without spawning anything. Warnings go to stderr; problems are one line each on
stderr, `magna mission: FILE: JSON.PATH: message`, and exit 2.

A warning is something the original ROS-MAGNA tolerated and MAGNA works around (it says
how): a safety branch naming a UAV the mission does not configure, an outcome-map entry
that can never match, an ID given twice, a key nothing reads, ... --strict refuses them
(exit 2), for authors of new files.

Names are looked up as <dir>/<mission>/<submission>.json (and <dir>/Missions/...) in
each --search-path DIR, then $MAGNA_MISSIONS_PATH, then missions/; worlds as
<dir>/<world>/<subworld>.json (and <dir>/Worlds/...) in each --search-path DIR, then
$MAGNA_WORLDS_PATH, then worlds/.

examples:
  magna mission check Gym/2UAVs_2paths_Central_Cylinder --search-path ../shared/ros_magna_corpus
  magna mission check Delivery/2UAVs_follow_ad_safe --world Delivery/Delivery --search-path ../shared/ros_magna_corpus
"""

_DRAW_EPILOG = """\
The machine is built with states that never run and drawn with magna_sm's graphviz
drawing: containers as clusters, container outcomes as red boxes, initial states with
a bold border. The format follows the suffix: .png, .svg, .pdf or .dot.

examples:
  magna mission draw Gym/2UAVs_2paths_Central_Cylinder --search-path ../shared/ros_magna_corpus -o gym.png
  magna mission draw missions/Gym/Two_Paths.json -o two_paths.svg --force
"""

DRAW_FORMATS = (".png", ".svg", ".pdf", ".dot")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    sub = parser.add_subparsers(dest="mission_command", metavar="ACTION", title="actions")
    sub.required = True

    check = sub.add_parser("check", help="load, validate and build a mission; check it against a world",
                           description="Load, validate and build a mission; with --world, resolve its poses there.",
                           epilog=_CHECK_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    _mission(check)
    check.add_argument("--world", metavar="WORLD",
                       help="world file or <world>/<subworld> name to resolve the mission's poses in")
    check.add_argument("--seed", type=int, default=0, metavar="N",
                       help="seed of the world's random pose sets and of random queries (default: %(default)s)")
    check.add_argument("--strict", action="store_true",
                       help="refuse what would only be a warning (what the original tolerated): for new files")
    check.set_defaults(_mission_run=_check)

    draw = sub.add_parser("draw", help="draw a mission's state machine",
                          description="Draw a mission's state machine (graphviz) to a picture.",
                          epilog=_DRAW_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    _mission(draw)
    draw.add_argument("-o", "--output", required=True, metavar="FILE",
                      help=f"picture to write ({', '.join(DRAW_FORMATS)} by its suffix)")
    draw.add_argument("--title", help="title over the picture (default: the mission file and its state count)")
    draw.add_argument("--force", action="store_true", help="overwrite FILE if it exists")
    draw.set_defaults(_mission_run=_draw)


def _mission(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mission", metavar="MISSION",
                        help="mission file, or <mission>/<submission> name (e.g. Gym/2UAVs_2paths_Central_Cylinder)")
    parser.add_argument("--search-path", action="append", default=[], type=Path, metavar="DIR",
                        help="folder to look names up in, before $MAGNA_MISSIONS_PATH / $MAGNA_WORLDS_PATH and the "
                             "project's missions/ and worlds/ (repeatable; a ROS-MAGNA tree with Missions/ and "
                             "Worlds/ works too)")


class _Problems(Exception):
    """Problems to print one per line (exit 2)."""

    def __init__(self, lines: list[str]):
        super().__init__("\n".join(lines))
        self.lines = lines


def run(args) -> int:
    from magna_master.cli import UsageError

    try:
        return args._mission_run(args)
    except _Problems as problems:
        for line in problems.lines:
            print(f"magna mission: {line}", file=sys.stderr)
        return 2
    except UsageError as error:
        # printed here, not by magna_master.cli.main: under `python -m magna_master.cli` that module's
        # UsageError is another class than the one imported here (as in magna_worlds.cli)
        print(f"magna mission: {error}", file=sys.stderr)
        return 2


# --- loading ---------------------------------------------------------------------------------------------------

def _load(args):
    from magna_gs.mission.loader import load_mission, resolve_mission_path
    from magna_gs.mission.model import MissionError

    folders = [*args.search_path, *_default_missions()]
    try:
        path = resolve_mission_path(args.mission, folders)
        return load_mission(path, strict=getattr(args, "strict", False))
    except MissionError as error:
        raise _Problems([" ".join(p.split()) for p in error.problems]) from None


def _default_missions() -> list[Path]:
    from magna_gs.mission.loader import default_search_path

    return default_search_path()


def _world_file(name: str, folders: list[Path]) -> Path:
    from magna_master.cli import UsageError
    from magna_worlds.loader import default_search_path, find_world_file

    path = Path(name)
    if path.is_file():
        return path
    relative = name[:-5] if name.endswith(".json") else name
    world, _, subworld = relative.rpartition("/")
    roots = [*folders, *default_search_path()]
    roots = [r for folder in roots for r in (Path(folder), Path(folder) / "Worlds")]
    found = find_world_file(world, subworld, roots) if world and subworld else None
    if found is None:
        looked = ", ".join(str(r / f"{relative}.json") for r in roots)
        raise UsageError(f"--world {name}: no such file, nor a world <world>/<subworld> of that name; looked at "
                         f"{looked}")
    return found


# --- check -----------------------------------------------------------------------------------------------------

def summary(loaded, world_line: str = "") -> str:
    """What `check` prints about a loaded (and validated) mission."""
    mission, plan = loaded.mission, loaded.plan
    states = [s for s in plan.root.walk() if s.node is not None]
    by_kind = Counter(s.kind for s in states)
    by_type: dict[str, Counter] = {kind: Counter() for kind in ("SimpleActionState", "CBState")}
    for state in states:
        if state.kind in by_type:
            by_type[state.kind][state.state_type] += 1
    kinds = []
    for kind in ("SimpleActionState", "CBState", "StateMachine", "Concurrence", "Sequence"):
        if by_kind[kind]:
            detail = ", ".join(f"{t} {n}" for t, n in sorted(by_type[kind].items())) if kind in by_type else ""
            kinds.append(f"{kind} {by_kind[kind]}" + (f" ({detail})" if detail else ""))
    agents = ", ".join(f"{a.id} ({a.model}, {a.mode})" for a in mission.agents)
    lines = [f"file        {mission.source}",
             f"schema      {_schema(loaded.changes)}"]
    lines += [f"  {change}" for change in loaded.changes]
    lines += [f"agents      {len(mission.agents)}: {agents}",
              f"states      {len(mission.root)} written at the top level, {len(states)} after expansion",
              *[f"  {k}" for k in kinds],
              f"outcomes    {', '.join(plan.outcomes)}",
              f"warnings    {len(loaded.warnings)}" + (" (on stderr)" if loaded.warnings else "")]
    if world_line:
        lines.append(world_line)
    return "\n".join(lines)


def _schema(changes: list[str]) -> str:
    if not changes:
        return "current (nothing to migrate)"
    return f"legacy parts migrated to the current schema: {len(changes)} change(s)"


def _check(args) -> int:
    from magna_gs.mission.build import InertFactory, build_machine

    loaded = _load(args)
    build_machine(loaded.mission, InertFactory(), loaded.plan)  # magna_sm validates the machine it would run
    for warning in loaded.warnings:
        print(f"magna mission: warning: {' '.join(warning.split())}", file=sys.stderr)
    world_line, problems = "", []
    if args.world:
        world_line, problems = _check_world(loaded.mission, args)
    print(summary(loaded, world_line))
    if problems:
        raise _Problems(problems)
    return 0


def _check_world(mission, args) -> tuple[str, list[str]]:
    from magna_gs.mission.world_check import check_in_world, pose_definitions
    from magna_worlds.errors import WorldError
    from magna_worlds.loader import load_world_checked

    strict = getattr(args, "strict", False)
    path = _world_file(args.world, args.search_path)
    try:
        checked = load_world_checked(path, [*args.search_path, *_world_roots(args.search_path)], strict=strict,
                                     seed=args.seed)
    except WorldError as error:
        raise _Problems([" ".join(str(error).split())]) from None
    found = check_in_world(mission, checked.resolved, args.seed, strict=strict)
    for warning in [*checked.warnings, *found.warnings]:
        print(f"magna mission: warning: {' '.join(warning.split())}", file=sys.stderr)
    problems = [" ".join(p.split()) for p in found.problems]
    count = len(pose_definitions(mission))
    verdict = f"{count} pose definition(s) resolve" if not problems else f"{len(problems)} problem(s) (on stderr)"
    return f"world       {path} (seed {args.seed}): {verdict}", problems


def _world_roots(folders: list[Path]) -> list[Path]:
    from magna_worlds.loader import default_search_path

    return [*(Path(f) / "Worlds" for f in folders), *default_search_path()]


# --- draw ------------------------------------------------------------------------------------------------------

def _draw(args) -> int:
    from magna_master.cli import UsageError

    output = Path(args.output)
    if output.suffix.lower() not in DRAW_FORMATS:
        raise UsageError(f"-o {output}: unknown picture format '{output.suffix}'; name it *.png, *.svg, *.pdf or *.dot")
    if not output.parent.is_dir():
        raise UsageError(f"-o {output}: folder {output.parent} does not exist; create it first")
    if output.exists() and not args.force:  # before any work: nothing is drawn for nothing
        raise UsageError(f"{output}: already exists; pass --force to overwrite it")
    loaded = _load(args)

    from magna_gs.mission.build import InertFactory, build_machine
    from magna_sm.draw import DrawError, draw

    machine = build_machine(loaded.mission, InertFactory(), loaded.plan)
    count = sum(1 for s in loaded.plan.root.walk() if s.node is not None)
    title = args.title if args.title is not None else f"{loaded.mission.source} ({count} states)"
    try:
        draw(machine, output, title=title, show_active=False)
    except DrawError as error:
        raise UsageError(str(error)) from None
    except OSError as error:
        raise UsageError(f"{output}: cannot write it: {error.strerror or error}") from None
    print(output)
    return 0
