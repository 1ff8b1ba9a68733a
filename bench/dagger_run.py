"""A whole DAgger run, from the teacher's recorded dataset to the final table (target: <= 45 min on 2 cores).

It runs `magna learn dagger CONFIG` into a fresh output folder (nothing reused), times it, and prints the
DAgger table, the wall time per part (training, flights and evaluation) and the ratio to the target. The
teacher's dataset must be recorded first (the config's comment says how); without it, it says so and exits 2.
Never fails on a time.

    python bench/dagger_run.py [--config mlr/configs/dagger_central_obstacle_margin06.yaml]
        [--search-path ../shared/ros_magna_corpus] [--data-root DIR] [--iterations N] [--flights N]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/dagger_run.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "torch", "magna_uav", "yaml"))

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mlr.dagger import DaggerError, load_config  # noqa: E402
from mlr.pickler import find_simulations  # noqa: E402

TARGET_SECONDS = 45 * 60.0
CORPUS = ROOT.parent / "shared" / "ros_magna_corpus"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", type=Path,
                        default=ROOT / "mlr" / "configs" / "dagger_central_obstacle_margin06.yaml")
    parser.add_argument("--search-path", type=Path, action="append",
                        help=f"where the ROS-MAGNA files are (default {CORPUS} when it exists)")
    parser.add_argument("--data-root", type=Path, help="where the teacher's Simulations/ are (default: the config's)")
    parser.add_argument("--iterations", type=int, help="override the config's iterations")
    parser.add_argument("--flights", type=int, help="override the config's flights per iteration")
    args = parser.parse_args()
    search = args.search_path or ([CORPUS] if CORPUS.is_dir() else [])
    overrides = {"data_root": str(args.data_root) if args.data_root else None}
    try:
        config = load_config(args.config, overrides)
    except DaggerError as err:
        print(f"dagger_run: {err}", file=sys.stderr)
        return 2
    sims, _ = find_simulations(config.run.selection) if config.run.selection.dataset_dirs()[0].is_dir() else ([], [])
    if not sims:
        print(f"dagger_run: no teacher dataset in {config.run.selection.dataset_dirs()[0]}: record it first, e.g. "
              f"magna learn thesis --search-path {CORPUS} --only central_obstacle --stages datasets"
              + (f" --data-root {args.data_root}" if args.data_root else ""), file=sys.stderr)
        return 2
    data_root = Path(config.run.data_root).expanduser()
    out = data_root / "mlr" / "dagger_bench" / time.strftime("%Y%m%d-%H%M%S")
    command = [sys.executable, "-m", "mlr", "dagger", str(args.config), "-o", str(out), "--quiet",
               "--data-root", str(data_root)]
    for path in search:
        command += ["--search-path", str(path)]
    for key in ("iterations", "flights"):
        if getattr(args, key) is not None:
            command += [f"--{key}", str(getattr(args, key))]
    print(f"dagger_run: {len(sims)} teacher simulations; {' '.join(command)}", flush=True)
    started = time.monotonic()
    code = subprocess.call(command, cwd=ROOT, env=dict(os.environ, MAGNA_ROOT=str(ROOT)))
    wall = time.monotonic() - started
    if code != 0:
        print(f"dagger_run: magna learn dagger ended with status {code} after {wall / 60:.1f} min", file=sys.stderr)
        return code
    results = json.loads((out / "results.json").read_text())
    training = sum(row["accuracy"]["train_seconds"] for row in results["iterations"])
    print()  # the table of the run is printed above, by magna learn dagger
    print(f"| figure | measured | target | ratio (target / measured) |\n|---|---|---|---|\n"
          f"| whole run, teacher's dataset to final table | {wall / 60:.1f} min | <= {TARGET_SECONDS / 60:.0f} min | "
          f"{TARGET_SECONDS / wall:.2f} ({'met' if wall <= TARGET_SECONDS else 'missed'}) |\n"
          f"| of which training ({len(results['iterations'])} networks) | {training / 60:.1f} min | | |\n"
          f"| of which flying, relabelling and evaluating | {(wall - training) / 60:.1f} min | | |")
    print(f"\ndagger_run: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
