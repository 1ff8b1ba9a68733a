"""rosrun magna_viz rviz_world: rviz with the configuration of a world's family, its camera fitted to the world.

    rosrun magna_viz rviz_world --world Gym [--subworld Central_Obstacle_Torus] [--worlds-path DIR]
                                [--config FILE] [--seed N]
    rosrun magna_viz rviz_world --sim-dir SIMULATION_FOLDER [--config FILE]

The configuration (magna_viz/rviz/<family>.rviz, or --config) is copied to
$ROS_HOME/magna_viz/<live_WORLD_SUBWORLD or replay_SIMULATION>.rviz with the orbit camera and the
grid fitted to the world (the world file, or the simulation's world.json and flights) when it is
known (else the configuration is used as it is), and rviz is started on it (this process becomes
rviz). roslaunch magna_viz rviz.launch (live runs) and replay.launch use it.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

from magna_common.records import WorldRecord
from magna_common.storage_tree import BAG_FILE
from magna_viz import rviz_config as rc


def fitted_config(world: str, record: WorldRecord | None, flights, override: Path | None,
                  name: str) -> tuple[Path, str]:
    """(the rviz file to open, a note for the log): the family's configuration, fitted to the world
    record (a recorded world.json or a resolved world file) and the flights when known."""
    from magna_viz.replay.plan import view_box

    choice = rc.choose_config(world, override)
    config = rc.load_config(choice.path)
    note = choice.note
    box = view_box(record, flights, "world")
    if box is None:
        return choice.path, (note + "; " if note else "") + f"using {choice.path} as it is"
    yaw, pitch = rc.view_of(config)
    view = rc.fit_orbit(box, yaw, pitch, aspect=1.2)  # the 3-D view between the docks
    file_name = re.sub(r"[^A-Za-z0-9_.-]", "_", name) + ".rviz"
    ros_home = Path(os.environ.get("ROS_HOME", Path.home() / ".ros"))
    path = rc.write_config(rc.adapt(config, view=view, grid_box=box), ros_home / "magna_viz" / file_name)
    return path, (note + "; " if note else "") + f"{choice.path.name} fitted to the world: {path}"


def _sim_dir_inputs(sim_dir: Path):
    """(world name, recorded world, flight box) of a simulation folder."""
    from magna_viz.replay.errors import ReplayError
    from magna_viz.replay.plan import read_bag, read_world

    flights = None
    if (sim_dir / BAG_FILE).is_file():
        try:
            flights = read_bag(sim_dir / BAG_FILE).flight_box
        except ReplayError as err:
            print(f"rviz_world: {err}", file=sys.stderr)
    return rc.world_of_sim_dir(sim_dir), read_world(sim_dir), flights


def _world_record(world: str, subworld: str, worlds_path: list[Path], seed: int) -> WorldRecord | None:
    try:
        from magna_common.search_path import find_world_file, world_folders
        from magna_worlds.generate import resolve_world, world_record
        from magna_worlds.loader import load_world

        found = find_world_file(world, subworld, [*worlds_path, *world_folders()])
        if found is None:
            return None
        return WorldRecord.from_dict({"parts": {"main": world_record(resolve_world(load_world(found), seed))}},
                                     str(found))
    except Exception as error:  # a view is a convenience: a world that does not resolve keeps the default one
        print(f"rviz_world: cannot fit the view to {world}/{subworld}: {error}", file=sys.stderr)
        return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ros_args = [a for a in argv if ":=" in a]
    parser = argparse.ArgumentParser(prog="rviz_world", description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="", help="world name (its family picks the configuration)")
    parser.add_argument("--subworld", default="", help="subworld: with --world, the file the camera is fitted to")
    parser.add_argument("--worlds-path", action="append", default=[], type=Path, metavar="DIR",
                        help="also look for WORLD/SUBWORLD.json here (repeatable; empty values are ignored)")
    parser.add_argument("--seed", type=int, default=0, help="seed the world is resolved with (default 0)")
    parser.add_argument("--config", default="", help="an rviz file instead of the family's")
    parser.add_argument("--sim-dir", default="", metavar="DIR",
                        help="a simulation folder: its world (result.json) and world.json and bag set the view")
    args = parser.parse_args([a for a in argv if ":=" not in a])
    config = Path(args.config) if args.config else None
    if config is not None and not config.is_file():
        print(f"rviz_world: --config {config}: no such file", file=sys.stderr)
        return 2
    paths = [p for p in args.worlds_path if str(p).strip() not in ("", ".")]
    try:
        if args.sim_dir:
            world, record, flights = _sim_dir_inputs(Path(args.sim_dir))
            world = args.world or world
            name = f"replay_{Path(args.sim_dir).resolve().name}"
        else:
            world, flights = args.world, None
            record = _world_record(world, args.subworld, paths, args.seed) if world and args.subworld else None
            name = f"live_{world}_{args.subworld}"
        path, note = fitted_config(world, record, flights, config, name)
    except rc.ConfigError as err:
        print(f"rviz_world: {err}", file=sys.stderr)
        return 2
    print(f"rviz_world: {note}", flush=True)
    os.execvp("rviz", ["rviz", "-d", str(path), *ros_args])
    return 0  # not reached
