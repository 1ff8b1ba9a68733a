"""Whole-stack mission simulations against issue 27's targets: x real time with 2, 10 and 50 UAVs, the
overhead of each simulation outside its mission, a dataset of 80, memory per UAV and CPU by process.

Everything runs as a user runs it: `./magna run` (by default one persistent stack per batch: a ROS
master, magna_sim, the world node and ORCA-3D kept up and reset between simulations; a ground station
and its UAV managers per simulation), bags on, into a temporary data root, headless, rtf max. Side by
side in one run:

  (a) the simulated-time / wall-time factors of --repeats simulations (default 3) of
      * the default mission of `make run` (missions/Gym/2UAVs_Crossing_ORCA.json), 2 UAVs;
      * the same with `--cold-start` (a fresh master and launch per simulation), same seeds;
      * its 10-UAV version (bench/missions/Gym/10UAVs_Crossing_ORCA.json, world Gym/Central_Obstacle_Torus);
      * the 50-UAV crossing (bench/missions/Gym/50UAVs_Crossing_ORCA.json in bench/worlds/Gym/Big_Crossing,
        found with --search-path bench; --skip-50 leaves it out, and so does a missing file, said so);
      * and the batches of the overheads and of (b);
      four factors each, simulated s of the mission over wall s of:
        "flight"  the mission while simulated time ran (its setup left out: the simulator
                  stands still while UAVs are spawned and their managers start);
        "mission" the mission from its first state to its end, setup included;
        "window"  the launch (or the stack's reset) to the ground station's report (what `magna run`
                  prints);
        "e2e"     the whole `magna run` process per simulation: the time between two progress lines,
                  the first one from the process's start (master, stack), the last one to its exit
                  (stack stopped, pictures, index);
      all over the simulations the ground station ended (one stopped by --time-limit is left out).
      Beside them: the physics-only factor of magna_sim for the same number of light UAVs, measured
      just before each batch (bench/sim_speed.py's physics_steps_per_second / 240 Hz, for
      --physics-seconds), and the stack's share of the wall time while flying, 1 - flight / physics.
  Overheads: over a batch of --overhead-batch two-UAV simulations (default 20), the mean and the max of
      window - mission and e2e - window; and report.html's time per simulation, measured apart (written
      again for a few of them; `magna run` draws it in a worker thread while the next simulation runs,
      so only the last one's falls in e2e, and the others take their share of the cores).
  (b) the wall time of one `magna run` of --simulations (default 80) of the default mission, the
      average per simulation, and how many ran on a warm stack or started cold (result.json's
      stack.start; a result without it ran on the cold path).
  For 10 and 50 UAVs: memory per UAV (the resident sum of the simulation's processes at its peak over
  the UAVs) and CPU seconds by kind of process, sampled from /proc every 0.5 s (bench/process_usage.py).

Targets (issue 27, 2 cores, bags on): e2e >= 15x with 2 UAVs, >= 8x with 10, >= 1.5x with 50;
window - mission and e2e - window <= 1 s each in a batch of 20; 80 simulations in <= 5 min (300 s).
Each figure is printed with its target, met or missed and the ratio (>= 1 is met). Prints figures;
never fails on a time. The default run takes about 20-30 minutes on 2 cores; --simulations 0,
--overhead-batch 0 and --skip-50 leave parts out.

    python bench/mission_batch.py [--repeats 3] [--simulations 80] [--overhead-batch 20] [--skip-50]
        [--repeats-50 N] [--no-bag-2] [--no-bag-10] [--physics-seconds 3] [--time-limit 600] [-o DIR]
"""
from __future__ import annotations

import argparse
import csv
import json
import math
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

    run_script_in_workspace(__file__, modules=("magna_sim", "magna_viz"))

ROOT = Path(__file__).resolve().parent.parent
MAGNA = ROOT / "magna"
WORLD = "Gym/Central_Obstacle_Torus"
MISSION_2 = "Gym/2UAVs_Crossing_ORCA"  # the default of `make run`
MISSION_10 = ROOT / "bench" / "missions" / "Gym" / "10UAVs_Crossing_ORCA.json"
MISSION_50 = ROOT / "bench" / "missions" / "Gym" / "50UAVs_Crossing_ORCA.json"
WORLD_50 = "Gym/Big_Crossing"  # found under bench/worlds/ with --search-path bench
WORLD_50_FILE = ROOT / "bench" / "worlds" / "Gym" / "Big_Crossing.json"
TARGET_E2E = {2: 15.0, 10: 8.0, 50: 1.5}  # x real time, per simulation, the whole `magna run`
TARGET_OVERHEAD_S = 1.0  # wall s each: window - mission, e2e - window
TARGET_80_S = 300.0  # wall s for a dataset of 80 two-UAV simulations
PHYSICS_RATE = 240.0  # Hz, magna_sim's default physics step
REPORTS_TIMED = 3  # simulations whose report.html is written again to time it


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
    stack_start: str = "cold"  # result.json stack.start: "warm" on a kept stack; absent: the cold path

    @property
    def flight_wall_s(self) -> float:
        return self.mission_wall_s - self.setup_wall_s


@dataclass
class Batch:
    label: str
    uavs: int
    wall_s: float  # the whole `magna run` process
    exit_code: int
    sims: list[Simulation] = field(default_factory=list)
    load_before: float = 0.0
    dataset_dir: Path | None = None
    tail_s: float = 0.0  # wall s from the last progress line to the process's exit (in the last e2e)
    usage: object = None  # process_usage.Usage when sampled
    physics_factor: float = float("nan")  # magna_sim's physics alone with as many light UAVs, just before

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
        return self._factor(lambda s: s.flight_wall_s)

    @property
    def mission_factor(self) -> float:
        return self._factor(lambda s: s.mission_wall_s)

    @property
    def window_factor(self) -> float:
        return self._factor(lambda s: s.window_s)

    @property
    def end_to_end_factor(self) -> float:
        return self._factor(lambda s: s.end_to_end_s)

    @property
    def successes(self) -> int:
        return sum(s.success for s in self.sims)

    @property
    def collisions(self) -> int:
        return sum(s.collisions for s in self.sims)

    def starts(self) -> dict[str, int]:
        counts = {"warm": 0, "cold": 0}
        for s in self.sims:
            counts[s.stack_start] = counts.get(s.stack_start, 0) + 1
        return counts


def stack_start(result: dict) -> str:
    """"warm" or "cold" from result.json (the batch's extra fields may be kept apart or at the top)."""
    stack = (result.get("extra") or {}).get("stack") or result.get("stack") or {}
    return str(stack.get("start") or "cold")


def run_batch(label: str, uavs: int, mission: str, n: int, data_root: Path, name: str, time_limit: float, *,
              world: str = WORLD, options: tuple[str, ...] = (), sample: bool = False) -> Batch:
    """One `./magna run` of n simulations; the time each simulation ends is read from its progress line.
    With `sample`, its processes' CPU and memory are sampled from /proc as it runs."""
    argv = [str(MAGNA), "run", "--world", world, "--mission", mission, "--n-iter", str(n), "--rtf", "max",
            "--data-root", str(data_root), "--name", name, "--append", "--time-limit", f"{time_limit:g}", *options]
    load = os.getloadavg()[0]
    print(f"-- {label}: {n} simulation(s) ({' '.join(argv[1:])}); load average {load:.1f}", flush=True)
    ends: dict[int, float] = {}
    started = time.monotonic()
    # stderr (not a terminal): magna run prints "simulation M (k/N): ..." when each one ends
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
                               stdin=subprocess.DEVNULL)
    sampler = process_usage().ProcessSampler(process.pid) if sample else None
    output = []
    try:
        if sampler is not None:
            sampler.__enter__()
        assert process.stdout is not None
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
    finally:
        if sampler is not None:
            sampler.__exit__(None, None, None)
    wall = time.monotonic() - started
    if code != 0:
        print("".join(output[-20:]), end="", flush=True)
        print(f"   magna run exited with status {code}", flush=True)
    batch = Batch(label, uavs, wall, code, load_before=load, usage=sampler.usage() if sampler else None)
    summaries = list(data_root.glob(f"Simulations/**/{name}/dataset_1/summary.csv"))
    if not summaries:
        print(f"   no summary.csv under {data_root}", flush=True)
        return batch
    batch.dataset_dir = summaries[0].parent
    previous = 0.0
    with open(summaries[0], newline="") as f:
        for row in csv.DictReader(f):
            m = int(row["id"])
            end = ends.get(m, previous)
            try:
                result = json.loads((batch.dataset_dir / f"simulation_{m}" / "result.json").read_text())
            except (OSError, ValueError):
                result = {}
            batch.sims.append(Simulation(m, row["success"] == "True", row["outcome"], float(row["duration"] or 0),
                                         float(row["wall_time"] or 0), end - previous, int(row["collisions"] or 0),
                                         str(result.get("termination", "")), bool(result.get("timed_out")),
                                         float(result.get("mission_wall_time", 0.0)),
                                         float(result.get("setup_wall_time", 0.0)), stack_start(result)))
            previous = end
    if batch.sims:  # the process's exit belongs to its simulations too: the last one carries it
        batch.tail_s = wall - previous
        batch.sims[-1].end_to_end_s += batch.tail_s
    return batch


def load_bench(name: str):
    """Another bench script as a module, as tests/test_bench_cli.py loads them."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from tests.support import load_module

    return sys.modules.get(f"bench_{name}") or load_module(ROOT / "bench" / f"{name}.py", f"bench_{name}")


def process_usage():
    return load_bench("process_usage")


def physics_factor(uavs: int, seconds: float) -> float:
    """magna_sim's physics alone with `uavs` light UAVs manoeuvring: simulated s per wall s."""
    return load_bench("sim_speed").physics_steps_per_second("light", uavs, seconds) / PHYSICS_RATE


def report_seconds(batch: Batch | None) -> list[float]:
    """Wall s to write report.html again for a few of the batch's simulations (magna_viz imported first)."""
    if batch is None or batch.dataset_dir is None:
        return []
    from magna_viz.report import write_report

    folders = [batch.dataset_dir / f"simulation_{s.id}" for s in batch.ended[:REPORTS_TIMED]]
    seconds = []
    for folder in folders:
        started = time.perf_counter()
        try:
            write_report(folder, overwrite=True)
        except Exception as error:  # a figure, not a check: say why and go on
            print(f"   report of {folder.name} not written: {error}", flush=True)
            continue
        seconds.append(time.perf_counter() - started)
    return seconds


def fmt_ratio(value: float, target: float, higher_is_better: bool = True) -> str:
    """The measured value over its target (the target over it when lower is better): >= 1 is met."""
    if math.isnan(value):
        return "    - no data"
    if higher_is_better:
        ratio = value / target
    else:
        ratio = target / value if value > 0 else math.inf
    return f"{ratio:5.2f} {'met' if ratio >= 1.0 else 'missed'}"


def build_parser() -> argparse.ArgumentParser:
    from magna_common.cli_vocabulary import add_output

    parser = argparse.ArgumentParser(prog="python bench/mission_batch.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3,
                        help="simulations per speed measurement of table (a) (default 3)")
    parser.add_argument("--repeats-50", type=int, default=None, metavar="N",
                        help="simulations of the 50-UAV crossing (default: --repeats)")
    parser.add_argument("--skip-50", action="store_true", help="leave the 50-UAV crossing out")
    parser.add_argument("--overhead-batch", type=int, default=20, metavar="N",
                        help="two-UAV simulations in the batch whose overheads are measured (default 20; 0: skip)")
    parser.add_argument("--simulations", type=int, default=80,
                        help="size of the timed dataset (b) of the default mission (default 80; 0: skip it)")
    parser.add_argument("--no-bag-2", action="store_true", help="also run the 2-UAV mission without bags")
    parser.add_argument("--no-bag-10", action="store_true", help="also run the 10-UAV mission without bags")
    parser.add_argument("--physics-seconds", type=float, default=3.0,
                        help="wall seconds of each physics-only measurement (default 3)")
    add_output(parser, metavar="DIR", old=("--keep-data",),
               help="keep the simulations' data (bags, CSVs) in a new folder under DIR, instead of a temporary "
                    "folder removed at the end")
    parser.add_argument("--time-limit", type=float, default=600.0,
                        help="wall seconds per simulation before magna run stops it (default 600)")
    return parser


def fifty_missing() -> str:
    """Why the 50-UAV crossing cannot run (empty: it can)."""
    missing = [str(p.relative_to(ROOT)) for p in (MISSION_50, WORLD_50_FILE) if not p.is_file()]
    return f"{' and '.join(missing)} missing" if missing else ""


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not MAGNA.is_file():
        raise SystemExit(f"{MAGNA} is missing")
    if not MISSION_10.is_file():
        raise SystemExit(f"{MISSION_10} is missing")
    fifty = "" if args.skip_50 else fifty_missing()
    run_fifty = not args.skip_50 and not fifty
    if args.output:
        args.output.mkdir(parents=True, exist_ok=True)
        data_root = Path(tempfile.mkdtemp(prefix="mission_batch_", dir=args.output))
    else:
        data_root = Path(tempfile.mkdtemp(prefix="mission_batch_"))
    print(f"{os.cpu_count()} cores; data under {data_root}", flush=True)
    if args.skip_50:
        print("-- 50 UAVs: skipped (--skip-50)", flush=True)
    elif fifty:
        print(f"-- 50 UAVs: skipped, {fifty} (bench/missions/make_crossing.py writes the mission)", flush=True)

    speed: list[Batch] = []
    warm2 = cold2 = ten = big = overhead = dataset = None
    reports: list[float] = []

    def batch(label, uavs, mission, n, name, **kwargs) -> Batch:
        # the physics alone right before its batch, so that both see the same machine
        physics = physics_factor(uavs, args.physics_seconds)
        print(f"-- physics only, {uavs} light UAVs: {physics:.1f}x", flush=True)
        b = run_batch(label, uavs, mission, n, data_root, name, args.time_limit, **kwargs)
        b.physics_factor = physics
        speed.append(b)
        return b

    try:
        # the persistent stack and --cold-start back to back (same seeds), so that both see the same machine
        warm2 = batch("2 UAVs", 2, MISSION_2, args.repeats, "uavs2")
        cold2 = batch("2 UAVs, --cold-start", 2, MISSION_2, args.repeats, "uavs2_cold", options=("--cold-start",))
        if args.no_bag_2:
            batch("2 UAVs, --no-bag", 2, MISSION_2, args.repeats, "uavs2_nobag", options=("--no-bag",))
        ten = batch("10 UAVs", 10, str(MISSION_10), args.repeats, "uavs10", sample=True)
        if args.no_bag_10:
            batch("10 UAVs, --no-bag", 10, str(MISSION_10), args.repeats, "uavs10_nobag", options=("--no-bag",))
        if run_fifty:
            big = batch("50 UAVs", 50, str(MISSION_50),
                        args.repeats if args.repeats_50 is None else args.repeats_50, "uavs50", world=WORLD_50,
                        options=("--search-path", str(ROOT / "bench")), sample=True)
        if args.overhead_batch > 0:
            overhead = batch(f"2 UAVs, batch of {args.overhead_batch}", 2, MISSION_2, args.overhead_batch,
                             "overhead")
        reports = report_seconds(overhead or warm2)
        if args.simulations > 0:
            dataset = batch(f"2 UAVs, dataset of {args.simulations}", 2, MISSION_2, args.simulations, "dataset")
    finally:
        size = sum(f.stat().st_size for f in data_root.rglob("*") if f.is_file()) / 1e6
        if args.output:
            print(f"data kept: {data_root} ({size:.0f} MB)", flush=True)
        else:
            shutil.rmtree(data_root, ignore_errors=True)
            print(f"data removed ({size:.0f} MB)", flush=True)

    print_speed(speed)
    if warm2 and cold2 and warm2.ended and cold2.ended:
        print(f"2 UAVs, e2e with the persistent stack {warm2.end_to_end_factor:.1f}x "
              f"({mean_of(warm2.ended, 'end_to_end_s'):.1f} s per simulation) vs --cold-start "
              f"{cold2.end_to_end_factor:.1f}x ({mean_of(cold2.ended, 'end_to_end_s'):.1f} s), same seeds: "
              f"persistent / cold {warm2.end_to_end_factor / cold2.end_to_end_factor:.2f}")
    if overhead is not None:
        print_overheads(overhead, reports)
    elif reports:
        print(f"\nreport.html, written again apart: {statistics.mean(reports):.2f} s per simulation "
              f"(mean of {len(reports)})")
    if dataset is not None:
        print_dataset(dataset, args.simulations)
    for b in (ten, big):
        if b is not None and b.usage is not None:
            print(f"\nmemory and CPU, {b.label} ({len(b.sims)} simulation(s), every process of the `magna run`)")
            process_usage().print_usage(b.usage, b.uavs, max(len(b.sims), 1))
    if fifty:
        print(f"\n50 UAVs: not measured, {fifty}")
    elif args.skip_50:
        print("\n50 UAVs: not measured (--skip-50)")
    return 0


def fmt(value: float, width: int, unit: str = "", digits: int = 1) -> str:
    """A table cell: the value with its unit, or '-' when there is none."""
    text = "-" if math.isnan(value) else f"{value:.{digits}f}{unit}"
    return f"{text:>{width}}"


def mean_of(sims: list[Simulation], name: str) -> float:
    return statistics.mean(getattr(s, name) for s in sims) if sims else float("nan")


def print_speed(speed: list[Batch]) -> None:
    print(f"\n(a) simulated time / wall time, whole ROS stack, bags on unless said, rtf max, {os.cpu_count()} cores")
    head = (f"{'run':30} {'ended':>5} {'ok':>5} {'coll':>4} {'warm':>4} {'sim s':>6} {'flight s':>8} "
            f"{'mission s':>9} {'window s':>8} {'e2e s':>6} {'flight x':>8} {'mission x':>9} {'window x':>8} "
            f"{'e2e x':>6} {'target':>6} {'ratio e2e':>12} {'physics x':>9} {'stack':>5} {'load':>4}")
    print(head)
    print("-" * len(head))
    for b in speed:
        ended = b.ended
        target = TARGET_E2E.get(b.uavs, float("nan"))
        rate = b.physics_factor
        share = 100 * (1 - b.flight_factor / rate)
        print(f"{b.label:30} {len(ended):>2}/{len(b.sims):<2} {b.successes:>2}/{len(b.sims):<2} {b.collisions:>4} "
              f"{b.starts()['warm']:>4} {fmt(mean_of(ended, 'sim_s'), 6)} {fmt(mean_of(ended, 'flight_wall_s'), 8)} "
              f"{fmt(mean_of(ended, 'mission_wall_s'), 9)} {fmt(mean_of(ended, 'window_s'), 8)} "
              f"{fmt(mean_of(ended, 'end_to_end_s'), 6)} {fmt(b.flight_factor, 8, 'x')} "
              f"{fmt(b.mission_factor, 9, 'x')} {fmt(b.window_factor, 8, 'x')} {fmt(b.end_to_end_factor, 6, 'x')} "
              f"{fmt(target, 6, 'x')} {fmt_ratio(b.end_to_end_factor, target):>12} {fmt(rate, 9, 'x')} "
              f"{fmt(share, 5, '%', 0)} {b.load_before:>4.1f}")
    for b in speed:
        for s in b.sims:
            if s not in b.ended:
                print(f"{b.label}: simulation {s.id} left out, it ended {s.termination or '?'} ({s.outcome}) after "
                      f"{s.end_to_end_s:.0f} wall s, {s.sim_s:.1f} simulated s")
    print("ended = simulations the ground station ended (the factors are over these); ok = mission succeeded; "
          "coll = collisions; warm = simulations run on a kept stack\n"
          "sim s = simulated s of the mission; flight s = wall s of it while simulated time ran; mission s = wall s "
          "from its first state to its end (setup included: spawning, managers' start); window = launch or reset -> "
          "the ground station's report (summary.csv wall_time); e2e = the `magna run` process per simulation\n"
          "target / ratio e2e = issue 27's e2e target for that many UAVs, e2e x / target (>= 1 met); physics x = "
          "magna_sim's physics alone with as many light UAVs, measured just before the batch; stack = 1 - flight x "
          "/ physics x, the share of the flight's wall time spent outside the physics; load = 1-min load average "
          "before the batch")


def print_overheads(batch: Batch, reports: list[float]) -> None:
    ended = batch.ended
    print(f"\nOverheads per simulation outside its mission, {batch.label} ({len(ended)} ended of {len(batch.sims)}; "
          f"target <= {TARGET_OVERHEAD_S:g} s each)")
    rows = [("window - mission", [s.window_s - s.mission_wall_s for s in ended]),
            ("e2e - window", [s.end_to_end_s - s.window_s for s in ended])]
    for name, values in rows:
        if not values:
            print(f"{name:34} no ended simulation")
            continue
        worst = max(range(len(values)), key=lambda i: values[i])
        mean = statistics.mean(values)
        print(f"{name:34} mean {mean:5.2f} s  ratio {fmt_ratio(mean, TARGET_OVERHEAD_S, False)}   "
              f"max {values[worst]:5.2f} s (simulation {ended[worst].id})  "
              f"ratio {fmt_ratio(values[worst], TARGET_OVERHEAD_S, False)}")
    print(f"{'  of e2e: before the first':34} {ended[0].end_to_end_s - ended[0].window_s if ended else 0:5.2f} s "
          f"(process start, master, stack); after the last progress line {batch.tail_s:.2f} s (stack stop, "
          "pictures, index.html), both in the figures above")
    if reports:
        print(f"{'report.html, written again apart':34} mean {statistics.mean(reports):5.2f} s, "
              f"max {max(reports):5.2f} s over {len(reports)} (in e2e - window when written in the loop)")


def print_dataset(dataset: Batch, size: int) -> None:
    n = len(dataset.sims)
    e2e = [s.end_to_end_s for s in dataset.sims]
    starts = dataset.starts()
    print(f"\n(b) a dataset of {size} simulations of {MISSION_2} (bags on), one `magna run`")
    print(f"{'simulations run':34} {n} ({dataset.successes} succeeded, {dataset.collisions} collisions, "
          f"exit status {dataset.exit_code}); {starts['warm']} on a warm stack, {starts['cold']} started cold")
    scaled = dataset.wall_s * 80 / max(n, 1)
    print(f"{'wall time':34} {dataset.wall_s:8.1f} s = {dataset.wall_s / 60:5.1f} min   target "
          f"{TARGET_80_S:.0f} s for 80 (was 20 min)   ratio {fmt_ratio(scaled, TARGET_80_S, False)}"
          + (f" (scaled to 80: {scaled:.0f} s)" if n != 80 else ""))
    if not n:
        return
    print(f"{'per simulation (mean)':34} {dataset.wall_s / n:8.1f} s   "
          f"(median {statistics.median(e2e):.1f}, min {min(e2e):.1f}, max {max(e2e):.1f}; "
          f"{dataset.sim_s / n:.1f} simulated s)")
    windows = sum(s.window_s for s in dataset.sims)
    print(f"{'  outside the windows':34} {(dataset.wall_s - windows) / n:8.1f} s   "
          f"({100 * (dataset.wall_s - windows) / dataset.wall_s:.0f}% of the wall time)")
    stuck = [s for s in dataset.sims if s.timed_out or s.termination != "ground_station"]
    if stuck:
        rest = dataset.wall_s - sum(s.end_to_end_s for s in stuck)
        print(f"{'not ended by the ground station':34} {len(stuck)}: "
              + ", ".join(f"#{s.id} {s.termination or '?'} after {s.end_to_end_s:.0f} s" for s in stuck))
        print(f"{'wall time without them':34} {rest:8.1f} s for {n - len(stuck)} "
              f"({rest / max(n - len(stuck), 1) * 80:.0f} s for 80 at that pace)")


if __name__ == "__main__":
    sys.exit(main())
