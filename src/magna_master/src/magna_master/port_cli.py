"""`magna port DIR`: can a folder of original ROS-MAGNA worlds and missions be used as it is?

    magna port ~/ros_magna/Code/JSONs [--fly] [--strict] [-o FILE] [--force]

Exit status: 0 when every file loads and every paired mission validates in its world (flights that
end in a safety branch or a failure are part of the report, not errors), 2 when a file or a pair is
refused, or the folder cannot be read.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from magna_common.cli_vocabulary import (
    OutputExists,
    add_deprecated_flag,
    add_force,
    add_output,
    add_rtf,
    check_output,
    parse_rtf,
)
from magna_common.errors import UsageError
from magna_common.files import write_text_atomically
from magna_common.storage_tree import DEFAULT_DATA_ROOT

HELP = "porting report for a folder of ROS-MAGNA worlds and missions: what loads, migrates, warns and flies"

_EPILOG = """\
The folder is laid out as the original's Code/JSONs: Worlds/<family>/<name>.json and
Missions/<family>/<name>.json (a folder of loose files works too). Each mission is paired with one
world that holds every volume and geometry it names: a world of its own family first (the one with
the mission's name, else the one whose name's words the mission's name contains, else the smallest),
then likewise among the other families.

The table has one row per file: loads (or REFUSED), migrated (how many changes the migration of an
older schema made), warnings (what the original tolerated and MAGNA accepts, saying what it does),
the paired world, validates (the mission's places resolve in it) and, with --fly, flies (one
simulation each at --rtf, 'yes' when the mission ended in success). Below the table, each file's
changes, warnings and refusals in full.

The original flew its simulated UAVs on PX4's SITL battery, which never falls below 50 % (its
SIM_BAT_MIN_PCT), so its long inspections never met a low battery; --fly flies them the same way
(--battery-floor 50). With --battery-floor 0 batteries run empty as in `magna run`.

-o FILE also writes the whole report as JSON (replaced only with --force). With --fly each flight is
saved under DATA_ROOT/Simulations/... in the series 'port', appended; --skip-save saves none.

examples:
  ./magna port ../shared/ros_magna_corpus
  ./magna port ../shared/ros_magna_corpus --brief -o /tmp/port.json --force
  ./magna port . --strict --brief     # the project's own worlds/ and missions/; warnings are refusals
  ./magna port ../shared/ros_magna_corpus --fly --skip-save      # also fly each pair once [long]
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from magna_master.run_cli import percentage_arg

    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument("folder", type=Path, metavar="DIR", help="folder holding Worlds/ and Missions/")
    parser.add_argument("--fly", action="store_true",
                        help="fly each validated pair once in magna run (needs the built workspace)")
    parser.add_argument("--strict", action="store_true",
                        help="treat warnings as refusals (for authors of new files)")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="seed for random pose sets (default: 0)")
    add_rtf(parser, help="real-time factor when flying: 'max' runs as fast as the machine goes, a number runs "
                         "that many times real time")
    parser.add_argument("--skip-save", action="store_true",
                        help="with --fly: keep no simulation folders (by default each flight is saved under "
                             "DATA_ROOT/Simulations/... with the name 'port', appended)")
    add_deprecated_flag(parser, "--no-data", "skip_save", "--skip-save")
    parser.add_argument("--data-root", type=Path, default=DEFAULT_DATA_ROOT, metavar="DIR",
                        help="with --fly: where Simulations/ goes (default: ~/magna_data)")
    parser.add_argument("--time-limit", type=float, default=600.0, metavar="SECONDS",
                        help="with --fly: wall-clock seconds per flight before it is stopped (default: 600)")
    parser.add_argument("--battery-floor", type=percentage_arg, default=50.0, metavar="PCT",
                        help="with --fly: simulated batteries keep PCT %% of their charge, as the PX4 SITL battery "
                             "the original flew on (SIM_BAT_MIN_PCT; default: 50); 0 for batteries that run empty")
    add_output(parser, metavar="FILE", help="also write the report as JSON to FILE", old=("--json",))
    add_force(parser, help="replace an existing -o FILE")
    parser.add_argument("--brief", action="store_true", help="the table and totals only, no per-file details")


def run(args) -> int:
    from magna_master.port import PortError, as_json, format_report, port_folder

    if args.output is not None:
        try:
            check_output(args.output, args.force, what="-o")
        except OutputExists as error:
            raise UsageError(str(error)) from None
        if not args.output.parent.is_dir():
            raise UsageError(f"-o {args.output}: folder {args.output.parent} does not exist; create it first")
    try:
        report = port_folder(args.folder, strict=args.strict, seed=args.seed, progress=_Progress())
    except PortError as error:
        raise UsageError(str(error)) from None
    _Progress.clear()
    if args.fly:
        _fly(report, args)
    print(format_report(report, details=not args.brief), flush=True)
    if args.output is not None:
        write_text_atomically(args.output, json.dumps(as_json(report), indent=2) + "\n", overwrite=True)
        print(f"json:    {args.output}")
    return 2 if report.refused else 0


def _fly(report, args) -> None:
    from magna_gs.inputs import resolve_inputs
    from magna_master.batch import run_batch
    from magna_master.batch_config import BatchConfig
    from magna_master.port import fly_pairs
    from magna_master.storage import APPEND

    rtf = parse_rtf(args.rtf)

    def make_config(mission):
        inputs = resolve_inputs(str(mission.world.path), str(mission.path), check=False)
        return BatchConfig(inputs=inputs, n_iter=1, name="port", rtf=rtf, seed=args.seed,
                           save_data=not args.skip_save, data_root=args.data_root, policy=APPEND,
                           time_limit=args.time_limit or None, battery_floor=args.battery_floor)

    def progress(index, total, mission):
        print(f"flying {index} of {total}: {mission.label} in {mission.world.label}", file=sys.stderr, flush=True)

    fly_pairs(report, make_config, lambda config: run_batch(config, progress=False), progress)


class _Progress:
    """One line on a terminal, rewritten per file; silent elsewhere."""
    def __call__(self, what: str) -> None:
        if sys.stderr.isatty():
            print(f"\rchecking {what}"[:100].ljust(100), end="", file=sys.stderr, flush=True)

    @staticmethod
    def clear() -> None:
        if sys.stderr.isatty():
            print("\r" + " " * 100 + "\r", end="", file=sys.stderr, flush=True)
