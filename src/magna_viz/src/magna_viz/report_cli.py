"""`magna report`: the HTML report of a simulation, or of every simulation of a dataset plus its index.

    magna report SIM_DIR [--force]       # SIM_DIR/report.html (magna run wrote it already: --force again)
    magna report DATASET_DIR [--force]   # the reports still missing (all with --force) + index.html
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from magna_common.errors import UsageError

# The dataset the root README's `make run` leaves, which examples name.
EXAMPLE_DATASET = "~/magna_data/Simulations/Gym/Central_Obstacle_Torus/Gym/2UAVs_Crossing_ORCA/default/dataset_1"

HELP = "write the HTML report of a simulation (plots, result, mission), or of a dataset with its index page"

_EPILOG = f"""\
A simulation folder (simulation_<m>, with result.json) gets report.html and plots/*.png beside its
bag and CSVs. A dataset folder (dataset_<n>) gets a report for each simulation that has none yet
(all of them with --force) and index.html, the summary table linking every report. `magna run`
writes both as it goes, unless --no-report: to write a simulation's report again (after a change
to MAGNA, say), pass --force.

Reading needs no ROS master: the bag is read with rosbags, the CSVs with pandas.

examples:
  ./magna report {EXAMPLE_DATASET}/simulation_1 --force
  ./magna report {EXAMPLE_DATASET}          # only the missing reports, and index.html
  ./magna report {EXAMPLE_DATASET} --force   # every report again
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument("folders", nargs="+", type=Path, metavar="FOLDER",
                        help="a simulation_<m> folder or a dataset_<n> folder")
    parser.add_argument("--force", action="store_true", help="write reports that exist already again")


def run(args) -> int:
    from magna_viz.index import simulation_dirs
    from magna_viz.report import REPORT_FILE

    jobs: list[tuple[Path, list[Path]]] = []  # (the folder given, its simulations)
    for folder in args.folders:
        folder = folder.expanduser()
        if not folder.is_dir():
            raise UsageError(f"{folder}: no such folder; give a simulation_<m> or dataset_<n> folder of `magna run`")
        if (folder / "result.json").exists():
            if (folder / REPORT_FILE).exists() and not args.force:
                raise UsageError(f"{folder / REPORT_FILE} already exists (magna run writes it); pass --force to "
                                 "write it again")
            jobs.append((folder, [folder]))
        elif sims := simulation_dirs(folder):
            jobs.append((folder, sims))
        else:
            raise UsageError(f"{folder}: neither a simulation folder (no result.json) nor a dataset "
                             "(no simulation_<m> folders)")
    failed = 0
    for folder, sims in jobs:
        failed += _reports(sims, args.force)
        if sims != [folder]:
            from magna_viz.index import write_index

            print(f"index:  {write_index(folder)}", flush=True)
    return 1 if failed else 0


def _reports(sims: list[Path], force: bool) -> int:
    from tqdm import tqdm

    from magna_viz.report import REPORT_FILE, ReportError, write_report

    failed = 0
    todo = [s for s in sims if force or not (s / REPORT_FILE).exists()]
    for sim_dir in tqdm(todo, unit="report", disable=len(todo) < 2, file=sys.stderr):
        try:
            report = write_report(sim_dir, overwrite=force)
        except ReportError as error:
            print(f"magna report: {error}", file=sys.stderr)
            failed += 1
            continue
        for note in report.notes:
            print(f"magna report: {sim_dir.name}: {note}", file=sys.stderr)
        print(f"report: {report.path}", flush=True)
    return failed
