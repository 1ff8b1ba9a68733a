"""How long `magna run` takes to stop after Ctrl-C, by the phase the simulation is in.

Runs `magna run --n-iter 1` of a short mission (one UAV takes off to 1.5 m and lands) again and again, sends
SIGINT (what Ctrl-C sends) when the simulation reaches a phase, and measures the wall time until `magna run`
has exited. The phases are read from the simulation's files, as the fault tests do: launch (its launch log
exists), flight (the ground station copied the mission), finishing (result.json exists). Prints the median
and the worst per phase; never fails on a time. The data goes to a temporary folder, removed at the end.

    python bench/interrupt_latency.py [--repeat 3] [--phases launch,flight,finishing]
"""
from __future__ import annotations

import argparse
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/interrupt_latency.py` from any Python: in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("magna_common",))

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

# the fault tests' mission, world and phases: what they interrupt is what this measures
from magna_common.storage_tree import simulation_dir  # noqa: E402
from tests.faults.batch_runs import PHASE_FILES, WORLD, dataset_dir  # noqa: E402
from tests.faults.batch_runs import SHORT_MISSION as MISSION  # noqa: E402


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python bench/interrupt_latency.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="interrupts per phase (default 3)")
    parser.add_argument("--phases", default="launch,flight,finishing",
                        help="comma-separated, of launch, flight, finishing (default all three)")
    return parser


def interrupt_once(phase: str, folder: Path) -> float:
    """Seconds from SIGINT, sent when the simulation entered `phase`, to `magna run`'s exit."""
    data_root = folder / "data"
    command = [str(ROOT / "magna"), "run", "--world", str(WORLD), "--mission", str(MISSION), "--rtf", "max",
               "--n-iter", "1", "--no-report", "--data-root", str(data_root)]
    with open(folder / "output.txt", "w") as output:
        run = subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                               start_new_session=True)
    try:
        marker = simulation_dir(dataset_dir(data_root), 1) / PHASE_FILES[phase]
        while not marker.is_file():
            if run.poll() is not None:
                raise RuntimeError(f"magna run ended before the {phase} phase: see {folder / 'output.txt'}")
            time.sleep(0.02)
        start = time.monotonic()
        run.send_signal(signal.SIGINT)
        run.wait(timeout=120)
        return time.monotonic() - start
    finally:
        if run.poll() is None:  # never leave a batch behind, even when the bench itself breaks
            run.send_signal(signal.SIGINT)
            run.wait(timeout=60)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    phases = [p.strip() for p in args.phases.split(",") if p.strip()]
    unknown = [p for p in phases if p not in PHASE_FILES]
    if unknown or args.repeat < 1:
        parser.error(f"--phases takes {', '.join(PHASE_FILES)}; --repeat at least 1 (got {args.phases!r}, "
                     f"{args.repeat})")
    print(f"SIGINT to `magna run` of {MISSION.name}, {args.repeat} per phase: seconds until it exited")
    print(f"{'phase':<10} {'median':>7} {'worst':>7}  each")
    for phase in phases:
        times = []
        for index in range(args.repeat):
            with tempfile.TemporaryDirectory(prefix="magna-interrupt-") as folder:
                times.append(interrupt_once(phase, Path(folder)))
            print(f"  {phase} {index + 1}/{args.repeat}: {times[-1]:.2f} s", file=sys.stderr, flush=True)
        print(f"{phase:<10} {statistics.median(times):7.2f} {max(times):7.2f}  {' '.join(f'{t:.2f}' for t in times)}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
