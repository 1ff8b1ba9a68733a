"""`magna mission`: check a mission (structure, and against a world), or draw its state machine.

    magna mission check MISSION [--world WORLD] [--search-path DIR ...] [--seed N] [--strict]
    magna mission draw MISSION -o mission.png [--search-path DIR ...] [--title T] [--force]

MISSION and WORLD are files, or names as `magna run` takes them (`Gym/2UAVs_2paths_Central_Cylinder`,
`Gym/1Obs_Central_Cylinder`), looked up as `magna run` does. Every problem is one line on stderr,
`magna mission: <file>: <JSON path>: <message>`, and the exit status is 2; nothing is written.
"""
from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

from magna_common import search_path
from magna_common.cli_vocabulary import OutputExists, add_force, add_output, add_search_path, check_output
from magna_common.errors import UsageError

HELP = "check a mission (a file or a MISSION/SUBMISSION name; structure, and against a world) or draw it"

_LOOKUP = """\
MISSION is a mission file or a name MISSION/SUBMISSION, looked up as MISSION/SUBMISSION.json in
each --search-path DIR (its missions/, DIR itself, its Missions/), then $MAGNA_MISSIONS_PATH, then
the project's missions/. WORLD likewise: a file or WORLD/SUBWORLD, in each DIR's worlds/, DIR
itself and its Worlds/, then $MAGNA_WORLDS_PATH and the project's worlds/. `magna run` looks them
up the same way (magna_common.search_path).
"""

_EPILOG = _LOOKUP + """
examples:
  ./magna mission check Gym/2UAVs_Crossing_ORCA --world Gym/Central_Obstacle_Torus
  ./magna mission check Gym/2UAVs_2paths_Central_Cylinder --world Gym/1Obs_Central_Cylinder \\
      --search-path ../shared/ros_magna_corpus
  ./magna mission draw missions/Gym/Safe_Stop.json -o /tmp/safe_stop.png --force
"""

_CHECK_EPILOG = _LOOKUP + """
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

examples:
  ./magna mission check missions/Gym/Safe_Stop.json --strict
  ./magna mission check Gym/2UAVs_2paths_Central_Cylinder --search-path ../shared/ros_magna_corpus
  ./magna mission check Delivery/2UAVs_follow_ad_safe --world Delivery/Delivery \\
      --search-path ../shared/ros_magna_corpus
"""

_DRAW_EPILOG = _LOOKUP + """
The machine is built with states that never run and drawn with magna_sm's graphviz
drawing: containers as clusters, container outcomes as red boxes, initial states with
a bold border. The format follows the suffix: .png, .svg, .pdf or .dot. An existing
picture is replaced only with --force.

examples:
  ./magna mission draw Gym/2UAVs_Crossing_ORCA -o /tmp/crossing.svg --force
  ./magna mission draw Gym/2UAVs_2paths_Central_Cylinder --search-path ../shared/ros_magna_corpus \\
      -o /tmp/two_paths.png --force
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
                       help="world file or WORLD/SUBWORLD name to resolve the mission's poses in")
    check.add_argument("--seed", type=int, default=0, metavar="N",
                       help="seed of the world's random pose sets and of random queries (default: %(default)s)")
    check.add_argument("--strict", action="store_true",
                       help="refuse what would only be a warning (what the original tolerated): for new files")
    check.set_defaults(_mission_run=_check)

    draw = sub.add_parser("draw", help="draw a mission's state machine",
                          description="Draw a mission's state machine (graphviz) to a picture.",
                          epilog=_DRAW_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    _mission(draw)
    add_output(draw, required=True, metavar="FILE",
               help=f"picture to write ({', '.join(DRAW_FORMATS)} by its suffix)")
    add_force(draw, help="replace FILE if it exists")
    draw.add_argument("--title", help="title over the picture (default: the mission file and its state count)")
    draw.set_defaults(_mission_run=_draw)


def _mission(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("mission", metavar="MISSION",
                        help="mission file, or MISSION/SUBMISSION name (e.g. Gym/2UAVs_Crossing_ORCA)")
    add_search_path(parser, what="missions and worlds")


class _Problems(Exception):
    """Problems to print one per line (exit 2)."""
    def __init__(self, lines: list[str]):
        super().__init__("\n".join(lines))
        self.lines = lines


def run(args) -> int:
    try:
        return args._mission_run(args)
    except _Problems as problems:
        for line in problems.lines:
            print(f"magna mission: {line}", file=sys.stderr)
        return 2
    except UsageError as error:
        print(f"magna mission: {error}", file=sys.stderr)
        return 2


# --- loading ---------------------------------------------------------------------------------------------------

def mission_folders(search_dirs) -> list[Path]:
    """Where mission names are looked up (magna_common.search_path, as `magna run` does); UsageError for a
    --search-path folder that does not exist."""
    search_path.check_search_dirs(search_dirs)
    return search_path.mission_folders(search_dirs)


def _load(args):
    from magna_gs.mission.loader import load_mission, resolve_mission_path
    from magna_gs.mission.model import MissionError

    folders = mission_folders(args.search_path)
    try:
        path = resolve_mission_path(args.mission, folders)
        return load_mission(path, strict=getattr(args, "strict", False))
    except MissionError as error:
        raise _Problems([" ".join(p.split()) for p in error.problems]) from None


def _world_file(name: str, search_dirs: list[Path]) -> Path:
    from magna_worlds.cli import find_world

    return find_world(name, search_dirs, option="--world")


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
    world_line, problems = "", list[str]()
    if args.world:
        world_line, problems = _check_world(loaded.mission, args)
    print(summary(loaded, world_line))
    if problems:
        raise _Problems(problems)
    return 0


def _check_world(mission, args) -> tuple[str, list[str]]:
    from magna_gs.mission.world_check import check_in_world, pose_definitions
    from magna_worlds.cli import world_roots
    from magna_worlds.errors import WorldError
    from magna_worlds.loader import load_world_checked

    strict = getattr(args, "strict", False)
    path = _world_file(args.world, args.search_path)
    try:
        checked = load_world_checked(path, world_roots(args.search_path), strict=strict, seed=args.seed)
    except WorldError as error:
        raise _Problems([" ".join(str(error).split())]) from None
    found = check_in_world(mission, checked.resolved, args.seed, strict=strict)
    for warning in [*checked.warnings, *found.warnings]:
        print(f"magna mission: warning: {' '.join(warning.split())}", file=sys.stderr)
    problems = [" ".join(p.split()) for p in found.problems]
    count = len(pose_definitions(mission))
    verdict = f"{count} pose definition(s) resolve" if not problems else f"{len(problems)} problem(s) (on stderr)"
    return f"world       {path} (seed {args.seed}): {verdict}", problems


# --- draw ------------------------------------------------------------------------------------------------------

def _draw(args) -> int:
    output = Path(args.output)
    if output.suffix.lower() not in DRAW_FORMATS:
        raise UsageError(f"-o {output}: unknown picture format '{output.suffix}'; name it *.png, *.svg, *.pdf or *.dot")
    if not output.parent.is_dir():
        raise UsageError(f"-o {output}: folder {output.parent} does not exist; create it first")
    try:  # before any work: nothing is drawn for nothing
        check_output(output, args.force)
    except OutputExists as error:
        raise UsageError(str(error)) from None
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
