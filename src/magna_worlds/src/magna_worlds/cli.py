"""`magna world`: check a world and say what it holds, or draw it.

    magna world check WORLD [--search-path DIR ...] [--seed N] [--json] [--strict]
    magna world draw WORLD -o world.png [--search-path DIR ...] [--seed N] [--elev E] [--azim A] [--force]

WORLD is a world file, or a name WORLD/SUBWORLD looked up as `magna run` does: WORLD/SUBWORLD.json
in each --search-path DIR (its worlds/, DIR itself, its Worlds/), then in $MAGNA_WORLDS_PATH and
the project's worlds/ (magna_common.search_path). A bad world file gets one line on stderr,
`magna world: <file>: <json path>: <message>`, and exit status 2 (a `magna_common.errors.UsageError`,
printed by `run`); nothing is written. What the original ROS-MAGNA tolerated gets one line each on
stderr, `magna world: warning: <file>: <json path>: <what MAGNA does>`; `--strict` refuses it (exit 2).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

from magna_common.cli_vocabulary import OutputExists, add_force, add_output, add_search_path, check_output
from magna_common.errors import UsageError
from magna_common.search_path import check_search_dirs, find_world_file, world_candidates, world_folders

HELP = "check a world (a file or a WORLD/SUBWORLD name: load, lay out poses and obstacles, summarise) or draw it"

_LOOKUP = """\
WORLD is a world file or a name WORLD/SUBWORLD, looked up as WORLD/SUBWORLD.json in each
--search-path DIR (its worlds/, DIR itself, its Worlds/), then in $MAGNA_WORLDS_PATH and the
project's worlds/, as `magna run --world` does.
"""

_EPILOG = _LOOKUP + """
examples:
  ./magna world check Gym/Four_Cylinders
  ./magna world check worlds/SolarPlant/Panels.json --seed 3 --json
  ./magna world check Delivery/Delivery --search-path ../shared/ros_magna_corpus
  ./magna world draw Gym/Central_Obstacle_Torus -o /tmp/torus.png --force
"""

_CHECK_EPILOG = _LOOKUP + """
The summary lists the file, its format (an older format is migrated first: the changes
are listed), the worlds it includes, the boundaries, origin_geo, then per volume its
geometries (shape, tf frame, poses per pose-set type, obstacles), the totals and the
time taken. What the original tolerated (unknown fields, no world_boundaries, poses
outside them, ...) is loaded and reported as one warning each on stderr,
`magna world: warning: FILE: JSON.PATH: what MAGNA does`; --strict refuses it instead.
A bad file prints one line `magna world: FILE: JSON.PATH: message` and exits 2.

examples:
  ./magna world check Gym/Four_Cylinders
  ./magna world check worlds/Inspection/WindTurbine.json --seed 3
  ./magna world check Gym/1Obs_Central_Cylinder --search-path ../shared/ros_magna_corpus --json
  ./magna world check worlds/Tube/Random_Bricks.json --strict     # for authors: warnings are errors
"""

_DRAW_EPILOG = _LOOKUP + """
Geometries are drawn as translucent surfaces in their colour, obstacles as dark
solids, poses as dots (one colour per pose set), zigzags as lines with their start
marked. The view fits the content, with the same scale on every axis. An existing
picture is replaced only with --force.

examples:
  ./magna world draw worlds/SolarPlant/Panels.json -o /tmp/panels.png --force
  ./magna world draw Delivery/Delivery --search-path ../shared/ros_magna_corpus -o /tmp/delivery.png --force
  ./magna world draw Gym/Four_Cylinders -o /tmp/top.png --elev 90 --azim -90 --force   # seen from above
"""

_WORLD_HELP = "world file, or WORLD/SUBWORLD name (e.g. Gym/Four_Cylinders)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    sub = parser.add_subparsers(dest="world_command", metavar="ACTION", title="actions")
    sub.required = True

    check = sub.add_parser("check", help="load and lay out a world; print what it holds",
                           description="Load and lay out a world, then print what it holds.",
                           epilog=_CHECK_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    check.add_argument("file", metavar="WORLD", help=_WORLD_HELP)
    add_search_path(check, what="worlds")
    _seed(check)
    check.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    check.add_argument("--strict", action="store_true",
                       help="refuse what would be a warning (exit 2): for authors of new world files")
    check.set_defaults(_world_run=_check)

    draw = sub.add_parser("draw", help="draw a world to a PNG",
                          description="Draw a world (geometries, obstacles, poses) to a PNG picture.",
                          epilog=_DRAW_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    draw.add_argument("file", metavar="WORLD", help=_WORLD_HELP)
    add_output(draw, required=True, metavar="PNG", help="picture to write (PNG)")
    add_force(draw, help="replace PNG if it exists")
    add_search_path(draw, what="worlds")
    _seed(draw)
    draw.add_argument("--elev", type=float, default=25.0, metavar="DEG",
                      help="view elevation above the xy plane, degrees (default: %(default)s; 90: from above)")
    draw.add_argument("--azim", type=float, default=-60.0, metavar="DEG",
                      help="view azimuth about z, degrees (default: %(default)s)")
    draw.add_argument("--title", help="title over the picture (default: file name, seed and counts)")
    draw.set_defaults(_world_run=_draw)


def _seed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, metavar="N",
                        help="seed of the random pose sets and obstacles (default: %(default)s)")


def run(args) -> int:
    try:
        return args._world_run(args)
    except UsageError as error:
        print(f"magna world: {error}", file=sys.stderr)
        return 2


# --- finding and loading -------------------------------------------------------------------------------------------

def world_roots(search_dirs) -> list[Path]:
    """Where world names are looked up (magna_common.search_path, as `magna run` does); UsageError for a
    --search-path folder that does not exist."""
    check_search_dirs(search_dirs)
    return world_folders(search_dirs)


def find_world(spec: str, search_dirs=(), option: str = "") -> Path:
    """The world file `spec` names: an existing file as it is, else a name WORLD/SUBWORLD (a trailing .json
    dropped) looked up in `world_roots(search_dirs)`. UsageError naming every place looked at."""
    roots = world_roots(search_dirs)
    path = Path(spec).expanduser()
    if path.is_file():
        return path
    label = f"{option} {spec}" if option else spec
    parts = spec.strip().removesuffix(".json").split("/")
    if len(parts) != 2 or not all(p.strip() for p in parts) or any(p in (".", "..") for p in parts):
        raise UsageError(f"{label}: no such file; check the path, or give a world name WORLD/SUBWORLD "
                         "(e.g. Gym/Four_Cylinders)")
    world, subworld = parts
    found = find_world_file(world, subworld, roots)
    if found is None:
        raise UsageError(f"{label}: no such file, nor a world WORLD/SUBWORLD of that name; looked at "
                         f"{world_candidates(world, subworld, roots)}. Give a file path, or add the folder "
                         "holding it with --search-path DIR")
    return found


def _load(spec: str, seed: int, strict: bool = False, search_dirs=()):
    """(resolved world, load seconds, resolve seconds); a WorldError becomes a one-line usage error.
    Warnings go to stderr, one line each."""
    from magna_worlds.errors import WorldError
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import load_world

    path = find_world(spec, search_dirs)
    try:
        start = time.perf_counter()
        world = load_world(path, world_roots(search_dirs), strict=strict)  # includes: the same folders
        loaded = time.perf_counter()
        resolved = resolve_world(world, seed, strict=strict)
        done = time.perf_counter()
    except WorldError as error:
        raise UsageError(" ".join(str(error).split())) from None  # one line, whatever the message holds
    for warning in resolved.warnings:
        print(f"magna world: warning: {' '.join(warning.split())}", file=sys.stderr)
    return resolved, loaded - start, done - loaded


# --- check ----------------------------------------------------------------------------------------------------

def summary(resolved, load_seconds: float = 0.0, resolve_seconds: float = 0.0) -> dict:
    """What `check` reports, as JSON-ready data."""
    import numpy as np

    world = resolved.world
    volumes = []
    for volume in world.volumes:
        geometries = []
        for placed in (g for g in resolved.geometries if g.volume is volume):
            poses: Counter[str] = Counter()
            for pose_set in placed.poses():
                poses[pose_set.spec.type] += len(pose_set)
            geometries.append({
                "name": placed.geometry.name, "shape": placed.geometry.spec.shape, "frame": placed.frame_name,
                "poses": sum(poses.values()), "poses_by_type": dict(poses),
                "obstacles": len(placed.obstacles),
                "obstacles_by_shape": dict(Counter(o.shape for o in placed.obstacles)),
            })
        volumes.append({"name": volume.name, "prefix": volume.prefix, "permits": volume.permits,
                        "source": volume.source, "geometries": geometries})
    by_type: Counter[str] = Counter()
    for placed in resolved.geometries:
        for pose_set in placed.poses():
            by_type[pose_set.spec.type] += len(pose_set)
    boundaries = world.boundaries.tolist() if np.isfinite(world.boundaries).all() else None
    return {
        "file": world.source, "included": list(world.included), "seed": resolved.seed,
        "world_boundaries": boundaries, "origin_geo": list(world.origin_geo) if world.origin_geo else None,
        "volumes": volumes,
        "totals": {"volumes": len(world.volumes), "geometries": len(resolved.geometries),
                   "poses": resolved.pose_count(), "poses_by_type": dict(by_type),
                   "obstacles": len(resolved.obstacles()), "frames": len(resolved.static_transforms())},
        "load_ms": round(load_seconds * 1e3, 3), "generate_ms": round(resolve_seconds * 1e3, 3),
        "warnings": list(resolved.warnings), "changes": list(world.changes),
        "boundaries_defaulted": world.boundaries_defaulted,
    }


def _counts(by_type: dict) -> str:
    return " (" + ", ".join(f"{kind} {n}" for kind, n in by_type.items()) + ")" if by_type else ""


def format_summary(data: dict) -> str:
    changes = data.get("changes", [])
    lines = [f"file        {data['file']}",
             "format      " + (f"older format migrated to the current one: {len(changes)} change(s)" if changes
                              else "current (nothing to migrate)")]
    lines += [f"  {change}" for change in changes]
    lines.append(f"included    {', '.join(data['included']) if data['included'] else '(none)'}")
    if data["world_boundaries"] is None:
        lines.append("boundaries  (none)")
    else:
        (x0, x1), (y0, y1), (z0, z1) = data["world_boundaries"]
        made = " (not in the file: the box around its geometries)" if data.get("boundaries_defaulted") else ""
        lines.append(f"boundaries  x {x0:g}..{x1:g}  y {y0:g}..{y1:g}  z {z0:g}..{z1:g} m{made}")
    geo = data["origin_geo"]
    lines.append(f"origin_geo  {'(none)' if geo is None else f'lat {geo[0]:g}, lon {geo[1]:g}, alt {geo[2]:g} m'}")
    lines.append(f"seed        {data['seed']}")
    rows = [g for v in data["volumes"] for g in v["geometries"]]
    name_w = max([len(g["name"]) for g in rows] + [4])
    frame_w = max([len(g["frame"]) for g in rows] + [4])
    for volume in data["volumes"]:
        permits = f", permits {volume['permits']}" if volume["permits"] else ""
        source = f", from {volume['source']}" if volume["source"] != data["file"] else ""
        lines.append("")
        lines.append(f"volume {volume['name']} (prefix {volume['prefix']}{permits}{source})")
        if not volume["geometries"]:
            lines.append("  (no geometries)")
        for g in volume["geometries"]:
            lines.append(f"  {g['name']:<{name_w}}  {g['shape']:<8}  frame {g['frame']:<{frame_w}}  "
                         f"poses {g['poses']}{_counts(g['poses_by_type'])}  "
                         f"obstacles {g['obstacles']}{_counts(g['obstacles_by_shape'])}")
    t = data["totals"]
    lines.append("")
    geometries = f"{t['geometries']} geometr{'y' if t['geometries'] == 1 else 'ies'}"
    lines.append(f"totals      {t['volumes']} volume(s), {geometries}, "
                 f"{t['poses']} pose(s){_counts(t['poses_by_type'])}, {t['obstacles']} obstacle(s), "
                 f"{t['frames']} tf frame(s)")
    lines.append(f"time        loaded in {data['load_ms']:.1f} ms, generated in {data['generate_ms']:.1f} ms")
    if data["warnings"]:
        lines.append(f"warnings    {len(data['warnings'])} (what the original tolerated; listed on stderr)")
    return "\n".join(lines)


def _check(args) -> int:
    resolved, load_seconds, resolve_seconds = _load(args.file, args.seed, args.strict, args.search_path)
    data = summary(resolved, load_seconds, resolve_seconds)
    print(json.dumps(data, indent=2) if args.json else format_summary(data))
    return 0


# --- draw -----------------------------------------------------------------------------------------------------

def _draw(args) -> int:
    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise UsageError(f"-o {output}: the picture is a PNG; name it *.png")
    if not output.parent.is_dir():
        raise UsageError(f"-o {output}: folder {output.parent} does not exist; create it first")
    try:  # before any work: nothing is drawn for nothing
        check_output(output, args.force)
    except OutputExists as error:
        raise UsageError(str(error)) from None
    resolved, _, _ = _load(args.file, args.seed, search_dirs=args.search_path)

    from magna_worlds.draw import draw_world  # matplotlib: only when drawing

    try:
        draw_world(resolved, output, elev=args.elev, azim=args.azim, title=args.title, overwrite=args.force)
    except FileExistsError as error:  # appeared while drawing
        raise UsageError(str(error)) from None
    except OSError as error:
        raise UsageError(f"{output}: cannot write it: {error.strerror or error}") from None
    print(output)
    return 0
