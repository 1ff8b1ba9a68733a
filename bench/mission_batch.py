"""Whole-stack mission simulations: how much faster than real time, and how long a dataset of 80 takes.

Everything runs as a user runs it: `./magna run` (a fresh ROS master per simulation, magna_sim,
the world node, ORCA-3D, the ground station and one UAV manager per UAV, bags on), into a
temporary data root, headless, rtf max. In one run:

  (a) the simulated-time / wall-time factor over a few simulations (--repeats, default 3) of
      * the default mission of `make run` (missions/Gym/2UAVs_Crossing_ORCA.json) with 2 UAVs,
        then right after it the same without bags (--no-bag), same seeds, for comparison;
      * a 10-UAV version of it (bench/missions/Gym/10UAVs_Crossing_ORCA.json: ten UAVs on two
        rows of pads, a ring of 8 m round the central obstacles, then every UAV crosses to the
        opposite side of the ring at 5.5 / 6.5 m and flies home, ORCA-3D throughout);
      * and again over the simulations of (b);
      four factors each, simulated s of the mission over wall s of:
        "flight"  the mission while simulated time ran (its setup left out: the simulator
                  stands still while UAVs are spawned and their managers start);
        "mission" the mission from its first state to its end, setup included, with the whole
                  ROS stack running (simulator, world, ORCA, ground station, UAV managers):
                  the figure DESIGN.md's targets are compared with;
        "window"  the launch to the ground station's report (what `magna run` prints): adds
                  the nodes' start-up and the finishing sequence;
        "e2e"     the whole `magna run` process per simulation: adds the ROS master, the
                  supervisor and the clean-up;
      all over the simulations the ground station ended (one stopped by --time-limit is left out);
  (b) the wall time of one `magna run` of --simulations (default 80) of the default mission,
      with the average per simulation, the overhead outside the simulations' windows, and the
      simulations that did not end by themselves (time limit, crash).

The table compares with DESIGN.md section 6: >= 10x real time with 2 UAVs, >= 3x with 10,
80 simulations in <= 20 minutes (on 2 cores). Prints figures; never fails on a time. The default
run takes about 25 minutes (the 80 simulations about 20 of them); --simulations 0 skips (b).

    python bench/mission_batch.py [--repeats 3] [--simulations 80]
        [--no-bag-10] [-o DIR]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

if __name__ == "__main__":  # `python bench/mission_batch.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__)

ROOT = Path(__file__).resolve().parent.parent
MAGNA = ROOT / "magna"
WORLD = "Gym/Central_Obstacle_Torus"
MISSION_2 = "Gym/2UAVs_Crossing_ORCA"  # the default of `make run`
MISSION_10 = ROOT / "bench" / "missions" / "Gym" / "10UAVs_Crossing_ORCA.json"
TARGET_2, TARGET_10 = 10.0, 3.0  # x real time
TARGET_80_S = 20 * 60.0  # wall seconds for 80 simulations


@dataclass
class Simulation:
    id: int
    success: bool
    outcome: str
    sim_s: float  # simulated seconds of the mission (ground station)
    window_s: float  # wall seconds from the launch to the ground station's report (summary.csv wall_time)
    end_to_end_s: float  # wall seconds of this simulation within the `magna run` process
    collisions: int
    termination: str = ""  # result.json: ground_station, time_limit, crashed, ...
    timed_out: bool = False
    mission_wall_s: float = 0.0  # result.json: wall s from the mission's first state to its end
    setup_wall_s: float = 0.0  # of those, wall s with simulated time standing still


@dataclass
class Batch:
    label: str
    uavs: int
    bag: bool
    wall_s: float  # the whole `magna run` process
    exit_code: int
    sims: list[Simulation] = field(default_factory=list)
    load_before: float = 0.0

    @property
    def ended(self) -> list[Simulation]:
        """The simulations the ground station ended (not stopped by the time limit, not crashed)."""
        return [s for s in self.sims if s.termination == "ground_station"]

    @property
    def sim_s(self) -> float:
        return sum(s.sim_s for s in self.sims)

    def _factor(self, wall_of) -> float:
        ended = self.ended
        wall = sum(wall_of(s) for s in ended)
        return sum(s.sim_s for s in ended) / wall if wall > 0 else float("nan")

    @property
    def flight_factor(self) -> float:
        return self._factor(lambda s: s.mission_wall_s - s.setup_wall_s)

    @property
    def mission_factor(self) -> float:
        return self._factor(lambda s: s.mission_wall_s)

    @property
    def window_factor(self) -> float:
        """Simulated s / wall s from the launch to the ground station's report, over the ended simulations."""
        wall = sum(s.window_s for s in self.ended)
        return sum(s.sim_s for s in self.ended) / wall if wall > 0 else float("nan")

    @property
    def end_to_end_factor(self) -> float:
        """Simulated s / wall s of the `magna run` process, per ended simulation."""
        wall = sum(s.end_to_end_s for s in self.ended)
        return sum(s.sim_s for s in self.ended) / wall if wall > 0 else float("nan")

    @property
    def successes(self) -> int:
        return sum(s.success for s in self.sims)

    @property
    def collisions(self) -> int:
        return sum(s.collisions for s in self.sims)


def run_batch(label: str, uavs: int, mission: str, n: int, bag: bool, data_root: Path, name: str,
              time_limit: float) -> Batch:
    """One `./magna run` of n simulations; the time each simulation ends is read from its progress line."""
    argv = [str(MAGNA), "run", "--world", WORLD, "--mission", mission, "--n-iter", str(n), "--rtf", "max",
            "--data-root", str(data_root), "--name", name, "--append", "--time-limit", f"{time_limit:g}"]
    if not bag:
        argv.append("--no-bag")
    load = os.getloadavg()[0]
    print(f"-- {label}: {n} simulation(s) ({' '.join(argv[1:])}); load average {load:.1f}", flush=True)
    ends: dict[int, float] = {}
    started = time.monotonic()
    # stderr (not a terminal): magna run prints "simulation M (k/N): ..." when each one ends
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
                               stdin=subprocess.DEVNULL)
    output = []
    try:
        for line in process.stdout:
            output.append(line)
            if line.startswith("simulation ") and "/" in line.split(":", 1)[0]:
                m = int(line.split()[1])
                ends[m] = time.monotonic() - started
                print(f"   {ends[m]:7.1f} s  {line.rstrip()}", flush=True)
        code = process.wait()
    except BaseException:
        process.send_signal(2)  # magna run stops the running simulation and cleans up on SIGINT
        try:
            process.wait(timeout=120)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        raise
    wall = time.monotonic() - started
    if code != 0:
        print("".join(output[-20:]), end="", flush=True)
        print(f"   magna run exited with status {code}", flush=True)
    batch = Batch(label, uavs, bag, wall, code, load_before=load)
    summaries = list(data_root.glob(f"Simulations/**/{name}/dataset_1/summary.csv"))
    if not summaries:
        print(f"   no summary.csv under {data_root}", flush=True)
        return batch
    previous = 0.0
    with open(summaries[0], newline="") as f:
        for row in csv.DictReader(f):
            m = int(row["id"])
            end = ends.get(m, previous)
            try:
                result = json.loads((summaries[0].parent / f"simulation_{m}" / "result.json").read_text())
            except (OSError, ValueError):
                result = {}
            batch.sims.append(Simulation(m, row["success"] == "True", row["outcome"], float(row["duration"] or 0),
                                         float(row["wall_time"] or 0), end - previous, int(row["collisions"] or 0),
                                         str(result.get("termination", "")), bool(result.get("timed_out")),
                                         float(result.get("mission_wall_time", 0.0)),
                                         float(result.get("setup_wall_time", 0.0))))
            previous = end
    return batch


def fmt_ratio(value: float, target: float, higher_is_better: bool = True) -> str:
    ratio = value / target if higher_is_better else target / value
    return f"{ratio:5.2f} {'meets' if ratio >= 1.0 else 'misses'}"


def build_parser() -> argparse.ArgumentParser:
    from magna_common.cli_vocabulary import add_output

    parser = argparse.ArgumentParser(prog="python bench/mission_batch.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="simulations per speed measurement (default 3)")
    parser.add_argument("--simulations", type=int, default=80,
                        help="size of the timed dataset of the default mission (default 80; 0: skip it)")
    parser.add_argument("--no-bag-10", action="store_true", help="also run the 10-UAV mission without bags")
    add_output(parser, metavar="DIR", old=("--keep-data",),
               help="keep the simulations' data (bags, CSVs) in a new folder under DIR, instead of a temporary "
                    "folder removed at the end")
    parser.add_argument("--time-limit", type=float, default=600.0,
                        help="wall seconds per simulation before magna run stops it (default 600)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not MAGNA.is_file():
        raise SystemExit(f"{MAGNA} is missing")
    if not MISSION_10.is_file():
        raise SystemExit(f"{MISSION_10} is missing")
    if args.output:
        args.output.mkdir(parents=True, exist_ok=True)
        data_root = Path(tempfile.mkdtemp(prefix="mission_batch_", dir=args.output))
    else:
        data_root = Path(tempfile.mkdtemp(prefix="mission_batch_"))
    print(f"{os.cpu_count()} cores; data under {data_root}", flush=True)
    speed: list[Batch] = []
    dataset = None
    try:
        # bags and --no-bag back to back (same seeds), so that the comparison sees the same machine
        speed.append(run_batch("2 UAVs, bags", 2, MISSION_2, args.repeats, True, data_root, "bag2",
                               args.time_limit))
        speed.append(run_batch("2 UAVs, --no-bag", 2, MISSION_2, args.repeats, False, data_root, "nobag2",
                               args.time_limit))
        speed.append(run_batch("10 UAVs, bags", 10, str(MISSION_10), args.repeats, True, data_root, "bag10",
                               args.time_limit))
        if args.no_bag_10:
            speed.append(run_batch("10 UAVs, --no-bag", 10, str(MISSION_10), args.repeats, False, data_root,
                                   "nobag10", args.time_limit))
        if args.simulations > 0:
            dataset = run_batch(f"dataset of {args.simulations}, 2 UAVs, bags", 2, MISSION_2, args.simulations, True,
                                data_root, "dataset", args.time_limit)
            speed.append(dataset)
    finally:
        size = sum(f.stat().st_size for f in data_root.rglob("*") if f.is_file()) / 1e6
        if args.output:
            print(f"data kept: {data_root} ({size:.0f} MB)", flush=True)
        else:
            shutil.rmtree(data_root, ignore_errors=True)
            print(f"data removed ({size:.0f} MB)", flush=True)

    print(f"\n(a) simulated time / wall time, whole ROS stack, rtf max, {os.cpu_count()} cores "
          f"(mission {MISSION_2} and its 10-UAV version)")
    head = (f"{'run':34} {'ended':>5} {'ok':>5} {'coll':>4} {'sim s':>6} {'setup s':>7} {'mission s':>9} "
            f"{'window s':>8} {'e2e s':>6} {'flight x':>8} {'mission x':>9} {'window x':>8} {'e2e x':>6} "
            f"{'target':>6}  {'ratio mission':>13} {'ratio window':>13}  {'load':>4}")
    print(head)
    print("-" * len(head))
    for b in speed:
        ended = b.ended
        n = len(ended) or 1

        def mean(values, n=n):
            return sum(values) / n

        target = TARGET_2 if b.uavs == 2 else TARGET_10
        print(f"{b.label:34} {len(ended):>2}/{len(b.sims):<2} {b.successes:>2}/{len(b.sims):<2} {b.collisions:>4} "
              f"{mean(s.sim_s for s in ended):>6.1f} {mean(s.setup_wall_s for s in ended):>7.1f} "
              f"{mean(s.mission_wall_s for s in ended):>9.1f} {mean(s.window_s for s in ended):>8.1f} "
              f"{mean(s.end_to_end_s for s in ended):>6.1f} {b.flight_factor:>7.1f}x {b.mission_factor:>8.1f}x "
              f"{b.window_factor:>7.1f}x {b.end_to_end_factor:>5.1f}x {target:>5.0f}x  "
              f"{fmt_ratio(b.mission_factor, target):>13} {fmt_ratio(b.window_factor, target):>13}  "
              f"{b.load_before:>4.1f}")
    bags, nobag, ten = speed[0], speed[1], speed[2]
    if bags.ended and nobag.ended:
        print(f"2 UAVs, bags / --no-bag (e2e factor): {bags.end_to_end_factor / nobag.end_to_end_factor:.2f}")
    if bags.ended and ten.ended:
        print(f"10 UAVs / 2 UAVs (e2e factor): {ten.end_to_end_factor / bags.end_to_end_factor:.2f}; "
              f"wall s per simulated s per UAV: 2 UAVs {1 / bags.end_to_end_factor / 2:.4f}, "
              f"10 UAVs {1 / ten.end_to_end_factor / 10:.4f}")
    print("ended = simulations the ground station ended (the factors are over these; a simulation stopped by the "
          "time limit or crashed is left out); ok = mission succeeded; coll = collisions reported\n"
          "sim s = simulated s of the mission; setup s = wall s of it standing still while UAVs are spawned and "
          "their managers start; mission s = wall s from the mission's first state to its end (setup included); "
          "flight x = sim s / (mission s - setup s); mission x = sim s / mission s\n"
          "window = launch -> ground station's report (summary.csv wall_time, as `magna run` prints it); "
          "e2e = the whole `magna run` process per simulation (master, start-up, clean-up); "
          "load = 1-min load average before the batch (2 cores: above 2, something else competes)")

    if dataset is not None:
        n = len(dataset.sims)
        windows = sum(s.window_s for s in dataset.sims)
        e2e = [s.end_to_end_s for s in dataset.sims]
        print(f"\n(b) a dataset of {args.simulations} simulations of {MISSION_2} (bags on), one `magna run`")
        print(f"{'simulations run':34} {n} ({dataset.successes} succeeded, {dataset.collisions} collisions, "
              f"exit status {dataset.exit_code})")
        scaled = dataset.wall_s * 80 / max(n, 1)
        print(f"{'wall time':34} {dataset.wall_s:8.1f} s = {dataset.wall_s / 60:5.1f} min   target "
              f"{TARGET_80_S / 60:.0f} min for 80   ratio {fmt_ratio(scaled, TARGET_80_S, False)}"
              + (" (scaled to 80)" if n != 80 else ""))
        if n:
            print(f"{'per simulation (average)':34} {dataset.wall_s / n:8.1f} s   "
                  f"(median {statistics.median(e2e):.1f}, min {min(e2e):.1f}, max {max(e2e):.1f})")
            print(f"{'  inside the window':34} {windows / n:8.1f} s   ({dataset.sim_s / n:.1f} simulated s)")
            print(f"{'  overhead outside the window':34} {(dataset.wall_s - windows) / n:8.1f} s   "
                  f"({100 * (dataset.wall_s - windows) / dataset.wall_s:.0f}% of the wall time: master, supervisor, "
                  "clean-up, process start)")
            print(f"{'time for 80 at this pace':34} {dataset.wall_s / n * 80 / 60:8.1f} min")
            stuck = [s for s in dataset.sims if s.timed_out or s.termination != "ground_station"]
            if stuck:
                rest = dataset.wall_s - sum(s.end_to_end_s for s in stuck)
                print(f"{'not ended by the ground station':34} {len(stuck)}: "
                      + ", ".join(f"#{s.id} {s.termination or '?'} after {s.end_to_end_s:.0f} s" for s in stuck))
                print(f"{'wall time without them':34} {rest:8.1f} s = {rest / 60:5.1f} min for {n - len(stuck)} "
                      f"({rest / max(n - len(stuck), 1) * 80 / 60:.1f} min for 80 at that pace)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
