"""What seeing a mission costs: reports in `magna run`, `magna report` alone, a headless replay.

In one run, on the default mission of `make run` (Gym/2UAVs_Crossing_ORCA in Gym/Central_Obstacle_Torus,
rtf max, bags on), into a temporary data root:
  (a) `./magna run --n-iter N --no-report` and `./magna run --n-iter N` (reports on), alternately
      --rounds times, same seeds: whole-process wall seconds per simulation and their ratio;
  (b) `magna report SIM --force` on one of those simulations, --repeats times: wall s per report
      (fresh process: imports, loading the bag and CSVs, six plots, the mission picture, the page);
  (c) `magna replay SIM --headless --speed S --every 2 --gif` once: wall s against the bag's length.
Prints figures; never fails on a time. About 4 minutes with the defaults.

    python bench/viz_cost.py [--simulations 3] [--rounds 2] [--repeats 3] [--speed 5]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/viz_cost.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__)

ROOT = Path(__file__).resolve().parent.parent
MAGNA = ROOT / "magna"
WORLD, MISSION = "Gym/Central_Obstacle_Torus", "Gym/2UAVs_Crossing_ORCA"


def timed(argv: list[str]) -> float:
    started = time.monotonic()
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, stdin=subprocess.DEVNULL)
    elapsed = time.monotonic() - started
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} exited {done.returncode}:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
    return elapsed


def batch(data_root: Path, name: str, n: int, report: bool) -> float:
    argv = [str(MAGNA), "run", "--world", WORLD, "--mission", MISSION, "--n-iter", str(n), "--rtf", "max",
            "--data-root", str(data_root), "--name", name, "--append"] + ([] if report else ["--no-report"])
    return timed(argv) / n


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--simulations", type=int, default=3, help="simulations per magna run (default 3)")
    parser.add_argument("--rounds", type=int, default=2, help="alternating rounds of (a) (default 2)")
    parser.add_argument("--repeats", type=int, default=3, help="magna report runs in (b) (default 3)")
    parser.add_argument("--speed", type=float, default=5.0, help="replay speed in (c) (default 5)")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="magna_viz_bench_") as tmp:
        data_root = Path(tmp)
        without, with_reports = [], []
        for r in range(args.rounds):
            print(f"(a) round {r + 1}/{args.rounds}", flush=True)
            without.append(batch(data_root, "no_report", args.simulations, report=False))
            with_reports.append(batch(data_root, "report", args.simulations, report=True))
        sims = sorted((data_root / "Simulations").glob("*/*/*/*/report/dataset_1/simulation_*"))
        sim = sims[0]
        report_s = [timed([str(MAGNA), "report", str(sim), "--force"]) for _ in range(args.repeats)]
        from rosbags.highlevel import AnyReader

        with AnyReader([sim / "simulation.bag"]) as reader:
            bag_s = (reader.end_time - reader.start_time) / 1e9
        replay_s = timed([str(MAGNA), "replay", str(sim), "--headless", "--speed", f"{args.speed:g}", "--every", "2",
                          "--gif", "--out", str(data_root / "replay")])

    a, b = statistics.median(without), statistics.median(with_reports)
    print("\n| what | wall s | compared |")
    print("|---|---|---|")
    print(f"| magna run, per simulation, --no-report (median of {args.rounds} x {args.simulations}) | {a:.1f} | 1.00 |")
    print(f"| magna run, per simulation, with reports | {b:.1f} | {b / a:.2f} (+{b - a:.1f} s) |")
    print(f"| magna report SIM --force, fresh process (median of {args.repeats}) | {statistics.median(report_s):.1f} "
          f"| {statistics.median(report_s) / a:.2f} of a simulation |")
    print(f"| magna replay --headless --speed {args.speed:g} --gif, {bag_s:.0f} s of bag | {replay_s:.1f} "
          f"| {bag_s / replay_s:.1f}x the bag's pace |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
