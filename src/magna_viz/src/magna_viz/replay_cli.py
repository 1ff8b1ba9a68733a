"""`magna replay`: play a simulation's bag into rviz, or headless into screenshots, a GIF and an MP4.

    magna replay BAG|SIM_DIR [--speed F] [--config FILE] [--mission MISSION] [--search-path DIR ...]
                 [--fit world|uavs|none] [--loop]
    magna replay BAG|SIM_DIR --headless [--every S] [-o DIR] [--gif] [--mp4] [--fps N] [--size WxH] [--force]

Exit status: 0 done, 1 a process failed (rviz, Xvfb, rosbag play, ffmpeg), 2 bad input (nothing
started or written), 130 interrupted (every process it started is ended).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from magna_common.cli_vocabulary import add_force, add_output, add_search_path
from magna_common.errors import UsageError
from magna_viz.report_cli import EXAMPLE_DATASET

HELP = "play a simulation's bag into rviz; --headless writes screenshots, the final frame, a GIF or an MP4"

_EPILOG = f"""\
BAG|SIM_DIR is a simulation's bag or its folder (DATA_ROOT/Simulations/.../simulation_M/, which
holds simulation.bag, mission.json, world.json and result.json).

What rviz shows: fixed frame map, a grid, the world's markers, each UAV in its mission colour
(marker_color of mission.json) with its safety sphere, name, trail, raw and smoothed paths and
current goal, and the tf frames. The configuration is the world family's (result.json's world,
else the folder): Gym gym.rviz, Delivery delivery.rviz, SolarPlant solar_plant.rviz, Inspection
inspection.rviz, any other gym.rviz; --config FILE overrides. The camera keeps the configuration's
angle and is fitted (--fit) to the world and the flights (world), the flights only (uavs), or not
at all (none). The world stays drawn after the mission clears it at its end.

The UAVs' colours come from SIM_DIR/mission.json; --mission takes another mission, a file or a name
MISSION/SUBMISSION looked up as `magna run` does (each --search-path DIR, then missions/).

The replay runs on a private ROS master (never 11311) with simulated time from the bag
(rosbag play --clock at --speed). Without --headless rviz opens on your display (DISPLAY must be
set) and stays open on the last state until you close it. With --headless rviz runs full screen
without panels in an Xvfb server of its own, and -o DIR (default SIM_DIR/replay/) receives
frame_0001.png, frame_0002.png, ... (one every --every seconds of bag time), final.png (once the
picture has settled after the bag's end), and replay.gif / replay.mp4 when asked (frames and the
final one, at --fps; the MP4 through ffmpeg). Existing outputs are kept unless --force. Every
process the replay starts (master, Xvfb, rviz, scene node, rosbag) is ended when it finishes,
fails or is interrupted.

examples:
  ./magna replay {EXAMPLE_DATASET}/simulation_1 --speed 2   # rviz on your display [display]
  ./magna replay {EXAMPLE_DATASET}/simulation_1 --headless --speed 4 --every 0 --force
  ./magna replay {EXAMPLE_DATASET}/simulation_1/simulation.bag --headless --speed 4 --every 2 --gif \\
      -o /tmp/replay --size 960x540 --force
"""


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT (e.g. 1280x720), got {text!r}") from None
    return width, height


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from magna_viz.replay.plan import FITS

    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument("source", type=Path, metavar="BAG|SIM_DIR", help="a simulation.bag or its simulation folder")
    parser.add_argument("--speed", type=float, default=1.0, metavar="F",
                        help="bag seconds per wall second (rosbag play -r; default 1.0)")
    parser.add_argument("--config", type=Path, default=None, metavar="FILE",
                        help="an rviz file instead of the world family's")
    parser.add_argument("--mission", default=None, metavar="MISSION",
                        help="the mission whose UAV colours to use: a file or a MISSION/SUBMISSION name "
                             "(default: SIM_DIR/mission.json)")
    add_search_path(parser, what="missions (--mission)")
    parser.add_argument("--fit", choices=FITS, default="world",
                        help="fit the camera to the world and the flights, the flights only, or keep the "
                             "configuration's (default: world)")
    parser.add_argument("--loop", action="store_true", help="play the bag again and again (not with --headless)")
    headless = parser.add_argument_group("headless (no display needed)")
    headless.add_argument("--headless", action="store_true",
                          help="run rviz in Xvfb and write screenshots instead of opening a window")
    headless.add_argument("--every", type=float, default=None, metavar="S",
                          help="a screenshot every S seconds of bag time (default 1; 0: only final.png)")
    add_output(headless, metavar="DIR", help="folder of the outputs (default: SIM_DIR/replay)", old=("--out",))
    headless.add_argument("--gif", action="store_true", help="also write replay.gif (at most 800 px wide)")
    headless.add_argument("--mp4", action="store_true", help="also write replay.mp4 (H.264, with ffmpeg)")
    headless.add_argument("--fps", type=float, default=None, metavar="N",
                          help="frames per second of the GIF and MP4 (default 5)")
    headless.add_argument("--size", type=_size, default=None, metavar="WxH",
                          help="screen and picture size (default 1280x720)")
    add_force(headless, help="replace the outputs of an earlier replay")


def options_from(args):
    """ReplayOptions from parsed arguments; UsageError for headless options without --headless."""
    from magna_viz.replay.plan import ReplayOptions

    if not args.headless:
        given = [flag for flag, value in (("--every", args.every), ("-o/--output", args.output),
                                          ("--gif", args.gif or None),
                                          ("--mp4", args.mp4 or None), ("--fps", args.fps), ("--size", args.size),
                                          ("--force", args.force or None)) if value is not None]
        if given:
            raise UsageError(f"{given[0]} only applies with --headless (screenshots); add --headless")
    return ReplayOptions(
        source=args.source, headless=args.headless, out_dir=args.output,
        every=1.0 if args.every is None else args.every, speed=args.speed, gif=args.gif, mp4=args.mp4,
        fps=5.0 if args.fps is None else args.fps, force=args.force, config=args.config,
        mission_file=mission_file(args.mission, args.search_path), size=args.size or (1280, 720), fit=args.fit,
        loop=args.loop)


def mission_file(spec: str | None, search_dirs=()) -> Path | None:
    """--mission: an existing file as it is, else a name MISSION/SUBMISSION looked up as `magna mission` does.
    Any other missing path is left to the replay's plan, which names it."""
    if spec is None:
        return None
    path = Path(spec).expanduser()
    name = spec.strip().removesuffix(".json")
    if path.is_file() or name.count("/") != 1:
        return path
    from magna_gs.mission.cli import mission_folders
    from magna_gs.mission.loader import find_mission
    from magna_gs.mission.model import MissionError

    try:
        return Path(find_mission(name, mission_folders(search_dirs)))
    except MissionError as error:
        raise UsageError(f"--mission {' '.join(error.problems[0].split())}") from None


def run(args) -> int:
    from magna_viz.replay.errors import ReplayError, ReplayFailure
    from magna_viz.replay.plan import FINAL_NAME, GIF_NAME, MP4_NAME, make_plan
    from magna_viz.replay.processes import Replay

    options = options_from(args)
    try:
        plan = make_plan(options)
    except ReplayError as err:
        raise UsageError(str(err)) from None
    say = _say
    say(f"{plan.bag.path} ({plan.bag.duration:.1f} s of bag; UAVs {', '.join(map(str, plan.uav_ids))}) "
        f"in rviz with {plan.choice.path}")
    for note in plan.notes:
        say(note)
    try:
        written = Replay(plan, log=say).run()
    except ReplayFailure as err:
        print(f"magna replay: {err}", file=sys.stderr)
        return 1
    if options.headless:
        frames = [p for p in written if p.name.startswith("frame_")]
        if frames:
            say(f"frames:  {len(frames)} in {plan.out_dir} (frame_0001.png .. {frames[-1].name})")
        labels = {FINAL_NAME: "final:", GIF_NAME: "gif:", MP4_NAME: "mp4:"}
        for path in written:
            if path.name in labels:
                say(f"{labels[path.name]:8} {path}")
    return 0


def _say(text: str) -> None:
    print(f"magna replay: {text}", flush=True)
