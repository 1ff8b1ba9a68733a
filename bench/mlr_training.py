"""How long one 20-30-20 network takes to train for 250,000 steps at batch 500 (target: < 10 min on 2 cores).

It trains on the four-cylinder thesis dataset when it is recorded (mlr/configs/thesis_four_cylinders.yaml),
else on synthetic samples of the same shape (12 inputs, 25,000 samples). First a short side-by-side of torch
thread counts (same steps, same run), then the full run with the faster count. Prints a table; never fails on a
time.

    python bench/mlr_training.py [--steps 250000] [--probe-steps 5000]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

if __name__ == "__main__":  # `python bench/mlr_training.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "torch", "magna_uav"))

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mlr import cache  # noqa: E402
from mlr.config import load_sweep  # noqa: E402
from mlr.pickler import PicklerError, Samples, find_simulations  # noqa: E402
from mlr.preprocess import prepare  # noqa: E402
from mlr.train import train_run  # noqa: E402

TARGET_SECONDS = 600.0


def data(run):
    try:
        sims, _ = find_simulations(run.selection)
        if sims:
            samples, key, _ = cache.cached_samples(run.selection, run.teacher, run.source, sims)
            prepared, _ = cache.cached_prepared(samples, key, run.selection.data_root, run.split, run.seed)
            return prepared, f"four-cylinder dataset ({len(samples)} samples, {len(sims)} simulations)"
    except PicklerError:
        pass
    rng = np.random.default_rng(0)
    n = 25000
    x = rng.normal(size=(n, 12))
    y = np.tanh(x[:, 3:6] + 0.3 * x[:, 6:9])
    synthetic = Samples(x, y, np.full(n, 2.0), np.zeros(n, dtype=int), np.arange(n), ["synthetic"])
    return prepare(synthetic), f"synthetic ({n} samples, 12 inputs: the four-cylinder dataset is not recorded)"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=250000)
    parser.add_argument("--probe-steps", type=int, default=5000)
    args = parser.parse_args()
    base = next(r for r in load_sweep(ROOT / "mlr/configs/thesis_four_cylinders.yaml").runs
                if r.hidden_layers == (20, 30, 20))
    base = replace(base, batch_size=500, eval_every=5000, lr_schedule="constant")
    prepared, what = data(base)
    print(f"data: {what}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        probes = {}
        for threads in (1, 2):
            run = replace(base, steps=args.probe_steps, threads=threads)
            result = train_run(run, prepared, Path(tmp) / f"probe{threads}", f"probe {threads} thread(s)")
            probes[threads] = result.steps_per_second
        best = max(probes, key=probes.get)
        print(f"{'threads':>8} {'steps/s':>9} {'vs 1 thread':>12}")
        for threads, speed in probes.items():
            print(f"{threads:>8} {speed:9.0f} {speed / probes[1]:11.2f}x")
        run = replace(base, steps=args.steps, threads=best)
        started = time.monotonic()
        result = train_run(run, prepared, Path(tmp) / "full", f"20-30-20, {args.steps} steps")
        wall = time.monotonic() - started
        rows.append((result, wall))
    result, wall = rows[0]
    print()
    print("| network | steps | batch | threads | wall | steps/s | test accuracy | target | ratio (target / wall) |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| 20-30-20 | {args.steps} | 500 | {best} | {wall / 60:.1f} min | {result.steps_per_second:.0f} | "
          f"{result.test_accuracy * 100:.1f}% | < {TARGET_SECONDS / 60:.0f} min | {TARGET_SECONDS / wall:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
