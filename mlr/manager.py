"""Manager: a config file -> pickled and prepared data (cached) -> every run of its sweep -> the
best run exported for the NAI.

Output, under `OUT` (default `<data_root>/mlr/runs/<config stem>`):
    <run name>/           one folder per run (mlr.train)
    results.csv, .md      one row per run
    best.json             the chosen run (best validation accuracy, then lower validation loss)
    <config stem>.pt/.json  the best network, exported (mlr.export)

A finished run whose config is unchanged is reused, not trained again; a finished run with a
different config, or an existing export, is kept unless `overwrite` is given. An export of the
best of unchanged finished runs is current: it is kept and the sweep goes on.
"""
from __future__ import annotations

import csv
import io
import json
import shutil
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from magna_common.files import write_text_atomically
from mlr import cache
from mlr.config import RunConfig, Sweep
from mlr.pickler import PicklerError, find_simulations
from mlr.train import RunResult, load_trained, train_run

Log = Callable[[str], None]


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@dataclass
class SweepOutcome:
    out: Path
    results: list[RunResult]
    best: RunResult | None
    exported: Path | None
    samples: dict[str, int]  # data key -> samples, per distinct dataset of the sweep


def _data_key(run: RunConfig) -> tuple:
    """What pickling and preprocessing depend on: runs equal here share their data."""
    return (run.selection, run.teacher, run.source, run.split, run.seed, run.normalization, run.features)


def _finished(run_dir: Path, run: RunConfig) -> RunResult | None:
    result_file = run_dir / "result.json"
    if not result_file.is_file():
        return None
    saved = json.loads(result_file.read_text())
    if saved.get("config") != run.as_dict():
        return None
    return RunResult(**saved["result"])


def _export_is_current(out: Path, sweep: Sweep, names: list[str]) -> Path | None:
    """The existing export, when every run is finished with its config and the export is of the best of them."""
    path = out / f"{sweep.name}.pt"
    spec = path.with_suffix(".json")
    if not path.is_file() or not spec.is_file():
        return None
    finished = [_finished(out / name, run) for name, run in zip(names, sweep.runs, strict=True)]
    results = [result for result in finished if result is not None]
    if len(results) < len(finished):
        return None
    best = max(results, key=lambda r: (r.val_accuracy, -r.val_loss))
    try:
        about = json.loads(spec.read_text()).get("about", {})
    except (OSError, json.JSONDecodeError):
        return None
    return path if about.get("run") == best.name and about.get("sweep") == str(sweep.source) else None


def _table(results: list[RunResult], runs: list[RunConfig], swept: tuple[str, ...]) -> tuple[str, str]:
    header = ["run", *swept, "best step", "val loss", "val acc", "test loss", "test acc", "params", "steps/s", "min"]
    rows = []
    for result, run in zip(results, runs, strict=True):
        values = [getattr(run, key) for key in swept]
        rows.append([result.name, *["-".join(map(str, v)) if isinstance(v, tuple) else v for v in values],
                     result.best_step, f"{result.val_loss:.5f}", f"{result.val_accuracy * 100:.2f}%",
                     f"{result.test_loss:.5f}", f"{result.test_accuracy * 100:.2f}%", result.parameters,
                     f"{result.steps_per_second:.0f}", f"{result.wall_seconds / 60:.1f}"])
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows([header, *rows])
    md = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    md += ["| " + " | ".join(map(str, row)) + " |" for row in rows]
    return out.getvalue(), "\n".join(md) + "\n"


def run_sweep(sweep: Sweep, out: Path | None = None, overwrite: bool = False, force_data: bool = False,
              export_best: bool = True, progress: bool = True, log: Log = _stderr) -> SweepOutcome:
    from tqdm import tqdm

    from mlr.export import export

    first = sweep.runs[0]
    out = Path(out) if out is not None else Path(first.data_root).expanduser() / "mlr" / "runs" / sweep.name
    names = [sweep.run_name(i) for i in range(len(sweep.runs))]
    # refuse before any work: a finished run of another config, or an existing export, is somebody's data
    if not overwrite:
        for name, run in zip(names, sweep.runs, strict=True):
            result_file = out / name / "result.json"
            if result_file.is_file() and _finished(out / name, run) is None:
                raise FileExistsError(f"{result_file}: a finished run with another config is there; pass "
                                      "--force to train it again, or give another -o/--output")
        if export_best and (out / f"{sweep.name}.pt").exists() and _export_is_current(out, sweep, names) is None:
            raise FileExistsError(f"{out / (sweep.name + '.pt')}: an exported network is there; pass --force "
                                  "to replace it, or give another -o/--output")
    out.mkdir(parents=True, exist_ok=True)
    data: dict[tuple, tuple] = {}
    counts: dict[str, int] = {}
    results: list[RunResult] = []
    for index, (name, run) in enumerate(zip(names, sweep.runs, strict=True)):
        key = _data_key(run)
        if key not in data:
            sims, skipped = find_simulations(run.selection)
            for reason in skipped:
                log(f"left out {reason}")
            if not sims:
                raise PicklerError(f"{run.selection.series_dir}: no usable simulation in datasets "
                                   f"{list(run.datasets)} (each needs world.json and a successful result.json)")
            samples, pickled_key, hit = cache.cached_samples(
                run.selection, run.teacher, run.source, sims, force=force_data,
                progress=lambda it: tqdm(it, desc="pickling", unit="sim", disable=not progress, leave=False))
            log(f"data: {len(samples)} samples of role {run.role} flown with {run.algorithm} from {len(sims)} "
                f"simulations ({'cached' if hit else 'pickled'}; {len(skipped)} left out)")
            prepared, hit = cache.cached_prepared(samples, pickled_key, run.selection.data_root, run.split, run.seed,
                                                  force=force_data, run=run)
            log(f"split: {len(prepared.train)} train, {len(prepared.val)} validation, {len(prepared.test)} test "
                f"({'cached' if hit else 'prepared'})")
            data[key] = (prepared, len(samples))
            counts[pickled_key] = len(samples)
        prepared = data[key][0]
        run_dir = out / name
        reused = None if overwrite else _finished(run_dir, run)
        if reused is not None:
            log(f"[{index + 1}/{len(sweep.runs)}] {name}: finished before, reused (test accuracy "
                f"{reused.test_accuracy * 100:.2f}%)")
            results.append(reused)
            continue
        if run_dir.exists():
            shutil.rmtree(run_dir)  # an interrupted run, or --force
        result = train_run(run, prepared, run_dir, name, progress=progress)
        log(f"[{index + 1}/{len(sweep.runs)}] {name}: test accuracy {result.test_accuracy * 100:.2f}%, val "
            f"{result.val_accuracy * 100:.2f}%, {result.steps} steps in {result.wall_seconds / 60:.1f} min "
            f"({result.steps_per_second:.0f} steps/s)")
        results.append(result)
    table_csv, table_md = _table(results, list(sweep.runs), sweep.swept)
    write_text_atomically(out / "results.csv", table_csv, overwrite=True)
    write_text_atomically(out / "results.md", table_md, overwrite=True)
    best_index = max(range(len(results)), key=lambda i: (results[i].val_accuracy, -results[i].val_loss))
    best = results[best_index]
    write_text_atomically(out / "best.json", json.dumps({"run": best.name, "result": asdict(best),
                                                         "config": sweep.runs[best_index].as_dict()}, indent=2)
                          + "\n", overwrite=True)
    exported = None if overwrite else _export_is_current(out, sweep, names)
    if exported is not None:
        log(f"best: {best.name}, exported before to {exported}")
    elif export_best:
        run = sweep.runs[best_index]
        prepared = data[_data_key(run)][0]
        net, _ = load_trained(Path(best.directory), prepared.train.x.shape[1])
        about = {"sweep": str(sweep.source), "run": best.name, "test_accuracy": best.test_accuracy,
                 "val_accuracy": best.val_accuracy, "teacher": f"{run.role}/{run.algorithm}",
                 "data": str(run.selection.series_dir), "datasets": list(run.datasets), "fvi": run.fvi}
        exported = export(net, run, prepared, out / f"{sweep.name}.pt", about=about, overwrite=overwrite)
        log(f"best: {best.name} (validation accuracy {best.val_accuracy * 100:.2f}%, test "
            f"{best.test_accuracy * 100:.2f}%), exported to {exported}")
    return SweepOutcome(out, results, best, exported, counts)
