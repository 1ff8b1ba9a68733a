"""`magna learn dagger CONFIG`: DAgger, so that a network imitating ORCA-3D learns what to do in the states it
flies itself into (Ross, Gordon and Bagnell, "A reduction of imitation learning and structured prediction to
no-regret online learning", AISTATS 2011).

Imitation alone trains on the states the teacher visited. A network that drifts off them meets states nobody
taught it. DAgger flies the network, asks the teacher what it would have done in every state the network
reached, adds those answers to the data and trains again.

- Iteration 0 trains the network of the config's training run on the teacher's own flights (its dataset).
- Iteration k = 1..N:
  1. flies the network of iteration k-1: `flights` simulations of the training mission through `magna run`
     (mlr.fly's network variant), on seeds `flight_seed + 100 k + 1...` that neither the training data nor
     the evaluation use. While the network flies, the NAI records ORCA-3D's answer from the same inputs at
     every step (the recorder's teacher_vel);
  2. relabels: every step the network flew becomes a sample labelled with the teacher's answer
     (mlr.pickler, label "teacher"), from every simulation run to an outcome, collisions included;
     with `teacher_agent_radius` the teacher is ORCA-3D with that margin, in flight and on its own
     samples (relabelled from their input vectors, mlr.relabel);
  3. aggregates the teacher's samples and every iteration's relabelled samples so far;
  4. trains the same network again, from scratch, on the aggregate, and exports it.
- Evaluation: the last network flies the evaluation seeds beside ORCA-3D (mlr.fly). With `fallback` it flies
  them once more with the NAI's safety fallback, reported apart: the plain network's figures are the ones
  that count.

How a network flies is read from the flights it was not trained on: network k-1 from iteration k's
flights, the last one from the evaluation.

Files (OUT, default DATA_ROOT/mlr/dagger/NAME):
    config.json                    the DAgger config as resolved; another config refuses to go on (--force)
    iter_00/run/                   the training run (TensorBoard, checkpoint.pt, result.json)
    iter_00/net.pt, net.json       its network, exported
    iter_00/accuracy.json          test accuracy on the teacher's states and on the network's
    iter_01/flights.json           the flights of network 0 (written when the batch is done)
    iter_01/missions/              the network's mission of those flights
    evaluation/, evaluation_fallback/   mlr.fly's comparisons
    results.md, results.json, dagger.png
A stage whose product exists is skipped, so an interrupted run goes on where it stopped; a batch of flights
that was interrupted is flown again whole.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from magna_common.cli_vocabulary import add_force, add_output, add_rtf, add_search_path
from magna_common.files import write_atomically, write_text_atomically
from mlr.config import ConfigError, RunConfig, load_sweep, read_mapping
from mlr.pickler import PicklerError, Samples, Selection, find_simulations

if TYPE_CHECKING:  # mlr.fly is imported when a flight is due: the parser stays light
    from mlr.fly import FlyRequest

HELP = "DAgger: fly the network, relabel its states with ORCA-3D's answers, retrain; a table and a figure"
DESCRIPTION = __doc__
EXAMPLES = """\
examples:
  magna learn dagger mlr/configs/dagger_central_obstacle.yaml --search-path ../shared/ros_magna_corpus  # [long]
  magna learn dagger mlr/configs/dagger_central_obstacle.yaml --iterations 2 --flights 5 \\
      --search-path ../shared/ros_magna_corpus    # a shorter run [long]
"""
SEED_STRIDE = 100  # iteration k flies seeds flight_seed + 100 k + 1 ..: up to 100 flights per iteration
KEYS: dict[str, tuple[object, str]] = {  # key -> (default, what to give)
    "train": (None, "the path of a training config (relative to this file) whose dataset is the teacher's flights"),
    "select": ({}, "a mapping of training-config keys to one value each, so that one run is left"),
    "iterations": (4, "a whole number >= 0 (0: imitation alone, then the evaluation)"),
    "flights": (20, f"a whole number of simulations per iteration, 1..{SEED_STRIDE}"),
    "flight_seed": (2000, "a whole number >= 0: iteration k flies seeds flight_seed + 100 k + 1 .."),
    "evaluation_flights": (20, "a whole number >= 1"),
    "evaluation_seed": (1000, "a whole number >= 0: the evaluation flies seeds evaluation_seed + 1 .."),
    "fallback": (False, "true or false: also evaluate the last network with the NAI's safety fallback"),
    "teacher_agent_radius": (None, "a radius in metres > 0, or null for the mission's: the teacher's ORCA-3D "
                                   "agent_radius (a wider margin than the mission's)"),
}


class DaggerError(ValueError):
    """Bad input for dagger; the message names the file, the key and the fix."""


@dataclass(frozen=True)
class DaggerConfig:
    source: Path
    name: str  # the file's stem: names the output folder and the flight batches
    run: RunConfig  # the network and its teacher's dataset
    iterations: int
    flights: int
    flight_seed: int
    evaluation_flights: int
    evaluation_seed: int
    fallback: bool
    teacher_agent_radius: float | None = None  # the teacher's ORCA-3D agent_radius; None: the mission's

    @property
    def world(self) -> str:
        return f"{self.run.world}/{self.run.subworld}"

    @property
    def mission(self) -> str:
        return f"{self.run.mission}/{self.run.submission}"

    def seed(self, iteration: int) -> int:
        return self.flight_seed + SEED_STRIDE * iteration

    @property
    def series(self) -> str:
        """The batches' name prefix: dagger_NAME (NAME itself when it says dagger already)."""
        return self.name if self.name.startswith("dagger") else f"dagger_{self.name}"

    def batch_name(self, iteration: int) -> str:
        return f"{self.series}_{iteration:02d}"

    def as_dict(self) -> dict:
        return {"name": self.name, "run": self.run.as_dict(), "iterations": self.iterations, "flights": self.flights,
                "flight_seed": self.flight_seed, "evaluation_flights": self.evaluation_flights,
                "evaluation_seed": self.evaluation_seed, "fallback": self.fallback,
                "teacher_agent_radius": self.teacher_agent_radius}

    def fingerprint(self) -> dict:
        """What the finished iterations depend on: all but how many iterations there are to be."""
        return {k: v for k, v in self.as_dict().items() if k != "iterations"}


def _whole(path: Path, key: str, value, low: int, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low or (high is not None and value > high):
        raise DaggerError(f"{path}: {key} is {value!r}: give {KEYS[key][1]}")
    return value


def load_config(path: str | Path, overrides: dict | None = None) -> DaggerConfig:
    """A DAgger config file (YAML or JSON; mlr/README.md, "DAgger") with `overrides` (command line) applied."""
    path = Path(path)
    try:
        raw = read_mapping(path, "a mapping (train: ..., iterations: ...)")
    except ConfigError as err:
        raise DaggerError(str(err)) from None
    unknown = [key for key in raw if key not in KEYS]
    if unknown:
        raise DaggerError(f"{path}: unknown key {unknown[0]!r}: known keys are {', '.join(KEYS)}")
    values = {key: raw.get(key, default) for key, (default, _) in KEYS.items()}
    values.update({k: v for k, v in (overrides or {}).items() if v is not None and k in KEYS})
    if not isinstance(values["train"], str) or not values["train"].strip():
        raise DaggerError(f"{path}: train is {values['train']!r}: give {KEYS['train'][1]}")
    select = values["select"]
    if not isinstance(select, dict):
        raise DaggerError(f"{path}: select is {select!r}: give {KEYS['select'][1]}")
    train_path = (path.parent / values["train"]).resolve()
    run_overrides = dict(select)
    for key in ("data_root", "steps"):
        if (overrides or {}).get(key) is not None:
            run_overrides[key] = overrides[key]  # type: ignore[index]  # checked not None just above
    try:
        sweep = load_sweep(train_path, run_overrides)
    except ConfigError as err:
        raise DaggerError(f"{path}: train {values['train']}: {err}") from None
    if len(sweep.runs) != 1:
        raise DaggerError(f"{path}: train {values['train']} sweeps {', '.join(sweep.swept)} ({len(sweep.runs)} "
                          f"runs): give select with one value for each, e.g. select: {{{sweep.swept[0]}: ...}}")
    run = sweep.runs[0]
    if run.label != "chosen" or run.algorithm != "orca3d" or run.model != "mlp":
        raise DaggerError(f"{path}: train {values['train']} must learn ORCA-3D's own flights with an mlp "
                          f"(algorithm orca3d, label chosen, model mlp); it has algorithm {run.algorithm}, label "
                          f"{run.label}, model {run.model}")
    if not isinstance(values["fallback"], bool):
        raise DaggerError(f"{path}: fallback is {values['fallback']!r}: give {KEYS['fallback'][1]}")
    radius = values["teacher_agent_radius"]
    if radius is not None and (isinstance(radius, bool) or not isinstance(radius, int | float)
                               or not math.isfinite(radius) or radius <= 0):
        raise DaggerError(f"{path}: teacher_agent_radius is {radius!r}: give {KEYS['teacher_agent_radius'][1]}")
    return DaggerConfig(
        path, path.stem, run, _whole(path, "iterations", values["iterations"], 0),
        _whole(path, "flights", values["flights"], 1, SEED_STRIDE),
        _whole(path, "flight_seed", values["flight_seed"], 0),
        _whole(path, "evaluation_flights", values["evaluation_flights"], 1),
        _whole(path, "evaluation_seed", values["evaluation_seed"], 0), values["fallback"],
        None if radius is None else float(radius))


# --- the data ------------------------------------------------------------------------------------------------

def relabelled_selection(config: DaggerConfig, iteration: int, data_root: Path) -> Selection:
    """Where iteration `iteration`'s flights are recorded: mlr.fly's network dataset of its batch."""
    from mlr.nn_mission import VARIANT_SUFFIX

    run = config.run
    return Selection(data_root, run.world, run.subworld, run.mission, f"{run.submission}{VARIANT_SUFFIX}",
                     f"{config.batch_name(iteration)}_nn", (1,))


def teacher_samples(run: RunConfig, log: Callable[[str], None], agent_radius: float | None = None) -> Samples:
    """The teacher's own flights, as `magna learn train` reads them (cached); with `agent_radius`, relabelled
    with ORCA-3D at that radius from their input vectors (mlr.relabel)."""
    from mlr import cache

    sims, skipped = find_simulations(run.selection)
    if not sims:
        raise PicklerError(f"{run.selection.series_dir}: no usable simulation in datasets {list(run.datasets)}: "
                           "record the teacher's flights first (see the training config's comment)")
    samples, _, hit = cache.cached_samples(run.selection, run.teacher, run.source, sims)
    log(f"teacher: {len(samples)} samples from {len(sims)} simulations ({len(skipped)} left out; "
        f"{'cached' if hit else 'pickled'})")
    if agent_radius is None:
        return samples
    from mlr.relabel import relabelled, teacher_setup, with_param

    started = time.monotonic()
    setup = with_param(teacher_setup(sims[0], run), "agent_radius", agent_radius)
    out = relabelled(samples, run, setup)
    changed = float(np.mean(np.linalg.norm(out.y - samples.y, axis=1) > 0.1 * samples.max_speed))
    log(f"teacher: relabelled with ORCA-3D's agent_radius {agent_radius:g} m in {time.monotonic() - started:.0f} s "
        f"({changed * 100:.1f}% of the labels changed by more than the accuracy tolerance)")
    return out


def relabelled_samples(config: DaggerConfig, iteration: int, data_root: Path) -> Samples:
    """The steps network `iteration - 1` flew in iteration `iteration`, labelled with the teacher's answers."""
    from mlr import cache

    selection = relabelled_selection(config, iteration, data_root)
    teacher = dataclasses.replace(config.run.teacher, algorithm="neural_network", label="teacher")
    sims, _ = find_simulations(selection, failures=True)
    if not sims:
        raise PicklerError(f"{selection.series_dir}: no simulation of iteration {iteration} ran to an outcome; "
                           "nothing to relabel (see the batch's messages)")
    return cache.cached_samples(selection, teacher, "csv", sims)[0]


def aggregate(parts: list[Samples], d: int) -> tuple[Samples, np.ndarray]:
    """(all samples, each one's group: 0 the teacher's flights, k iteration k's relabelled flights)."""
    groups = np.concatenate([np.full(len(part), k, dtype=np.int64) for k, part in enumerate(parts)])
    return Samples.concatenate(parts, d, None), groups


# --- one iteration's network ----------------------------------------------------------------------------------

def train_iteration(config: DaggerConfig, iteration: int, samples: Samples, groups: np.ndarray, directory: Path,
                    progress: bool, log: Callable[[str], None]) -> dict:
    """Train and export iteration `iteration`'s network; its accuracies (also in directory/accuracy.json)."""
    from mlr.export import export
    from mlr.preprocess import Part, prepare, split_indices
    from mlr.train import evaluate, load_trained, train_run

    run = config.run
    if run.features != "none":
        from mlr.features import transformed

        samples = transformed(samples, run)
    prepared = prepare(samples, run.split, run.seed, run.normalization)
    test = split_indices(len(samples), run.split, run.seed)[2]  # the same shuffle prepare made
    if (directory / "run").exists():
        shutil.rmtree(directory / "run")  # an interrupted run starts again
    result = train_run(run, prepared, directory / "run", f"iteration {iteration}", progress=progress)
    net, _ = load_trained(directory / "run", prepared.train.x.shape[1])
    accuracies: dict[str, float | None] = {"iteration": iteration, "samples": int(len(samples)),
                                           "teacher_samples": int(np.sum(groups == 0)),
                  "relabelled_samples": int(np.sum(groups > 0)), "test_accuracy": result.test_accuracy,
                  "val_accuracy": result.val_accuracy, "train_seconds": result.wall_seconds}
    for label, mask in (("teacher_states", groups[test] == 0), ("network_states", groups[test] > 0)):
        part = Part(prepared.test.x[mask], prepared.test.y[mask], prepared.test.y_raw[mask],
                    prepared.test.max_speed[mask])
        accuracies[f"test_accuracy_{label}"] = evaluate(net, part, prepared)[1] if len(part) else None
    about = {"dagger": config.name, "iteration": iteration, **accuracies}
    export(net, run, prepared, directory / "net.pt", about=about, overwrite=True)
    write_text_atomically(directory / "accuracy.json", json.dumps(accuracies, indent=2) + "\n", overwrite=True)
    log(f"iteration {iteration}: {len(samples)} samples ({accuracies['relabelled_samples']} relabelled), test "
        f"accuracy {result.test_accuracy * 100:.1f}% (teacher's states "
        f"{_percent(accuracies['test_accuracy_teacher_states'])}, network's "
        f"{_percent(accuracies['test_accuracy_network_states'])}), {result.wall_seconds / 60:.1f} min")
    return accuracies


def _percent(value: float | None) -> str:
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value * 100:.1f}%"


# --- flights --------------------------------------------------------------------------------------------------

def _fly_request(config: DaggerConfig, args, model: Path, name: str, seed: int, n_iter: int, out: Path,
                 policy: str | None, fallback: bool = False) -> FlyRequest:
    from mlr.fly import FlyRequest

    return FlyRequest(world=config.world, mission=config.mission, model=model, name=name, data_root=args.data_root,
                      n_iter=n_iter, search_path=list(args.search_path), output=out, rtf=args.rtf, seed=seed,
                      no_bag=True, policy=policy, fallback=fallback,
                      teacher_agent_radius=config.teacher_agent_radius)


def fly_iteration(config: DaggerConfig, iteration: int, model: Path, directory: Path, args,
                  log: Callable[[str], None]) -> dict:
    """Fly network `iteration - 1` for iteration `iteration`; its flight metrics (also in flights.json)."""
    from mlr import fly
    from mlr.flight_metrics import read_batch

    policy = "overwrite" if relabelled_selection(config, iteration, args.data_root).dataset_dirs()[0].exists() \
        else None  # a batch interrupted before flights.json: flown again whole
    plan = fly.prepare(_fly_request(config, args, model, config.batch_name(iteration), config.seed(iteration),
                                    config.flights, directory, policy))
    log(f"iteration {iteration}: network {iteration - 1} flies {config.flights} simulations (seeds "
        f"{config.seed(iteration) + 1}..{config.seed(iteration) + config.flights}): {' '.join(plan.nn_argv)}")
    code, interrupted = fly.run_batch(plan.nn_argv)
    if interrupted or code == 130:
        raise KeyboardInterrupt
    if code not in (0, 1):
        raise RuntimeError(f"iteration {iteration}: magna run ended with status {code}; see its messages above")
    metrics = read_batch(plan.nn_dataset, f"network {iteration - 1}").to_json()
    write_text_atomically(directory / "flights.json", json.dumps(metrics, indent=2) + "\n", overwrite=True)
    return metrics


def _fallback_share(dataset: Path) -> float | None:
    """The share of the network's steps where the teacher's answer was sent (None: no step said)."""
    from magna_uav.recorder import read_csv

    said = fell_back = 0
    for csv_path in sorted(dataset.glob("simulation_*/uav_*.csv")):
        for row in read_csv(csv_path)[1]:
            if row["algorithm"] == "neural_network" and row["fallback"] is not None:
                said += 1
                fell_back += row["fallback"]
    return fell_back / said if said else None


def evaluate_in_flight(config: DaggerConfig, model: Path, out: Path, args, fallback: bool,
                       log: Callable[[str], None]) -> dict:
    """The network beside ORCA-3D on the evaluation seeds (mlr.fly); the comparison's numbers. A comparison
    there already is reused when it flew this very network, byte for byte (more iterations later, or a training
    done again, make another one)."""
    from mlr import fly

    folder = out / ("evaluation_fallback" if fallback else "evaluation")
    digest = hashlib.sha256(model.read_bytes()).hexdigest()
    done = _read(folder / "comparison.json")
    if done is not None and done.get("model_sha256") == digest:
        log(f"evaluation{' with the fallback' if fallback else ''}: flown before ({folder / 'comparison.json'})")
        return done
    name = f"{config.series}_eval{'_fallback' if fallback else ''}"
    request = _fly_request(config, args, model, name, config.evaluation_seed, config.evaluation_flights, folder,
                           "overwrite", fallback)
    plan = fly.prepare(request)
    if fallback:  # ORCA-3D was flown on the same seeds for the plain network just before: compare with it
        plan = dataclasses.replace(plan, orca_argv=None, orca_dataset=_evaluation_orca(config, args))
    log(f"evaluation{' with the fallback' if fallback else ''}: the last network and ORCA-3D, "
        f"{config.evaluation_flights} simulations each (seeds {config.evaluation_seed + 1}..)")
    code = fly.fly(plan)
    if code == 130:
        raise KeyboardInterrupt
    if code not in (0, 1):
        raise RuntimeError(f"evaluation: magna learn fly ended with status {code}; see its messages above")
    numbers = json.loads((folder / "comparison.json").read_text())
    numbers["fallback_share"] = _fallback_share(plan.nn_dataset) if fallback else None
    numbers["model_sha256"] = digest
    write_text_atomically(folder / "comparison.json", json.dumps(numbers, indent=2) + "\n", overwrite=True)
    return numbers


def _evaluation_orca(config: DaggerConfig, args) -> Path:
    from magna_common.storage_tree import StorageKey

    run = config.run
    return StorageKey(run.world, run.subworld, run.mission, run.submission,
                      f"{config.series}_eval_orca").dataset_dir(args.data_root, 1)


# --- the loop -------------------------------------------------------------------------------------------------

def _read(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def check_output(config: DaggerConfig, out: Path, force: bool) -> None:
    """Refuse to mix iterations of another config into this one (unless `force`, which starts afresh)."""
    written = _read(out / "config.json")
    if written is not None and written.get("fingerprint") != _jsonable(config.fingerprint()):
        if not force:
            raise DaggerError(f"{out / 'config.json'}: the iterations there were made with another config; pass "
                              "--force to start afresh there, or give another -o/--output")
        for stale in sorted(out.glob("iter_*")) + [out / "evaluation", out / "evaluation_fallback"]:
            shutil.rmtree(stale, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomically(out / "config.json", json.dumps({"fingerprint": _jsonable(config.fingerprint()),
                                                           "config": _jsonable(config.as_dict())}, indent=2) + "\n",
                          overwrite=True)


def _jsonable(value):
    return json.loads(json.dumps(value, default=str))


def run_dagger(config: DaggerConfig, args, out: Path, log: Callable[[str], None]) -> dict:
    """Every stage not done yet; the results (also written as results.md, results.json and dagger.png)."""
    from magna_uav.nai.inputs import input_size

    started = time.monotonic()
    check_output(config, out, args.force)
    run = config.run
    d = input_size(run.role, run.n_neighbors, run.n_obstacles)
    parts = [teacher_samples(run, log, config.teacher_agent_radius)]
    rows: list[dict] = []
    for iteration in range(config.iterations + 1):
        directory = out / f"iter_{iteration:02d}"
        directory.mkdir(exist_ok=True)
        flights = None
        if iteration > 0:
            flights = _read(directory / "flights.json")
            if flights is None:
                flights = fly_iteration(config, iteration, out / f"iter_{iteration - 1:02d}" / "net.pt", directory,
                                        args, log)
            else:
                log(f"iteration {iteration}: flown before ({directory / 'flights.json'})")
            parts.append(relabelled_samples(config, iteration, args.data_root))
            rows[-1]["flights"] = flights  # how the previous network flew, on seeds it never saw
        accuracy = _read(directory / "accuracy.json")
        if accuracy is None or not (directory / "net.pt").is_file():
            samples, groups = aggregate(parts, d)
            accuracy = train_iteration(config, iteration, samples, groups, directory, not args.quiet, log)
        else:
            log(f"iteration {iteration}: trained before ({directory / 'net.pt'}, test accuracy "
                f"{accuracy['test_accuracy'] * 100:.1f}%)")
        rows.append({"iteration": iteration, "accuracy": accuracy, "flights": None})
    last = out / f"iter_{config.iterations:02d}" / "net.pt"
    evaluation = evaluate_in_flight(config, last, out, args, False, log)
    with_fallback = evaluate_in_flight(config, last, out, args, True, log) if config.fallback else None
    results = {"config": _jsonable(config.as_dict()), "iterations": rows, "evaluation": evaluation,
               "evaluation_fallback": with_fallback, "wall_seconds_this_run": time.monotonic() - started}
    write_text_atomically(out / "results.json", json.dumps(results, indent=2) + "\n", overwrite=True)
    write_text_atomically(out / "results.md", results_markdown(results), overwrite=True)
    draw(results, out / "dagger.png")
    return results


# --- the table and the figure ---------------------------------------------------------------------------------

def _rate(flights: dict | None) -> str:
    if not flights or not flights.get("simulations"):
        return "-"
    return f"{flights['collision_free']}/{flights['simulations']}"


def _time(metrics: dict | None) -> str:
    if not metrics or metrics.get("mean_time_to_goal") is None:
        return "-"
    return f"{metrics['mean_time_to_goal']:.1f} ± {metrics['std_time_to_goal']:.1f} s " \
           f"({metrics['goals_reached']} of {metrics['uav_paths']} paths)"


def results_markdown(results: dict) -> str:
    config = results["config"]
    lines = [f"# DAgger: {config['name']}", "",
             f"Network {'-'.join(map(str, config['run']['hidden_layers']))}, augment {config['run']['augment']}, "
             f"{config['run']['steps']} training steps per iteration; {config['flights']} flights per iteration"
             + (f"; the teacher's ORCA-3D agent_radius {config['teacher_agent_radius']:g} m"
                if config.get("teacher_agent_radius") is not None else "") + ".", "",
             "| iteration | samples (relabelled) | test accuracy | on the teacher's states | on the network's states "
             "| its flights, collision-free | time to goal |",
             "|---|---|---|---|---|---|---|"]
    for row in results["iterations"]:
        acc, flights = row["accuracy"], row["flights"]
        lines.append(f"| {row['iteration']} | {acc['samples']} ({acc['relabelled_samples']}) | "
                     f"{_percent(acc['test_accuracy'])} | {_percent(acc['test_accuracy_teacher_states'])} | "
                     f"{_percent(acc['test_accuracy_network_states'])} | {_rate(flights)} | {_time(flights)} |")
    lines += ["", "Each network's flights are the next iteration's: seeds it was not trained on. The last network's "
              "are the evaluation's.", ""]
    for key, title in (("evaluation", "the network alone (what counts)"),
                       ("evaluation_fallback", "the network with the safety fallback (reported apart)")):
        numbers = results.get(key)
        if not numbers:
            continue
        orca, network = numbers["orca"], numbers["network"]
        ratio = numbers.get("collision_free_ratio")
        share = numbers.get("fallback_share")
        lines += [f"Evaluation, {title}: seeds {config['evaluation_seed'] + 1}..", "",
                  "| | collision-free | time to goal |", "|---|---|---|",
                  f"| ORCA-3D | {_rate(orca)} | {_time(orca)} |",
                  f"| last network | {_rate(network)} | {_time(network)} |",
                  "", f"Ratio of collision-free rates (network / ORCA-3D): "
                  f"{'-' if ratio is None else f'{ratio:.2f}'} (target >= 0.95)."
                  + ("" if share is None else f" The teacher's answer was sent in {share * 100:.1f}% of the "
                                              "network's steps."), ""]
    return "\n".join(lines)


def draw(results: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = results["iterations"]
    x = [row["iteration"] for row in rows]
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for key, label in (("test_accuracy_teacher_states", "on the teacher's states"),
                       ("test_accuracy_network_states", "on the network's states")):
        values = [row["accuracy"].get(key) for row in rows]
        left.plot(x, [np.nan if v is None else v * 100 for v in values], marker="o", label=label)
    left.set(xlabel="iteration", ylabel="test accuracy (%)", title="Accuracy", ylim=(0, 100), xticks=x)
    left.legend(loc="lower right")
    flown = [(row["iteration"], row["flights"]) for row in rows if row["flights"] and row["flights"]["simulations"]]
    right.plot([i for i, _ in flown], [f["collision_free"] / f["simulations"] * 100 for _, f in flown], marker="o",
               label="network's flights")
    evaluation = results.get("evaluation")
    if evaluation and evaluation["orca"]["simulations"]:
        orca = evaluation["orca"]["collision_free"] / evaluation["orca"]["simulations"] * 100
        right.axhline(orca, color="grey", linestyle="--", label="ORCA-3D (evaluation)")
        right.axhline(0.95 * orca, color="grey", linestyle=":", label="target: 0.95 x ORCA-3D")
        for key, label, marker in (("evaluation", "last network (evaluation)", "*"),
                                   ("evaluation_fallback", "last network + fallback (apart)", "P")):
            flown_last = (results.get(key) or {}).get("network") or {}
            if flown_last.get("simulations"):
                right.plot([x[-1]], [flown_last["collision_free"] / flown_last["simulations"] * 100], marker=marker,
                           markersize=12, linestyle="none", label=label)
    right.set(xlabel="iteration (network flown)", ylabel="collision-free flights (%)", title="In flight",
              ylim=(-5, 105), xticks=x)
    right.legend(loc="center left", fontsize=8)
    fig.suptitle(f"DAgger: {results['config']['name']}")
    fig.tight_layout()
    write_atomically(path, lambda out: fig.savefig(out, format="png", dpi=100), overwrite=True, binary=True)
    plt.close(fig)
    return path


# --- the command ----------------------------------------------------------------------------------------------

def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("config", type=Path, help="the DAgger config (YAML or JSON; mlr/README.md, 'DAgger')")
    add_search_path(parser, what="the mission's world and mission files (passed on to magna run)")
    parser.add_argument("--data-root", type=Path, metavar="DIR",
                        help="where Simulations/ is (default: the training config's)")
    add_output(parser, metavar="DIR",
               help="where the iterations and the results go (default DATA_ROOT/mlr/dagger/NAME)")
    parser.add_argument("--iterations", type=int, metavar="N",
                        help="iterations after the first network (default: the config's)")
    parser.add_argument("--flights", type=int, metavar="N", help="simulations per iteration (default: the config's)")
    parser.add_argument("--steps", type=int, metavar="N",
                        help="training steps per network (default: the training config's)")
    add_rtf(parser, help="real-time factor of the flights: 'max' runs as fast as the machine goes")
    add_force(parser, help="start afresh in an output folder that holds iterations of another config")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args) -> int:
    from magna_common.errors import UsageError
    from magna_common.storage_tree import StorageError

    overrides = {"iterations": args.iterations, "flights": args.flights, "steps": args.steps,
                 "data_root": str(args.data_root) if args.data_root is not None else None}
    try:
        config = load_config(args.config, overrides)
        for key, low in (("iterations", 0), ("flights", 1), ("steps", 1)):
            value = getattr(args, key)
            if value is not None and value < low:
                raise DaggerError(f"--{key} is {value}: give a whole number >= {low}")
        args.data_root = Path(config.run.data_root).expanduser().resolve()
        out = Path(args.output).expanduser().resolve() if args.output is not None \
            else args.data_root / "mlr" / "dagger" / config.name
        results = run_dagger(config, args, out, lambda message: print(f"dagger: {message}", file=sys.stderr,
                                                                      flush=True))
    except (DaggerError, PicklerError, StorageError) as err:
        raise UsageError(" ".join(str(err).split())) from None
    except KeyboardInterrupt:
        print("dagger: interrupted; run the same command again to go on where it stopped", file=sys.stderr)
        return 130
    print(results_markdown(results))
    print(f"dagger: {out / 'results.md'}, {out / 'results.json'}, {out / 'dagger.png'} "
          f"({results['wall_seconds_this_run'] / 60:.1f} min this run)")
    return 0
