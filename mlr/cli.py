"""`python -m mlr` and `magna learn`: the learning pipeline's commands.

    train CONFIG     pickle and preprocess (cached), train every run of the sweep, export the best
    pickle CONFIG    only build the samples and say what they hold
    export RUN_DIR   export one finished run for the NAI
    fly              fly a mission with a network and with ORCA-3D, side by side
    thesis           reproduce the thesis experiment (datasets, architectures, flights)
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HELP = "learn navigation networks from recorded missions (torch): train, pickle, export, fly, thesis"


class CliError(Exception):
    """Bad input: printed as `mlr: <message>`, exit status 2."""


def _overrides(args) -> dict:
    out = {}
    for key in ("data_root", "steps"):
        value = getattr(args, key, None)
        if value is not None:
            out[key] = value
    return out


def _load(args):
    from mlr.config import load_sweep

    return load_sweep(args.config, _overrides(args))


def cmd_train(args) -> int:
    from mlr.manager import run_sweep

    sweep = _load(args)
    print(f"{sweep.source}: {len(sweep.runs)} run(s)" + (f", sweeping {', '.join(sweep.swept)}" if sweep.swept else ""),
          file=sys.stderr)
    if args.dry_run:
        for i in range(len(sweep.runs)):
            print(sweep.run_name(i))
        return 0
    outcome = run_sweep(sweep, args.out, overwrite=args.overwrite, force_data=args.force_data,
                        export_best=not args.no_export, progress=not args.quiet)
    print((outcome.out / "results.md").read_text(), end="")
    print(f"results: {outcome.out / 'results.csv'}; TensorBoard: tensorboard --logdir {outcome.out}")
    if outcome.exported:
        print(f"network: {outcome.exported} (fly it: mlr fly --model {outcome.exported} ...)")
    return 0


def cmd_pickle(args) -> int:
    import numpy as np

    from magna_uav.nai.inputs import input_names
    from mlr import cache
    from mlr.pickler import find_simulations

    sweep = _load(args)
    seen = set()
    for run in sweep.runs:
        key = (run.selection, run.teacher, run.source)
        if key in seen:
            continue
        seen.add(key)
        sims, skipped = find_simulations(run.selection)
        for reason in skipped:
            print(f"left out {reason}", file=sys.stderr)
        samples, pickled_key, hit = cache.cached_samples(run.selection, run.teacher, run.source, sims,
                                                         force=args.force_data)
        names = input_names(run.role, run.n_neighbors, run.n_obstacles)
        print(f"{run.selection.series_dir} datasets {list(run.datasets)}: {len(sims)} simulations, "
              f"{len(samples)} samples of {run.role}/{run.algorithm} (fvi {run.fvi}), "
              f"{'from the cache' if hit else 'pickled'} [{pickled_key}]")
        if len(samples):
            print(f"{'input':<24} {'mean':>9} {'min':>9} {'max':>9}")
            for k, name in enumerate(names):
                column = samples.x[:, k]
                print(f"{name:<24} {column.mean():9.3f} {column.min():9.3f} {column.max():9.3f}")
            speed = np.linalg.norm(samples.y, axis=1)
            print(f"label sel_vel: |v| mean {speed.mean():.3f} m/s, max {speed.max():.3f} m/s")
        if args.output:
            path = Path(args.output)
            if path.exists() and not args.overwrite:
                raise CliError(f"{path}: already exists; pass --overwrite to replace it")
            cache.save_samples(samples, path)
            print(f"samples written to {path}")
    return 0


def cmd_export(args) -> int:
    from mlr import cache
    from mlr.export import export
    from mlr.pickler import find_simulations
    from mlr.train import load_trained, trained_config

    run_dir = Path(args.run_dir)
    if not (run_dir / "checkpoint.pt").is_file():
        raise CliError(f"{run_dir}: no checkpoint.pt: give the folder of a run trained by 'mlr train'")
    saved = json.loads((run_dir / "result.json").read_text()) if (run_dir / "result.json").is_file() else {}
    run = trained_config(run_dir)
    sims, _ = find_simulations(run.selection)
    samples, key, _ = cache.cached_samples(run.selection, run.teacher, run.source, sims)
    prepared, _ = cache.cached_prepared(samples, key, run.selection.data_root, run.split, run.seed)
    net, _ = load_trained(run_dir, prepared.train.x.shape[1])
    about = {"run": run_dir.name, "data": str(run.selection.series_dir), **saved.get("result", {})}
    path = export(net, run, prepared, args.output, about=about, overwrite=args.overwrite)
    print(f"network: {path} and its spec {path.with_suffix('.json')} (checked against the trained run)")
    return 0


def _add_config_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", help="hyperparameter file, YAML or JSON (see mlr/README.md and mlr/configs/)")
    parser.add_argument("--data-root", help="where Simulations/ is (overrides the config's data_root)")
    parser.add_argument("--force-data", action="store_true", help="pickle and preprocess again even if cached")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="mlr_command", metavar="COMMAND", title="commands")
    train = sub.add_parser("train", help="train every run of a config's sweep and export the best",
                           description="Pickle and preprocess (only when the inputs changed), train every "
                                       "combination of the config, log to TensorBoard, export the best run.")
    _add_config_arguments(train)
    train.add_argument("--out", type=Path, help="output folder (default: DATA_ROOT/mlr/runs/<config name>)")
    train.add_argument("--steps", type=int, help="training steps of every run (overrides the config)")
    train.add_argument("--overwrite", action="store_true", help="train again runs that finished with another "
                                                                "config, and replace the export")
    train.add_argument("--no-export", action="store_true", help="do not export the best run")
    train.add_argument("--dry-run", action="store_true", help="list the runs of the sweep and stop")
    train.add_argument("--quiet", action="store_true", help="no progress bars")
    train.set_defaults(_mlr_run=cmd_train)

    pickle = sub.add_parser("pickle", help="build the samples of a config and describe them",
                            description="Select the simulations, turn the teacher's steps into input vectors "
                                        "and labels (cached), and print what they hold.")
    _add_config_arguments(pickle)
    pickle.add_argument("--output", help="also write the samples to this .npz")
    pickle.add_argument("--overwrite", action="store_true", help="replace --output if it exists")
    pickle.set_defaults(_mlr_run=cmd_pickle)

    exp = sub.add_parser("export", help="export one trained run as TorchScript + JSON spec for the NAI",
                         description="Export the best checkpoint of a run folder; the export is checked against "
                                     "the trained network and loaded with the NAI's own loader.")
    exp.add_argument("run_dir", help="a run folder made by 'mlr train' (holds checkpoint.pt)")
    exp.add_argument("-o", "--output", required=True, help="the .pt file to write (the .json spec goes beside it)")
    exp.add_argument("--overwrite", action="store_true", help="replace existing files")
    exp.set_defaults(_mlr_run=cmd_export)

    from mlr import fly, thesis

    fly_parser = sub.add_parser("fly", help=fly.HELP, description=fly.HELP)
    fly.add_arguments(fly_parser)
    fly_parser.set_defaults(_mlr_run=fly.run)

    thesis_parser = sub.add_parser("thesis", help=thesis.HELP, description=thesis.DESCRIPTION,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    thesis.add_arguments(thesis_parser)
    thesis_parser.set_defaults(_mlr_run=thesis.run)


def run(args) -> int:
    from mlr.config import ConfigError
    from mlr.pickler import PicklerError

    command = getattr(args, "_mlr_run", None)
    try:
        if command is None:
            raise CliError("give a command: train, pickle, export, fly or thesis (--help lists them)")
        return int(command(args) or 0)
    except (CliError, ConfigError, PicklerError, FileExistsError) as err:
        print(f"mlr: {err}", file=sys.stderr)
        return 2


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mlr", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    args = parser.parse_args(argv)
    if getattr(args, "_mlr_run", None) is None:
        parser.print_help()
        return 2
    try:
        return run(args)
    except KeyboardInterrupt:
        print("mlr: interrupted (finished runs are kept)", file=sys.stderr)
        return 130
