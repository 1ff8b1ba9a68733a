"""`magna learn` and `python -m mlr`: the learning pipeline's commands.

    train CONFIG     pickle and preprocess (cached), train every run of the sweep, export the best
    pickle CONFIG    only build the samples and say what they hold
    board RUN_DIR    TensorBoard on the runs of a sweep (or one run)
    export RUN_DIR   export one finished run for the NAI
    fly              fly a mission with a network and with ORCA-3D, side by side
    thesis           reproduce the thesis experiment (datasets, architectures, flights)
    dagger CONFIG    DAgger: fly the network, relabel its states with ORCA-3D's answers, retrain
    rl CONFIG        PPO on the gym (mlr/gym), exported for the NAI
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from magna_common.cli_vocabulary import OutputExists, add_force, add_output, check_output

HELP = "learn navigation networks from recorded missions (torch): train, pickle, board, export, fly, thesis, dagger, rl"
# the command users type; messages name it, so that what they suggest can be typed as it is
COMMAND = "magna learn"
QUICK_CONFIG = "mlr/configs/crossing_quick.yaml"  # trains in under a minute on the data of `make run`
QUICK_RUNS = "~/magna_data/mlr/runs/crossing_quick"
QUICK_TRAIN = f"magna learn train {QUICK_CONFIG} --quiet    # the runs used below (under a minute; reused when done)"

_LEARN_EXAMPLES = f"""\
examples:
  magna learn pickle {QUICK_CONFIG}      # what the samples of `make run`'s dataset hold
  magna learn train {QUICK_CONFIG}       # a tiny training, exported as crossing_quick.pt
  magna learn board {QUICK_RUNS}   # TensorBoard on those runs [background]
  magna learn thesis --search-path ../shared/ros_magna_corpus   # the whole thesis experiment [long]
"""


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
    outcome = run_sweep(sweep, args.output, overwrite=args.force, force_data=args.force_data,
                        export_best=not args.no_export, progress=not args.quiet)
    print((outcome.out / "results.md").read_text(), end="")
    print(f"results: {outcome.out / 'results.csv'}; TensorBoard: {COMMAND} board {outcome.out}")
    if outcome.exported:
        best = next((i for i in range(len(sweep.runs)) if outcome.best and sweep.run_name(i) == outcome.best.name), 0)
        chosen = sweep.runs[best].selection  # its world and mission, which a sweep may vary
        print(f"network: {outcome.exported} (fly it: {COMMAND} fly --world {chosen.world}/{chosen.subworld} "
              f"--mission {chosen.mission}/{chosen.submission} --model {outcome.exported})")
    return 0


def cmd_pickle(args) -> int:
    import numpy as np

    from magna_uav.nai.inputs import input_names
    from mlr import cache
    from mlr.pickler import find_simulations

    sweep = _load(args)
    if args.output:
        check_output(args.output, args.force, "--output")  # before the work, not after it
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
            check_output(path, args.force, "--output")
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
        raise CliError(f"{run_dir}: no checkpoint.pt: give the folder of a run trained by '{COMMAND} train'")
    saved = json.loads((run_dir / "result.json").read_text()) if (run_dir / "result.json").is_file() else {}
    run = trained_config(run_dir)
    sims, _ = find_simulations(run.selection)
    samples, key, _ = cache.cached_samples(run.selection, run.teacher, run.source, sims)
    prepared, _ = cache.cached_prepared(samples, key, run.selection.data_root, run.split, run.seed, run=run)
    net, _ = load_trained(run_dir, prepared.train.x.shape[1])
    about = {"run": run_dir.name, "data": str(run.selection.series_dir), **saved.get("result", {})}
    path = export(net, run, prepared, args.output, about=about, overwrite=args.force)
    print(f"network: {path} and its spec {path.with_suffix('.json')} (checked against the trained run)")
    return 0


def board_argv(args) -> list[str]:
    """The workspace's TensorBoard (this Python's), on RUN_DIR."""
    argv = [sys.executable, "-m", "tensorboard.main", "--logdir", str(Path(args.run_dir).expanduser()),
            "--port", str(args.port)]
    if args.bind_all:
        argv.append("--bind_all")
    return argv


def cmd_board(args) -> int:
    run_dir = Path(args.run_dir).expanduser()
    if not run_dir.is_dir():
        raise CliError(f"{run_dir}: no such folder: give a folder made by '{COMMAND} train' "
                       "(default ~/magna_data/mlr/runs/<config name>)")
    if next(run_dir.rglob("events.out.tfevents.*"), None) is None:
        raise CliError(f"{run_dir}: no TensorBoard logs in it: give a folder made by '{COMMAND} train', or one run "
                       "in it")
    if not 0 < args.port < 65536:
        raise CliError(f"--port {args.port}: give a port from 1 to 65535")
    print(f"TensorBoard on {run_dir}: http://{'0.0.0.0' if args.bind_all else 'localhost'}:{args.port}/ "
          "(Ctrl-C stops it)", file=sys.stderr, flush=True)
    # its own session: a terminal's Ctrl-C reaches us only, and we stop it once, cleanly
    board = subprocess.Popen(board_argv(args), stdin=subprocess.DEVNULL, start_new_session=True)
    previous = _stop_on_terminate()
    try:
        code = board.wait()
    except KeyboardInterrupt:
        _stop_board(board)
        print("TensorBoard stopped", file=sys.stderr)
        return 0
    finally:
        if board.poll() is None:  # we leave for another reason: never leave it running
            _stop_board(board)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if code != 0:
        print(f"mlr: TensorBoard ended with status {code} (is port {args.port} in use? try --port)", file=sys.stderr)
        return 1
    return 0


def _stop_on_terminate() -> dict:
    """SIGTERM and SIGHUP stop TensorBoard as Ctrl-C does (it runs in a session of its own)."""
    def interrupt(_signum, _frame):
        raise KeyboardInterrupt

    previous = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        try:
            previous[sig] = signal.signal(sig, interrupt)
        except ValueError:  # not the main thread: the caller stops it
            break
    return previous


def _stop_board(board: subprocess.Popen) -> None:
    for sig, wait in ((signal.SIGINT, 10.0), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(board.pid, sig)
        except ProcessLookupError:
            pass
        try:
            board.wait(wait)
            return
        except subprocess.TimeoutExpired:
            continue


def _add_config_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", help="hyperparameter file, YAML or JSON (see mlr/README.md and mlr/configs/)")
    parser.add_argument("--data-root", help="where Simulations/ is (overrides the config's data_root)")
    parser.add_argument("--force-data", action="store_true", help="pickle and preprocess again even if cached")


def _examples(*lines: str) -> str:
    return "examples:\n" + "\n".join(f"  {line}" for line in lines) + "\n"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _LEARN_EXAMPLES
    sub = parser.add_subparsers(dest="mlr_command", metavar="COMMAND", title="commands")
    raw = argparse.RawDescriptionHelpFormatter
    train = sub.add_parser(
        "train", help="train every run of a config's sweep and export the best", formatter_class=raw,
        description="Pickle and preprocess (only when the inputs changed), train every combination of the config, "
                    "log to TensorBoard, export the best run.",
        epilog=_examples(f"magna learn train {QUICK_CONFIG}    # the data of `make run`, under a minute",
                         f"magna learn train {QUICK_CONFIG} --dry-run    # list the runs of the sweep",
                         "magna learn train mlr/configs/thesis_four_cylinders.yaml    # 10 networks [long]"))
    _add_config_arguments(train)
    add_output(train, metavar="DIR", old=("--out",),
               help="output folder (default: DATA_ROOT/mlr/runs/<config name>)")
    train.add_argument("--steps", type=int, help="training steps of every run (overrides the config)")
    add_force(train, old=("--overwrite",),
              help="train again runs there that finished with another config, and replace the export")
    train.add_argument("--no-export", action="store_true", help="do not export the best run")
    train.add_argument("--dry-run", action="store_true", help="list the runs of the sweep and stop")
    train.add_argument("--quiet", action="store_true", help="no progress bars")
    train.set_defaults(_mlr_run=cmd_train)

    pickle = sub.add_parser(
        "pickle", help="build the samples of a config and describe them", formatter_class=raw,
        description="Select the simulations, turn the teacher's steps into input vectors and labels (cached), and "
                    "print what they hold.",
        epilog=_examples(f"magna learn pickle {QUICK_CONFIG}",
                         f"magna learn pickle {QUICK_CONFIG} -o ~/crossing_samples.npz --force   "
                         "# and write them"))
    _add_config_arguments(pickle)
    add_output(pickle, metavar="PATH.npz", help="also write the samples to this .npz")
    add_force(pickle, old=("--overwrite",), help="replace --output if it exists")
    pickle.set_defaults(_mlr_run=cmd_pickle)

    board = sub.add_parser(
        "board", help="TensorBoard on a sweep's runs (or one run); Ctrl-C stops it", formatter_class=raw,
        description="Start the workspace's TensorBoard on RUN_DIR (a folder made by 'magna learn train', or one "
                    "run in it) and wait; Ctrl-C stops it. Open the address it prints in a browser.",
        epilog=_examples(QUICK_TRAIN,
                         f"magna learn board {QUICK_RUNS}    # http://localhost:6006 [background]",
                         f"magna learn board {QUICK_RUNS} --port 6010    # another port [background]"))
    board.add_argument("run_dir", metavar="RUN_DIR", help="a folder of runs made by 'magna learn train', or one run")
    board.add_argument("--port", type=int, default=6006, help="the port TensorBoard serves on (default %(default)s)")
    board.add_argument("--bind-all", action="store_true",
                       help="serve on every network interface, not only this machine (localhost)")
    board.set_defaults(_mlr_run=cmd_board)

    exp = sub.add_parser(
        "export", help="export one trained run as TorchScript + JSON spec for the NAI", formatter_class=raw,
        description="Export the best checkpoint of a run folder; the export is checked against the trained network "
                    "and loaded with the NAI's own loader.",
        epilog=_examples(QUICK_TRAIN,
                         f"magna learn export {QUICK_RUNS}/r00 -o ~/nets/crossing.pt --force   "
                         "# also writes ~/nets/crossing.json"))
    exp.add_argument("run_dir", help=f"a run folder made by '{COMMAND} train' (holds checkpoint.pt)")
    add_output(exp, required=True, metavar="PATH.pt", type=str,
               help="the .pt file to write (the .json spec goes beside it)")
    add_force(exp, old=("--overwrite",), help="replace the .pt and .json files if they exist")
    exp.set_defaults(_mlr_run=cmd_export)

    from mlr import compare, dagger, fly, thesis

    fly_parser = sub.add_parser("fly", help=fly.HELP, description=fly.HELP)
    fly.add_arguments(fly_parser)
    fly_parser.set_defaults(_mlr_run=fly.run)

    compare_parser = sub.add_parser("compare", help=compare.HELP, description=compare.HELP)
    compare.add_arguments(compare_parser)
    compare_parser.set_defaults(_mlr_run=compare.run)

    thesis_parser = sub.add_parser("thesis", help=thesis.HELP, description=thesis.DESCRIPTION,
                                   epilog=thesis.EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    thesis.add_arguments(thesis_parser)
    thesis_parser.set_defaults(_mlr_run=thesis.run)

    dagger_parser = sub.add_parser("dagger", help=dagger.HELP, description=dagger.DESCRIPTION,
                                   epilog=dagger.EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    dagger.add_arguments(dagger_parser)
    dagger_parser.set_defaults(_mlr_run=dagger.run)

    from mlr.gym import rl

    rl_parser = sub.add_parser("rl", help=rl.HELP, description=rl.DESCRIPTION, epilog=rl.EXAMPLES,
                               formatter_class=argparse.RawDescriptionHelpFormatter)
    rl.add_arguments(rl_parser)
    rl_parser.set_defaults(_mlr_run=rl.run)


def run(args) -> int:
    from magna_common.errors import UserError
    from mlr.config import ConfigError
    from mlr.pickler import PicklerError

    command = getattr(args, "_mlr_run", None)
    try:
        if command is None:
            raise CliError("give a command: train, pickle, board, export, fly, compare, thesis, dagger or rl "
                           "(--help lists them)")
        return int(command(args) or 0)
    except (CliError, ConfigError, PicklerError, FileExistsError, OutputExists, UserError) as err:
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
