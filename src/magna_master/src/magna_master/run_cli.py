"""`magna run`: a batch of simulations of one mission in one world, saved under the data root.

    magna run --world Gym/1Obs_Central_Cylinder --mission Gym/2UAVs_2paths_Central_Cylinder --n-iter 5 \\
        [--name NAME] [--dataset N] [--rtf max|FACTOR] [--seed S] [--no-bag] [--rviz] [--search-path DIR ...] \\
        [--data-root DIR] [--append|--overwrite|--skip-save] [--time-limit SECONDS] [--launch-command CMD] [--strict] \\
        [--fleet FLEET.yaml] [--min-free-space MB] [--cold-start] [--managers host|process] [--jobs N]
        [--cluster ADDRESS]

Exit status: 0 when every simulation ran to a mission outcome (a failed mission is data, not an
error), 1 when one or more crashed or could not start, or the disk filled up during the batch, 2 for
bad input or a data root that cannot take the data (nothing started or written), 130 when
interrupted (finished simulations and summary.csv are kept).
"""
from __future__ import annotations

import argparse
import math
import shlex
import sys
from pathlib import Path

from magna_common.cli_vocabulary import add_deprecated_flag, add_rtf, add_search_path, parse_rtf
from magna_common.errors import UsageError
from magna_common.storage_tree import DEFAULT_DATA_ROOT, DEFAULT_NAME
from magna_master.storage import APPEND, DEFAULT_MIN_FREE_MB, OVERWRITE

HELP = "run a batch of simulations of a mission in a world; save bags, CSVs and a summary per dataset"

_EPILOG = """\
Data goes to DATA_ROOT/Simulations/WORLD/SUBWORLD/MISSION/SUBMISSION/NAME/dataset_N/simulation_M/
(result.json, world.json, mission.json, uav_ID.csv, simulation.bag, logs/) with dataset_N/summary.csv
holding one row per simulation (id, success, outcome, message, duration in simulated s, wall_time,
collisions). Simulation M runs with seed S+M.

--world and --mission take a file, or a name looked up as WORLD/SUBWORLD.json and
MISSION/SUBMISSION.json: first in each --search-path DIR (its worlds/ or missions/, DIR itself, its
Worlds/ or Missions/), then in $MAGNA_WORLDS_PATH or $MAGNA_MISSIONS_PATH, then in the project's
worlds/ and missions/. The original ROS-MAGNA files are found with --search-path ../shared/ros_magna_corpus.

When simulation folders of this dataset exist already: --append numbers the new ones after the last,
--overwrite deletes and rewrites exactly the folders it runs again (each just before its run); with
neither you are asked on a terminal, and elsewhere the run stops before starting anything.
--skip-save saves nothing at all (no folders, no summary, no report); the table is printed at the end.

--jobs N runs N simulations at once, each with its own ROS master, simulator and stack; --cluster ADDRESS
runs them on the workers of a Dask scheduler, which send each simulation's folder back here. Either way
the dataset and summary.csv are those of a serial run of the same seeds (src/magna_master/README.md,
'Batches across machines').

Ctrl-C (or SIGTERM, SIGHUP) stops the running simulation (its processes are ended and it is marked
'interrupted' in result.json and summary.csv), starts no more, and keeps every finished one; --append
continues the dataset. A dataset folder that is not writable, or whose disk has less than
--min-free-space MB free, is refused before anything starts; a disk that fills up during the batch
stops it after the running simulation, with summary.csv whole.

examples:
  ./magna run --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA --n-iter 1 --append
  ./magna run --world Gym/1Obs_Central_Cylinder --mission Gym/2UAVs_2paths_Central_Cylinder \\
      --search-path ../shared/ros_magna_corpus --n-iter 1 --skip-save
  ./magna run --world worlds/Gym/Four_Cylinders.json --mission missions/Gym/All_Take_Off.json --skip-save --rtf 1.0
  ./magna run --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA --n-iter 4 --jobs 2 --skip-save
  ./magna run --world W/S --mission M/S --n-iter 200 --cluster tcp://SCHEDULER:8786   # on Dask workers [synopsis]
  ./magna run --world Gym/1Obs_Central_Cylinder --mission Gym/2UAVs_2paths_Central_Cylinder --n-iter 80 \\
      --search-path ../shared/ros_magna_corpus --name orca --seed 1000 --append   # [long]
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument("--world", required=True, metavar="WORLD/SUBWORLD",
                        help="the world: a name, e.g. Gym/Central_Obstacle_Torus, or a file")
    parser.add_argument("--mission", required=True, metavar="MISSION/SUBMISSION",
                        help="the mission: a name, e.g. Gym/2UAVs_Crossing_ORCA, or a file")
    parser.add_argument("--n-iter", type=int, default=1, metavar="N", help="simulations to run (default: 1)")
    parser.add_argument("--name", default=DEFAULT_NAME,
                        help="name of this series of datasets (a folder; default: %(default)s)")
    parser.add_argument("--dataset", type=int, default=1, metavar="N", help="dataset number (default: 1)")
    add_rtf(parser, help="real-time factor of the simulator: 'max' runs as fast as the machine goes, a number "
                         "(e.g. 1.0) runs that many times real time")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="base seed; simulation M uses S+M (default: 0)")
    parser.add_argument("--no-bag", action="store_true", help="do not record a bag per simulation")
    parser.add_argument("--no-report", action="store_true",
                        help="do not write each simulation's report.html and the dataset's index.html "
                             "(`magna report` writes them later)")
    parser.add_argument("--rviz", action="store_true",
                        help="show each simulation in rviz as it flies (needs a display; without one use "
                             "`magna replay --headless` afterwards)")
    add_search_path(parser)
    parser.add_argument("--data-root", type=Path, default=DEFAULT_DATA_ROOT, metavar="DIR",
                        help="where Simulations/ goes (default: ~/magna_data)")
    dataset = parser.add_argument_group("the dataset (when its simulation folders exist already)")
    policy = dataset.add_mutually_exclusive_group()
    policy.add_argument("--append", dest="policy", action="store_const", const=APPEND,
                        help="if the dataset has simulations: number the new ones after the last")
    policy.add_argument("--overwrite", dest="policy", action="store_const", const=OVERWRITE,
                        help="if the dataset has simulations: delete and rewrite the ones run again")
    policy.add_argument("--skip-save", action="store_true",
                        help="save nothing (no folders, no summary, no report); the table is printed at the end")
    add_deprecated_flag(parser, "--no-data", "skip_save", "--skip-save")
    parser.add_argument("--fleet", type=Path, metavar="FILE",
                        help="the fleet file (YAML) of the mission's hil and real UAVs: where each autopilot is "
                             "(MAVLink URL), its arming policy, or a simulated PX4-like stand-in; needed when the "
                             "mission has hil or real UAVs; autopilots outside the simulator make it run at real "
                             "time (--rtf 1), stand-ins do not. Format: "
                             "src/magna_mavlink/README.md, 'The fleet file'")
    parser.add_argument("--utm-plan", type=Path, metavar="FILE",
                        help="a UTM flight-plan file (JSON) for missions that follow paths 'from utm'; the UTM "
                             "node issues its plans at their simulated times (format: src/magna_gs/README.md)")
    parser.add_argument("--battery-floor", type=percentage_arg, default=0.0, metavar="PCT",
                        help="simulated batteries never fall below PCT %% of their charge, as PX4's SITL battery "
                             "(SIM_BAT_MIN_PCT, 50 there) on which the original ROS-MAGNA flew (default: 0, "
                             "batteries run empty and long missions meet low_battery)")
    parser.add_argument("--strict", action="store_true",
                        help="refuse the world or mission for what would only be a warning (what the original "
                             "ROS-MAGNA tolerated); for authors of new files")
    parser.add_argument("--status-file", type=Path, metavar="FILE",
                        help="keep FILE (JSON, rewritten atomically) saying how far the batch is and the ROS "
                             "master of the running simulation, for a program that watches it (magna studio)")
    parser.add_argument("--button-timeout", type=float, default=10.0, metavar="SECONDS",
                        help="a mission's wait for the operator's button goes on after this many simulated "
                             "seconds, since nobody presses it in a batch (default 10; 0: wait for "
                             "rosservice call /magna/gs/continue)")
    parser.add_argument("--time-limit", type=float, default=600.0, metavar="SECONDS",
                        help="wall-clock seconds per simulation before the ground station is stopped "
                             "(default: 600; 0: none)")
    parser.add_argument("--min-free-space", type=float, default=DEFAULT_MIN_FREE_MB, metavar="MB",
                        help="MB the disk of the dataset keeps free: checked before the batch and before each "
                             "simulation, which is not started below it (default: %(default)g)")
    parser.add_argument("--managers", choices=("host", "process"), default="host",
                        help="host (default): the UAV managers run in one process, a thread each, with the same "
                             "ROS names; process: one process per manager, as a real UAV's companion computer runs it")
    parallel = parser.add_argument_group("running simulations at once")
    parallel.add_argument("--jobs", type=int, default=1, metavar="N",
                          help="simulations run at once on this machine, each with its own ROS master, simulator "
                               "and stack (default: 1). A 2-UAV simulation keeps about one core busy")
    parallel.add_argument("--cluster", metavar="ADDRESS",
                          help="spread the batch over the workers of a Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                               "(set-up: src/magna_master/README.md, 'Batches across machines')")
    parser.add_argument("--cold-start", action="store_true",
                        help="a fresh ROS master and launch for every simulation; by default a batch keeps one "
                             "stack (master, simulator, world node, ORCA-3D) up and resets it between its "
                             "simulations, which gives the same flights faster (--rviz, --fleet and "
                             "--launch-command always start cold)")
    parser.add_argument("--launch-command", default="", metavar="CMD",
                        help="replace 'roslaunch magna_gs simulation.launch ...' (e.g. a stand-in ground "
                             "station); placeholders: " + ", ".join(f"{{{p}}}" for p in _placeholders()))


def percentage_arg(text: str) -> float:
    """argparse type: a percentage from 0 to below 100."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (0.0 <= value < 100.0):
        raise argparse.ArgumentTypeError(f"{text!r}: give a percentage from 0 to below 100, e.g. 50")
    return value


def _placeholders():
    from magna_master.batch_config import PLACEHOLDERS

    return PLACEHOLDERS


def build_config(args):
    """BatchConfig from parsed arguments; a UserError (InputError, BatchError) on bad input."""
    from magna_gs.inputs import resolve_inputs
    from magna_master.batch_config import DEFAULT_LAUNCH_COMMAND, BatchConfig, BatchError

    inputs = resolve_inputs(args.world, args.mission, args.search_path, strict=args.strict)
    command = DEFAULT_LAUNCH_COMMAND
    if args.launch_command.strip():
        try:
            command = tuple(shlex.split(args.launch_command))
        except ValueError as err:
            raise BatchError(f"--launch-command: {err}") from None
    utm_plan = None
    if args.utm_plan is not None:
        from magna_gs.utm import UtmPlanError, load_plan

        try:  # a bad plan stops the batch before anything starts, as the ground station would
            load_plan(args.utm_plan)
        except UtmPlanError as err:
            raise BatchError(f"--utm-plan: {' '.join(str(err).split())}") from None
        utm_plan = args.utm_plan.expanduser().resolve()
    fleet, rtf = check_fleet(inputs.mission_file, args.fleet, args.rtf)
    return BatchConfig(inputs=inputs, n_iter=args.n_iter, utm_plan=utm_plan, battery_floor=args.battery_floor,
                       name=args.name, n_dataset=args.dataset, fleet=fleet,
                       rtf=rtf,
                       seed=args.seed, bag=not args.no_bag, save_data=not args.skip_save,
                       data_root=args.data_root, policy=args.policy,
                       time_limit=args.time_limit or None, button_timeout=args.button_timeout,
                       launch_command=command, rviz=args.rviz, min_free_mb=args.min_free_space,
                       cold_start=args.cold_start, managers=args.managers, jobs=args.jobs)


def check_fleet(mission_file: Path, fleet_file: Path | None, rtf: str) -> tuple[Path | None, str]:
    """The fleet file and the real-time factor for this mission; BatchError when they do not fit it.

    A mission with hil or real UAVs needs a fleet file. It runs at real time when one of them is an autopilot
    outside the simulator (its links and timeouts live in wall time): the default --rtf (max) then becomes 1,
    any other factor is refused. Stand-ins fly in simulated time, so a fleet of stand-ins keeps --rtf."""
    from magna_gs.mission.loader import load_mission
    from magna_master.batch_config import BatchError
    from magna_mavlink.fleet import FleetError, check_against_mission, load_fleet, mavlink_uavs

    modes: dict[int, str] = {agent.id: agent.mode for agent in load_mission(mission_file).mission.agents}
    flown = mavlink_uavs(modes)
    if not flown:
        if fleet_file is not None:
            raise BatchError(f"--fleet {fleet_file}: every UAV of {mission_file.name} is sitl, so there is nothing "
                             f"to reach over MAVLink; drop --fleet, or make UAVs hil or real in the mission")
        return None, rtf
    if fleet_file is None:
        raise BatchError(f"{mission_file}: UAVs {flown} are hil or real; give --fleet FILE saying where their "
                         f"autopilots are (src/magna_mavlink/README.md, 'The fleet file')")
    try:
        fleet = load_fleet(fleet_file.expanduser())
    except FleetError as err:
        raise BatchError(f"--fleet: {err}") from None
    problems = check_against_mission(fleet, modes)
    if problems:
        raise BatchError(f"--fleet: {problems[0]}" + (f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""))
    factor = parse_rtf(rtf)
    outside = [i for i in flown if not fleet.uavs[i].stand_in]
    if outside and factor == "max":
        print(f"magna run: UAVs {outside} fly over MAVLink outside the simulator: the simulation runs at real "
              f"time (--rtf 1)", flush=True)
        factor = "1"
    elif outside and float(factor) != 1.0:
        raise BatchError(f"--rtf {rtf}: UAVs {outside} are autopilots outside the simulator and fly in real time; "
                         f"give --rtf 1 (or leave it out)")
    return fleet_file.expanduser().resolve(), factor


def run(args) -> int:
    from magna_master.reports import Reports
    from magna_master.storage import ask_policy

    config = build_config(args)  # bad input: a UserError, which `magna` prints (exit status 2)
    ask = ask_policy if sys.stdin is not None and sys.stdin.isatty() else None
    reports = None if args.no_report or not config.save_data else Reports()
    watched = _status_file(args, config)
    status = 2  # a UserError on the way
    try:
        status = _run_batch(args, config, ask, reports, watched)
        return status
    finally:
        if watched is not None:
            watched.ended(status)


def _status_file(args, config):
    """The --status-file writer, or None without the option."""
    if args.status_file is None:
        return None
    from magna_master.run_status import RunStatus

    path = args.status_file.expanduser()
    if not path.parent.is_dir():
        raise UsageError(f"--status-file {path}: folder {path.parent} does not exist; create it first")
    return RunStatus(path, config.n_iter, config.dataset_dir if config.save_data else None)


def _run_batch(args, config, ask, reports, watched) -> int:
    from magna_master.batch import run_batch
    from magna_master.batch_summary import format_summary

    finished = [f for f in (reports, watched.finished if watched else None) if f is not None]

    def on_simulation(result) -> None:
        for call in finished:
            call(result)

    if args.cluster:
        from magna_master.cluster import run_cluster_batch

        result = run_cluster_batch(config, args.cluster, ask=ask, on_simulation=on_simulation)
    else:
        result = run_batch(config, ask=ask, on_simulation=on_simulation,
                           on_start=watched.started if watched else None)
    print(format_summary(result), flush=True)
    if reports is not None:
        reports.wait()  # the last reports are drawn in a worker thread, and pyplot is for one thread at a time
    saved = result.dataset_dir if result.dataset_dir is not None and result.dataset_dir.is_dir() else None
    if saved is not None and not result.interrupted and not result.storage_error:
        pictures = draw_pictures(config, saved)
        if pictures:
            print("pictures: " + ", ".join(str(p) for p in pictures), flush=True)
    if saved is not None and reports is not None:
        reports.finish(saved)
    if result.interrupted:
        return 130
    return 1 if result.failed_to_run or result.storage_error else 0


def draw_pictures(config, folder: Path) -> list[Path]:
    """The world and the mission's state machine, drawn once per dataset (kept if already there)."""
    made = []
    world_png, mission_png = folder / "world.png", folder / "mission.png"
    try:
        if not world_png.exists():
            from magna_worlds.draw import draw_world
            from magna_worlds.generate import resolve_world
            from magna_worlds.loader import load_world

            draw_world(resolve_world(load_world(config.inputs.world_file), config.seed), world_png)
        made.append(world_png)
        if not mission_png.exists():
            from magna_gs.mission.build import InertFactory, build_machine
            from magna_gs.mission.loader import load_mission
            from magna_sm.draw import draw

            loaded = load_mission(config.inputs.mission_file)
            draw(build_machine(loaded.mission, InertFactory(), loaded.plan), mission_png,
                 title=config.inputs.mission_file.stem, show_active=False)
        made.append(mission_png)
    except Exception as error:  # pictures help; their failure must not hide the batch's result
        print(f"magna run: could not draw the pictures: {error}", file=sys.stderr)
    return made


def node_main(argv: list[str] | None = None) -> int:
    """nodes/batch: `magna run` with the arguments roslaunch gives (its name:=value remappings dropped)."""
    from magna_master.cli import main

    argv = sys.argv[1:] if argv is None else argv
    return main(["run", *[a for a in argv if ":=" not in a]])
