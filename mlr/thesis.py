"""`magna learn thesis`: reproduce the thesis experiment, end to end.

For each of its two scenarios (four cylinders; central obstacle):
1. datasets: make sure `--simulations` simulations (80) of the scenario's ROS-MAGNA mission
   are recorded under the series name `thesis` (only the missing ones are flown, with
   `magna run --append`);
2. train: the thesis architectures (10-10, 30-30, 10-20-10, 20-30-20) and a wider 128-128-128,
   each without and with yaw augmentation (mlr/configs/thesis_<scenario>.yaml), cached and reused
   like `magna learn train`;
3. fly: the mission flown `--flights` times (20) with the best network and with ORCA-3D, on
   the same seeds (mlr.fly; an ORCA-3D batch flown before is reused);
4. analysis: why the thesis's small networks fall short of its accuracies on our data (label
   noise, the class of the problem, input scaling, the amount of data: mlr.thesis_gap);
then a report (Markdown and a figure) beside the thesis's figures.

Every stage skips the work already done, so an interrupted experiment goes on where it stopped.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from magna_common.cli_vocabulary import add_force, add_output, add_rtf, add_search_path
from magna_common.files import write_atomically, write_text_atomically

HELP = "reproduce the thesis experiment: two datasets of 80 simulations, four architectures, flights vs ORCA-3D"
DESCRIPTION = __doc__
EXAMPLES = """\
examples:
  magna learn thesis --search-path ../shared/ros_magna_corpus    # days on 2 cores [long]
  magna learn thesis --search-path ../shared/ros_magna_corpus --only four_cylinders --stages datasets  # [long]
"""
CONFIGS = Path(__file__).resolve().parent / "configs"
STAGES = ("datasets", "train", "fly", "analysis")
SERIES = "thesis"
FLIGHT_SEED = 1000  # the flights' waypoints are not those of the training simulations (seeds 1..80)


@dataclass(frozen=True)
class Scenario:
    key: str
    title: str
    world: str  # WORLD/SUBWORLD
    mission: str  # MISSION/SUBMISSION
    config: Path
    thesis_accuracy: tuple[float, float]  # the range of test accuracies the thesis reports


SCENARIOS = (
    Scenario("four_cylinders", "four cylinders", "Gym/Empty_4_Cylinders", "Gym/2UAVs_2paths_4_Cylinders",
             CONFIGS / "thesis_four_cylinders.yaml", (0.913, 0.922)),
    Scenario("central_obstacle", "central obstacle", "Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder",
             CONFIGS / "thesis_central_obstacle.yaml", (0.852, 0.901)),
)


def _repo() -> Path:
    return Path(os.environ.get("MAGNA_ROOT") or Path(__file__).resolve().parents[1])


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_search_path(parser, what="the scenarios' worlds and missions (passed on to magna run)")
    parser.add_argument("--data-root", default="~/magna_data", help="where Simulations/ goes (default ~/magna_data)")
    add_output(parser, metavar="DIR", old=("--out",),
               help="where the experiment's runs and report go (default DATA_ROOT/mlr/thesis)")
    parser.add_argument("--only", choices=[s.key for s in SCENARIOS], action="append",
                        help="run only this scenario (repeatable; default both)")
    parser.add_argument("--stages", default=",".join(STAGES),
                        help=f"comma-separated stages to run, of {', '.join(STAGES)} (default all); the report is "
                             "always written from what exists")
    parser.add_argument("--simulations", type=int, default=80, help="simulations per dataset (default 80)")
    parser.add_argument("--flights", type=int, default=20, help="simulations per algorithm when flying (default 20)")
    parser.add_argument("--steps", type=int, help="training steps per architecture (default: the config's)")
    add_rtf(parser, help="real-time factor of the simulations (datasets and flights): 'max' runs as fast as the "
                         "machine goes, a number runs that many times real time")
    add_force(parser, old=("--overwrite",),
              help="train again what was trained with another config, and fly again what was flown")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def _stages(text: str) -> list[str]:
    stages = [s.strip() for s in text.split(",") if s.strip()]
    unknown = [s for s in stages if s not in STAGES]
    if unknown:
        raise ValueError(f"--stages {unknown[0]!r} is not a stage: give some of {', '.join(STAGES)}")
    return stages


def _selection(scenario: Scenario, args, name: str):
    """The scenario's dataset series `name` under --data-root."""
    from mlr.pickler import Selection

    world, subworld = scenario.world.split("/")
    mission, submission = scenario.mission.split("/")
    return Selection(Path(args.data_root).expanduser(), world, subworld, mission, submission, name)


def ensure_dataset(scenario: Scenario, args) -> None:
    """Fly what is missing for `--simulations` successful simulations (one batch; failures are kept, not redone)."""
    from mlr.pickler import find_simulations

    selection = _selection(scenario, args, SERIES)
    dataset = selection.dataset_dirs()[0]
    usable = len(find_simulations(selection)[0]) if dataset.is_dir() else 0
    missing = args.simulations - usable
    if missing <= 0:
        print(f"{scenario.title}: {usable} successful simulations recorded in {dataset}", file=sys.stderr)
        return
    command = [str(_repo() / "magna"), "run", "--world", scenario.world, "--mission", scenario.mission,
               "--n-iter", str(missing), "--name", SERIES, "--dataset", "1", "--append", "--rtf", str(args.rtf),
               "--data-root", str(args.data_root)]
    for path in args.search_path:
        command += ["--search-path", str(path)]
    print(f"{scenario.title}: {usable} successful simulations; flying {missing} more: {' '.join(command)}",
          file=sys.stderr)
    status = subprocess.call(command)
    if status not in (0, 1):  # 1: some simulation failed, which a dataset of real missions may hold
        raise RuntimeError(f"{scenario.title}: magna run ended with status {status}; see its messages above "
                           "(a mission that is not found needs --search-path DIR with the ROS-MAGNA files)")


def train(scenario: Scenario, args, out: Path):
    from mlr.config import load_sweep
    from mlr.manager import run_sweep

    overrides = {"data_root": args.data_root}
    if args.steps:
        overrides["steps"] = args.steps
    sweep = load_sweep(scenario.config, overrides)
    return run_sweep(sweep, out / scenario.key / "train", overwrite=args.force, progress=not args.quiet)


def fly(scenario: Scenario, args, out: Path, model: Path) -> None:
    from mlr import fly as fly_module

    if (out / scenario.key / "fly" / "comparison.json").is_file() and not args.force:
        print(f"{scenario.title}: flown before ({out / scenario.key / 'fly'}); --force flies again",
              file=sys.stderr)
        return
    parser = argparse.ArgumentParser()
    fly_module.add_arguments(parser)
    argv = ["--world", scenario.world, "--mission", scenario.mission, "--model", str(model), "--n-iter",
            str(args.flights), "--name", f"{SERIES}_fly", "--data-root", str(args.data_root), "--output",
            str(out / scenario.key / "fly"), "--rtf", str(args.rtf),
            "--seed", str(FLIGHT_SEED)]
    for path in args.search_path:
        argv += ["--search-path", str(path)]
    orca = _selection(scenario, args, f"{SERIES}_fly_orca").dataset_dirs()[0]
    if len(list(orca.glob("simulation_*"))) >= args.flights:
        argv.append("--skip-orca")  # ORCA-3D flies the same with any network: its batch is reused
    if args.force:
        argv.append("--overwrite")  # fly's dataset policy: rewrite the simulations flown before
    fly_args = parser.parse_args(argv)
    status = fly_module.run(fly_args)
    if status:
        raise RuntimeError(f"{scenario.title}: flying the comparison ended with status {status}")


def analyse(scenario: Scenario, args, out: Path) -> None:
    from mlr.config import load_sweep
    from mlr.thesis_gap import analyse as measure

    overrides = {"data_root": args.data_root, **({"steps": args.steps} if args.steps else {})}
    run = load_sweep(scenario.config, overrides).runs[0]
    measure(run, out / scenario.key / "analysis", progress=not args.quiet,
            log=lambda message: print(f"analysis: {message}", file=sys.stderr, flush=True))


def _read_json(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def _sweep_results(scenario: Scenario, out: Path) -> list[Path]:
    """result.json of each run of the scenario's config that is finished (older sweeps' folders are ignored)."""
    from mlr.config import load_sweep

    sweep = load_sweep(scenario.config)
    train_dir = out / scenario.key / "train"
    return [train_dir / sweep.run_name(i) / "result.json" for i in range(len(sweep.runs))
            if (train_dir / sweep.run_name(i) / "result.json").is_file()]


def report(scenarios: list[Scenario], out: Path) -> Path:
    """report.md and report.png from what the stages left in `out`."""
    lines = ["# The thesis experiment, reproduced", ""]
    lines += ["Accuracy: share of test samples whose predicted velocity is within 0.1 x max speed of ORCA-3D's "
              "(mlr/README.md).", ""]
    lines += ["## Training", "", "| scenario | network | samples (train/val/test) | best step | test loss (normalised) "
              "| val accuracy | **test accuracy** | thesis test accuracy |", "|---|---|---|---|---|---|---|---|"]
    bars = []
    for scenario in scenarios:
        for result_file in _sweep_results(scenario, out):
            saved = json.loads(result_file.read_text())
            result, config = saved["result"], saved["config"]
            hidden = "-".join(map(str, config["hidden_layers"])) + \
                (f", {config['augment']} augmentation" if config.get("augment", "none") != "none" else "")
            sizes = saved.get("samples", {})
            split = "/".join(str(sizes.get(k, "?")) for k in ("train", "val", "test"))
            lines.append(f"| {scenario.title} | {hidden} | {split} | {result['best_step']} | "
                         f"{result['test_loss']:.5f} | {result['val_accuracy'] * 100:.1f}% | "
                         f"**{result['test_accuracy'] * 100:.1f}%** | {scenario.thesis_accuracy[0] * 100:.1f}-"
                         f"{scenario.thesis_accuracy[1] * 100:.1f}% |")
            bars.append((scenario, hidden, result["test_accuracy"]))
    findings = [f for s in scenarios if (f := _read_json(out / s.key / "analysis" / "analysis.json")) is not None]
    if findings:
        from mlr.thesis_gap import markdown

        lines += ["", "## Why the small networks fall short (mlr.thesis_gap)", "", markdown(findings).strip()]
    lines += ["", "## Flights: the best network against ORCA-3D, same seeds", ""]
    for scenario in scenarios:
        comparison = out / scenario.key / "fly" / "comparison.md"
        lines += [f"### {scenario.title}", "", comparison.read_text().strip() if comparison.is_file()
                  else "(not flown yet: run the fly stage)", ""]
    path = write_text_atomically(out / "report.md", "\n".join(lines) + "\n", overwrite=True)
    if bars:
        _figure(bars, out / "report.png")
    return path


def _figure(bars: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.artist import Artist
    from matplotlib.patches import Patch

    colors = {SCENARIOS[0].key: "tab:blue", SCENARIOS[1].key: "tab:orange"}
    fig, ax = plt.subplots(figsize=(max(6.0, 0.55 * len(bars) + 2), 4.5))
    xs = list(range(len(bars)))
    ax.bar(xs, [acc * 100 for _, _, acc in bars], color=[colors[s.key] for s, _, _ in bars])
    for i, (scenario, _, _) in enumerate(bars):
        low, high = scenario.thesis_accuracy
        ax.fill_between([i - 0.45, i + 0.45], low * 100, high * 100, color="black", alpha=0.35, lw=0)
    labels = [h.replace(", yaw augmentation", " +yaw") for _, h, _ in bars]
    ax.set_xticks(xs, labels, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel("test accuracy (%)")
    ax.set_ylim(min(70, min(acc * 100 for _, _, acc in bars) - 5), 100)
    ax.axhline(93, color="tab:green", lw=1, ls=":")
    handles: list[Artist] = [Patch(color=colors[s.key], label=s.title) for s in SCENARIOS
                             if any(b[0] is s for b in bars)]
    handles += [Patch(color="black", alpha=0.35, label="the thesis's range"),
                plt.Line2D([], [], color="tab:green", ls=":", label="target 93%")]
    ax.legend(handles=handles, loc="lower right", fontsize=8)
    ax.set_title("Networks learning ORCA-3D: test accuracy (+yaw: trained with yaw augmentation)")
    fig.tight_layout()
    write_atomically(path, lambda file: fig.savefig(file, format="png", dpi=110), overwrite=True, binary=True)
    plt.close(fig)


def run(args) -> int:
    stages = _stages(args.stages)
    out = Path(args.output) if args.output else Path(args.data_root).expanduser() / "mlr" / "thesis"
    scenarios = [s for s in SCENARIOS if not args.only or s.key in args.only]
    for scenario in scenarios:
        if "datasets" in stages:
            ensure_dataset(scenario, args)
        model = out / scenario.key / "train" / f"{scenario.config.stem}.pt"
        if "train" in stages:
            outcome = train(scenario, args, out)
            model = outcome.exported or model
        if "fly" in stages:
            if not model.is_file():
                raise FileNotFoundError(f"{model}: no trained network to fly: run the train stage first")
            fly(scenario, args, out, model)
        if "analysis" in stages:
            analyse(scenario, args, out)
    path = report(scenarios, out)
    print(path.read_text())
    print(f"report: {path}", file=sys.stderr)
    return 0
