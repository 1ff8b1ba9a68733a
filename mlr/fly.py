"""`fly`: a mission flown N times with ORCA-3D and N times with a trained network, compared side by side.

    python -m mlr fly --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA \\
        --model runs/best/model.pt --n-iter 20

Steps (see mlr/README.md, "Flying a trained network"):

1. checks, before anything starts or is written: the model and its spec load as the UAV managers
   load them, the world and mission are found and valid, the mission sets ORCA-3D (orca3/orca3d)
   with an algorithm_control state, and no dataset would be mixed up with older data;
2. the network variant of the mission (`nn_variant`): every algorithm_control state that sets
   ORCA-3D sets neural_network with the model instead; written to
   OUT/missions/MISSION/SUBMISSION_nn.json, so `magna run --search-path OUT` finds it;
3. two batches through the real `magna run`: the mission as it is under the name NAME_orca, the
   variant under NAME_nn, with the same --seed so simulation m of both flies the same random
   waypoints (seed S+m);
4. the metrics of both datasets (`read_batch`), written to OUT/comparison.md, .json and .png.

Exit status: 0 when both batches ran, 1 when a simulation crashed or could not start (it is left
out of the metrics), 2 for bad input (nothing started), 130 when interrupted (Ctrl-C is forwarded
to the running `magna run`, which stops its simulation cleanly; no comparison is written).
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path

HELP = "fly a mission with a trained network and with ORCA-3D, N simulations each, and compare them side by side"

ORCA_NAMES = ("orca3", "orca3d")
NN_NAME = "neural_network"
# The NAI's default neighbour distance (magna_uav.nai.inputs.DEFAULT_NEIGHBOR_DIST, ORCA-3D's default);
# kept here so that building the parser imports no ROS or torch.
DEFAULT_NEIGHBOR_DIST = 6.0
TARGET_RATIO = 0.95  # DESIGN.md §6: missions flown by the network collision-free at >= 95% of ORCA's rate
VARIANT_SUFFIX = "_nn"
# Simulations that did not run to a mission outcome say nothing about the algorithm: left out.
NOT_FLOWN = ("interrupted", "crashed", "start_failed", "supervisor_failed")
# Roles the mission's action states fly, for the warning about roles the model does not cover.
STATE_ROLES = {"follow_path": "path", "follow_agent_ad": "agent_ad", "follow_uav_ad": "agent_ad",
               "follow_agent_ap": "agent_ap", "follow_uav_ap": "agent_ap"}
TIME_TO_GOAL = ("per UAV and simulation: the time of the UAV's last `path` control step minus its first, "
                "counted when every path role it flew ended 'succeeded' (the recorder's outcome column)")

_EPILOG = """\
Data: DATA_ROOT/Simulations/WORLD/SUBWORLD/MISSION/SUBMISSION/NAME_orca/dataset_1/ (ORCA-3D) and
.../MISSION/SUBMISSION_nn/NAME_nn/dataset_1/ (network); the comparison goes to OUT (default
DATA_ROOT/mlr/fly/NAME): comparison.md, comparison.json, comparison.png, and the network's mission
OUT/missions/MISSION/SUBMISSION_nn.json.

Existing datasets: --append adds N simulations to both, --overwrite rewrites simulations 1..N of both
(and a different variant file); the comparison covers every simulation of each dataset. --skip-orca
flies only the network and compares with the ORCA-3D dataset already there.

examples:
  python -m mlr fly --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA \\
      --model ~/magna_data/mlr/runs/best/model.pt --n-iter 20
  python -m mlr fly --search-path ../shared/ros_magna_corpus --world Gym/1Obs_Central_Cylinder \\
      --mission Gym/2UAVs_2paths_Central_Cylinder --model best.pt --name cyl --skip-orca
"""


class FlyError(ValueError):
    """Bad input for fly (a file, a mission, a dataset): the message names it and the fix; exit status 2."""


# --- the network's mission ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Change:
    """One algorithm_control state of the mission that the variant flies with the network."""

    where: str  # JSON path, e.g. State_Machine[5] or State_Machine[2].occurrencies[0]
    state: str  # the state's name
    was: str  # e.g. "orca3 set"
    neighbor_dist: float
    neighbor_dist_from: str  # "the model's spec", "the mission's ORCA neighborDist" or "the default"

    def __str__(self) -> str:
        return (f"{self.where} {self.state!r}: {self.was} -> {NN_NAME} set, neighborDist {self.neighbor_dist:g} "
                f"({self.neighbor_dist_from})")


def _walk_states(nodes, prefix: str):
    """(JSON path, state) of every state of a State_Machine list, children (occurrencies) after their parent."""
    for i, node in enumerate(nodes):
        where = f"{prefix}[{i}]"
        if not isinstance(node, dict):
            continue
        yield where, node
        children = node.get("occurrencies")
        if isinstance(children, list):
            yield from _walk_states(children, f"{where}.occurrencies")


def _control(node: dict) -> dict | None:
    """The parameters of an algorithm_control state, or None for any other state."""
    parameters = node.get("parameters")
    if node.get("state_type") != "algorithm_control" or not isinstance(parameters, dict):
        return None
    return parameters


def _given_neighbor_dist(parameters: dict) -> float | None:
    """neighborDist of one algorithm_control state, when it gives a usable one (> 0: the network needs it)."""
    names, values = parameters.get("params"), parameters.get("values")
    if not isinstance(names, list) or not isinstance(values, list) or "neighborDist" not in names:
        return None
    index = names.index("neighborDist")
    value = values[index] if index < len(values) else None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
        return None
    return float(value)


def nn_variant(mission, model_path: str, neighbor_dist: float | None = None,
               source: str | os.PathLike = "mission") -> tuple[dict, list[Change]]:
    """(a copy of `mission` flying the network, what changed); FlyError naming `source` if nothing sets ORCA.

    Every algorithm_control state, at any depth, whose parameters name orca3/orca3d with action
    set becomes neural_network set with the model and neighborDist: `neighbor_dist` (the spec's,
    when given), else that state's ORCA neighborDist, else the first neighborDist any ORCA state
    of the mission gives, else DEFAULT_NEIGHBOR_DIST. ORCA "configure" states stay: ORCA-3D still
    flies the roles no network is trained for (basic_move). `mission` is not modified.

    The model path goes in text_value (a string field of the AlgorithmControl service); the
    ground station sends `values` as float64 and so cannot carry a path there.
    """
    if not os.path.isabs(model_path):
        raise FlyError(f"model path {model_path!r} is relative: give the absolute path the UAV managers will load")
    if not isinstance(mission, dict) or not isinstance(mission.get("State_Machine"), list):
        raise FlyError(f"{source}: not a mission: expected an object with a State_Machine list (DESIGN.md §3)")
    variant = copy.deepcopy(mission)
    states = list(_walk_states(variant["State_Machine"], "State_Machine"))
    controls = [(where, node, p) for where, node in states if (p := _control(node)) is not None]
    orca = [(where, node, p) for where, node, p in controls if p.get("name") in ORCA_NAMES]
    mission_dist = next((d for _, _, p in orca if (d := _given_neighbor_dist(p)) is not None), None)
    changes = []
    for where, node, parameters in orca:
        if parameters.get("action") != "set":
            continue
        if neighbor_dist is not None:
            dist, origin = float(neighbor_dist), "the model's spec"
        elif (own := _given_neighbor_dist(parameters)) is not None:
            dist, origin = own, "the mission's ORCA neighborDist"
        elif mission_dist is not None:
            dist, origin = mission_dist, "the mission's ORCA neighborDist"
        else:
            dist, origin = DEFAULT_NEIGHBOR_DIST, "the default"
        changes.append(Change(where, str(node.get("name", "")), f"{parameters['name']} set", dist, origin))
        node["parameters"] = {"name": NN_NAME, "action": "set", "params": ["neighborDist"], "values": [dist],
                              "text_value": model_path}
    if not changes:
        found = ", ".join(f"{p.get('name')} {p.get('action')} at {where}" for where, _, p in controls)
        raise FlyError(f"{source}: no algorithm_control state sets orca3 or orca3d "
                       f"({'found: ' + found if found else 'it has no algorithm_control state'}); fly compares the "
                       "network with ORCA-3D, so give a mission that flies ORCA-3D")
    return variant, changes


def mission_roles(mission) -> list[str]:
    """The network roles (path, agent_ad, agent_ap) the mission's action states fly, in first-seen order."""
    roles: list[str] = []
    machine = mission.get("State_Machine") if isinstance(mission, dict) else None
    for _, node in _walk_states(machine if isinstance(machine, list) else [], "State_Machine"):
        role = STATE_ROLES.get(node.get("state_type"))
        if role is not None and role not in roles:
            roles.append(role)
    return roles


def variant_path(out: Path, mission: str, submission: str) -> Path:
    return Path(out) / "missions" / mission / f"{submission}{VARIANT_SUFFIX}.json"


def write_variant(out: Path, mission: str, submission: str, variant: dict, overwrite: bool = False) -> Path:
    """Write the variant atomically; an existing different file is kept (FlyError) unless `overwrite`."""
    from magna_master.storage import atomic_write_text

    path = variant_path(out, mission, submission)
    text = json.dumps(variant, indent=4) + "\n"
    if path.exists():
        try:
            same = path.read_text() == text
        except (OSError, UnicodeDecodeError):
            same = False
        if same:
            return path
        if not overwrite:
            raise FlyError(f"{path} exists and differs from this network's mission; nothing was started. Pass "
                           "--overwrite to replace it, or choose another --out or --name")
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, text)
    return path


# --- metrics ------------------------------------------------------------------------------------------------

@dataclass
class BatchMetrics:
    """What one dataset says about how its algorithm flew the mission."""

    label: str
    dataset: Path
    simulations: int = 0  # run to a mission outcome
    left_out: int = 0  # interrupted, crashed, not started: not counted anywhere
    successes: int = 0  # mission succeeded (summary.csv)
    collision_free: int = 0  # simulations with 0 collisions (summary.csv)
    uav_paths: int = 0  # (simulation, UAV) pairs that flew a path role
    times_to_goal: list[float] = field(default_factory=list)  # of those whose path roles all succeeded
    seeds: list[int] = field(default_factory=list)

    @property
    def collision_free_rate(self) -> float | None:
        return self.collision_free / self.simulations if self.simulations else None

    @property
    def success_rate(self) -> float | None:
        return self.successes / self.simulations if self.simulations else None

    @property
    def goals_reached(self) -> int:
        return len(self.times_to_goal)

    @property
    def mean_time_to_goal(self) -> float | None:
        return statistics.fmean(self.times_to_goal) if self.times_to_goal else None

    @property
    def std_time_to_goal(self) -> float | None:
        """Sample standard deviation (n - 1); 0 for one value."""
        if not self.times_to_goal:
            return None
        return statistics.stdev(self.times_to_goal) if len(self.times_to_goal) > 1 else 0.0

    def to_json(self) -> dict:
        return {"label": self.label, "dataset": str(self.dataset), "simulations": self.simulations,
                "left_out": self.left_out, "successes": self.successes, "success_rate": self.success_rate,
                "collision_free": self.collision_free, "collision_free_rate": self.collision_free_rate,
                "uav_paths": self.uav_paths, "goals_reached": self.goals_reached,
                "mean_time_to_goal": self.mean_time_to_goal, "std_time_to_goal": self.std_time_to_goal,
                "times_to_goal": self.times_to_goal, "seeds": self.seeds}


def path_time_to_goal(rows: list[dict]) -> tuple[bool, float | None]:
    """(flew a path role, its time to goal or None) from one UAV's recorder rows (`TIME_TO_GOAL`).

    A role's outcome is written on its last row, so the outcomes on `path` rows are those of its path roles.
    """
    path = [row for row in rows if row["role"] == "path"]
    if not path:
        return False, None
    outcomes = [row["outcome"] for row in path if row["outcome"]]
    if not outcomes or any(outcome != "succeeded" for outcome in outcomes):
        return True, None
    return True, float(path[-1]["time"]) - float(path[0]["time"])


def read_batch(dataset_dir: Path, label: str) -> BatchMetrics:
    """The metrics of a dataset: summary.csv, each simulation's result.json and uav_*.csv."""
    from magna_master import storage
    from magna_uav.recorder import read_csv

    dataset_dir = Path(dataset_dir)
    rows = storage.read_summary(dataset_dir)
    if not rows:
        raise FlyError(f"{dataset_dir}: no {storage.SUMMARY_FILE} with simulations; run the batch first "
                       f"(without --skip-orca for the ORCA-3D one)")
    metrics = BatchMetrics(label, dataset_dir)
    for row in rows:
        sim_dir = storage.simulation_dir(dataset_dir, int(row["id"]))
        result = storage.read_result(sim_dir / storage.RESULT_FILE) or {}
        if row.get("outcome") in NOT_FLOWN or result.get("termination") in NOT_FLOWN:
            metrics.left_out += 1
            continue
        metrics.simulations += 1
        metrics.successes += row.get("success") == "True"
        metrics.collision_free += int(row.get("collisions") or 0) == 0
        if result.get("seed") is not None:
            metrics.seeds.append(int(result["seed"]))
        for csv_path in sorted(sim_dir.glob("uav_*.csv")):
            try:
                _, uav_rows = read_csv(csv_path)
            except ValueError as err:
                raise FlyError(str(err)) from None
            flew, seconds = path_time_to_goal(uav_rows)
            metrics.uav_paths += flew
            if seconds is not None:
                metrics.times_to_goal.append(seconds)
    return metrics


@dataclass
class Comparison:
    orca: BatchMetrics
    nn: BatchMetrics
    world: str
    mission: str
    model: str
    changes: list[str] = field(default_factory=list)
    target: float = TARGET_RATIO

    @property
    def ratio(self) -> float | None:
        """collision-free rate of the network over ORCA-3D's (None when ORCA-3D's is 0 or unknown)."""
        orca, nn = self.orca.collision_free_rate, self.nn.collision_free_rate
        if orca is None or nn is None or orca == 0:
            return None
        return nn / orca

    @property
    def meets_target(self) -> bool | None:
        return None if self.ratio is None else self.ratio >= self.target

    @property
    def same_seeds(self) -> bool:
        return sorted(self.orca.seeds) == sorted(self.nn.seeds)

    def to_json(self) -> dict:
        return {"world": self.world, "mission": self.mission, "model": self.model, "changes": self.changes,
                "orca": self.orca.to_json(), "network": self.nn.to_json(),
                "collision_free_ratio": self.ratio, "target_ratio": self.target, "meets_target": self.meets_target,
                "same_seeds": self.same_seeds, "time_to_goal": TIME_TO_GOAL}

    def markdown(self) -> str:
        def count(n, total):
            return f"{n}/{total} ({100 * n / total:.1f}%)" if total else "-"

        def seconds(m: BatchMetrics):
            return "-" if m.mean_time_to_goal is None else f"{m.mean_time_to_goal:.1f} ± {m.std_time_to_goal:.1f}"

        o, n = self.orca, self.nn
        lines = [f"## {self.mission} in {self.world}: ORCA-3D vs network", "",
                 "| | ORCA-3D | network |", "|---|---:|---:|",
                 f"| simulations | {o.simulations} | {n.simulations} |",
                 f"| successful missions | {count(o.successes, o.simulations)} | {count(n.successes, n.simulations)} |",
                 f"| collision-free | {count(o.collision_free, o.simulations)} | "
                 f"{count(n.collision_free, n.simulations)} |",
                 f"| UAV paths to the goal | {count(o.goals_reached, o.uav_paths)} | "
                 f"{count(n.goals_reached, n.uav_paths)} |",
                 f"| time to goal (s, mean ± std) | {seconds(o)} | {seconds(n)} |", ""]
        if self.ratio is None:
            lines.append(f"collision-free rate network / ORCA-3D: undefined (ORCA-3D was collision-free in "
                         f"{o.collision_free} of {o.simulations}); target >= {self.target:g}")
        else:
            verdict = "met" if self.meets_target else "NOT met"
            lines.append(f"collision-free rate network / ORCA-3D: **{self.ratio:.3f}** "
                         f"(target >= {self.target:g}: {verdict})")
        lines += ["", f"- model: `{self.model}`", f"- ORCA-3D data: `{o.dataset}`", f"- network data: `{n.dataset}`",
                  f"- time to goal: {TIME_TO_GOAL}"]
        for m in (o, n):
            if m.left_out:
                lines.append(f"- {m.label}: {m.left_out} simulation(s) left out (interrupted, crashed or not started)")
        if not self.same_seeds:
            lines.append("- warning: the two datasets were not flown with the same seeds, so not over the same "
                         "random waypoints; run both again with the same --seed (without --skip-orca)")
        return "\n".join(lines) + "\n"


def draw_comparison(comparison: Comparison, path: Path) -> Path:
    """Bars: collision-free rate and mean time to goal (± std), ORCA-3D vs network; headless, written atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    o, n = comparison.orca, comparison.nn
    labels, colours = ["ORCA-3D", "network"], ["tab:blue", "tab:orange"]
    figure = Figure(figsize=(7.0, 3.4))
    FigureCanvasAgg(figure)
    left, right = figure.subplots(1, 2)
    rates = [m.collision_free_rate for m in (o, n)]
    left.bar(labels, [r or 0.0 for r in rates], color=colours)
    if o.collision_free_rate:
        left.axhline(comparison.target * o.collision_free_rate, color="grey", linestyle="--", linewidth=1)
        left.set_xlabel(f"dashed: {comparison.target:.0%} of ORCA-3D's rate (the target)", fontsize=8)
    left.set_ylim(0, 1.15)
    left.set_title("collision-free rate")
    means = [m.mean_time_to_goal for m in (o, n)]
    stds = [m.std_time_to_goal or 0.0 for m in (o, n)]
    right.bar(labels, [v or 0.0 for v in means], yerr=stds, capsize=6, color=colours)
    right.set_title("mean time to goal (s)")
    right.set_ylim(0, max([(v or 0.0) + s for v, s in zip(means, stds, strict=True)] + [1.0]) * 1.15)
    for x in range(2):  # the value over each bar (and over its error bar), "n/a" when there is none
        rate, mean = rates[x], means[x]
        left.annotate("n/a" if rate is None else f"{rate:.2f}", (x, rate or 0.0), xytext=(0, 2),
                      textcoords="offset points", ha="center", va="bottom", fontsize=8)
        right.annotate("n/a" if mean is None else f"{mean:.1f}", (x, (mean or 0.0) + stds[x]), xytext=(0, 2),
                       textcoords="offset points", ha="center", va="bottom", fontsize=8)
    figure.suptitle(f"{comparison.mission}: {o.simulations} vs {n.simulations} simulations", fontsize=10)
    figure.tight_layout()
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        figure.savefig(tmp, dpi=100)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_comparison(comparison: Comparison, out: Path) -> list[Path]:
    """comparison.md, comparison.json and comparison.png in `out`."""
    from magna_master.storage import atomic_write_text

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / "comparison.md", out / "comparison.json"
    atomic_write_text(md, comparison.markdown())
    atomic_write_text(js, json.dumps(comparison.to_json(), indent=2) + "\n")
    return [md, js, draw_comparison(comparison, out / "comparison.png")]


# --- the command --------------------------------------------------------------------------------------------

def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument("--world", required=True, metavar="WORLD/SUBWORLD", help="the world, as for magna run")
    parser.add_argument("--mission", required=True, metavar="MISSION/SUBMISSION",
                        help="a mission that sets orca3/orca3d with an algorithm_control state")
    parser.add_argument("--model", required=True, type=Path, metavar="PATH.pt",
                        help="the TorchScript network (its spec PATH.json beside it), as mlr's export writes it")
    parser.add_argument("--n-iter", type=int, default=20, metavar="N", help="simulations per batch (default: 20)")
    parser.add_argument("--search-path", action="append", default=[], type=Path, metavar="DIR",
                        help="also look for worlds and missions here (repeatable; passed on to magna run)")
    parser.add_argument("--name", default="fly",
                        help="the batches are named NAME_orca and NAME_nn (default: %(default)s)")
    parser.add_argument("--data-root", type=Path, default=Path("~/magna_data"), metavar="DIR",
                        help="where Simulations/ goes (default: ~/magna_data)")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="where the comparison and the network's mission go (default: DATA_ROOT/mlr/fly/NAME)")
    parser.add_argument("--rtf", default="max", metavar="max|FACTOR", help="real-time factor (default: max)")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="base seed of both batches; simulation M uses S+M (default: 0)")
    parser.add_argument("--no-bag", action="store_true", help="do not record a bag per simulation")
    policy = parser.add_mutually_exclusive_group()
    policy.add_argument("--append", dest="policy", action="store_const", const="append",
                        help="add the simulations to existing datasets (passed on to magna run)")
    policy.add_argument("--overwrite", dest="policy", action="store_const", const="overwrite",
                        help="rewrite simulations 1..N of existing datasets and a different network mission")
    parser.add_argument("--skip-orca", action="store_true",
                        help="fly only the network; compare with the ORCA-3D dataset NAME_orca already there")


def repo_root() -> Path:
    """The repository whose `magna` script runs the batches: $MAGNA_ROOT, else the parent of mlr/."""
    env = os.environ.get("MAGNA_ROOT")
    return Path(env).resolve() if env else Path(__file__).resolve().parents[1]


@dataclass
class FlyPlan:
    magna: Path
    world: str
    mission: str
    model: Path
    out: Path
    variant: Path
    changes: list[Change]
    orca_dataset: Path
    nn_dataset: Path
    orca_argv: list[str] | None  # None with --skip-orca
    nn_argv: list[str]


def _spec_arg(value: str) -> str:
    """A --world/--mission value: a .json file becomes absolute (the batches may run elsewhere), a name stays."""
    path = Path(value).expanduser()
    return str(path.resolve()) if value.endswith(".json") and path.is_file() else value


def prepare(args) -> FlyPlan:
    """Check everything and write the network's mission; FlyError/BatchError/StorageError before anything flies."""
    from magna_master import storage
    from magna_master.batch import parse_rtf, resolve_inputs
    from magna_uav.nai.neural import NeuralModelError, load_model

    if args.n_iter < 1:
        raise FlyError(f"--n-iter must be >= 1, got {args.n_iter}")
    rtf = parse_rtf(args.rtf)
    orca_name, nn_name = f"{args.name}_orca", f"{args.name}_nn"
    for value in (orca_name, nn_name):
        storage.check_component(value, "--name")
    magna = repo_root() / "magna"
    if not os.access(magna, os.X_OK):
        raise FlyError(f"{magna}: no magna command there; set MAGNA_ROOT to the repository root")

    model = args.model.expanduser().resolve()
    try:
        loaded = load_model(model)  # as the UAV managers will: a bad model stops here, not 20 missions later
    except NeuralModelError as err:
        raise FlyError(str(err)) from None
    neighbor_dist = loaded.spec.neighbor_dist  # the distance it was trained with, when its spec says

    search = [p.expanduser().resolve() for p in args.search_path]
    world, mission = _spec_arg(args.world), _spec_arg(args.mission)
    inputs = resolve_inputs(world, mission, search)
    try:
        raw = json.loads(inputs.mission_file.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise FlyError(f"{inputs.mission_file}: cannot read it as JSON: {err}") from None
    variant, changes = nn_variant(raw, str(model), neighbor_dist, inputs.mission_file)
    missing = [role for role in mission_roles(raw) if role != loaded.role]
    if missing:
        print(f"fly: warning: the model flies role {loaded.role!r}; the mission's {', '.join(missing)} role(s) will "
              "hover with no network for them", file=sys.stderr)

    data_root = args.data_root.expanduser().resolve()
    out = (args.out.expanduser() if args.out is not None else data_root / "mlr" / "fly" / args.name).resolve()
    nn_submission = f"{inputs.submission}{VARIANT_SUFFIX}"
    orca_dataset = storage.StorageKey(inputs.world, inputs.subworld, inputs.mission, inputs.submission,
                                      orca_name).dataset_dir(data_root, 1)
    nn_dataset = storage.StorageKey(inputs.world, inputs.subworld, inputs.mission, nn_submission,
                                    nn_name).dataset_dir(data_root, 1)
    # magna run would stop at such a conflict too, but only after the other batch had flown
    if args.skip_orca:
        if not storage.existing_simulations(orca_dataset):
            raise FlyError(f"--skip-orca: {orca_dataset} holds no simulations; run without --skip-orca first")
    elif args.policy is None and storage.existing_simulations(orca_dataset):
        raise FlyError(f"{orca_dataset} holds simulations already; nothing was started. Choose --append, "
                       "--overwrite, --skip-orca (compare with them) or another --name")
    if args.policy is None and storage.existing_simulations(nn_dataset):
        raise FlyError(f"{nn_dataset} holds simulations already; nothing was started. Choose --append, "
                       "--overwrite or another --name")

    path = write_variant(out, inputs.mission, inputs.submission, variant, args.policy == "overwrite")
    nn_search = [out, *search]
    found = resolve_inputs(world, f"{inputs.mission}/{nn_submission}", nn_search)  # the ground station's checks
    if found.mission_file != path.resolve():
        raise FlyError(f"magna run would fly {found.mission_file} instead of {path}; rename or move it")

    common = ["--world", world, "--n-iter", str(args.n_iter), "--rtf", rtf, "--seed", str(args.seed),
              "--data-root", str(data_root)]
    if args.policy:
        common.append(f"--{args.policy}")
    if args.no_bag:
        common.append("--no-bag")

    def searching(dirs):
        return [arg for d in dirs for arg in ("--search-path", str(d))]

    orca_argv = None if args.skip_orca else [str(magna), "run", *common, "--mission", mission, "--name", orca_name,
                                             *searching(search)]
    nn_argv = [str(magna), "run", *common, "--mission", f"{inputs.mission}/{nn_submission}", "--name", nn_name,
               *searching(nn_search)]
    return FlyPlan(magna, f"{inputs.world}/{inputs.subworld}", f"{inputs.mission}/{inputs.submission}", model, out,
                   path, changes, orca_dataset, nn_dataset, orca_argv, nn_argv)


def run_batch(argv: list[str], stop_wait: float = 180.0) -> tuple[int, bool]:
    """Run one `magna run`; (its exit status, whether we were interrupted). Never leaves it running.

    The batch runs in a session of its own, so a terminal's Ctrl-C reaches only us: we forward
    one SIGINT (SIGTERM likewise), on which magna run stops its simulation, ends every process
    of it and exits 130. Should we leave for another reason, it is stopped the same way, then
    terminated and killed if it does not end.
    """
    process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, start_new_session=True)
    interrupted = threading.Event()

    def forward(signum, _frame):
        if interrupted.is_set():
            print("fly: still waiting for magna run to clean up", file=sys.stderr, flush=True)
            return
        interrupted.set()
        print(f"\nfly: {signal.Signals(signum).name}: stopping the running batch (no further batch starts)",
              file=sys.stderr, flush=True)
        _signal(process, signal.SIGINT)

    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, forward)
    try:
        return process.wait(), interrupted.is_set()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if process.poll() is None:
            _stop(process, stop_wait)


def _signal(process: subprocess.Popen, sig: int, group: bool = False) -> None:
    try:
        if group:
            os.killpg(process.pid, sig)
        else:
            process.send_signal(sig)
    except ProcessLookupError:
        pass


def _stop(process: subprocess.Popen, wait: float) -> None:
    for sig, timeout, group in ((signal.SIGINT, wait, False), (signal.SIGTERM, 30.0, False),
                                (signal.SIGKILL, 10.0, True)):
        _signal(process, sig, group)
        try:
            process.wait(timeout)
            return
        except subprocess.TimeoutExpired:
            continue


def fly(plan: FlyPlan) -> int:
    """Run the batches of `plan`, then compare them; the exit status (module doc)."""
    for change in plan.changes:
        print(f"fly: network mission {plan.variant}: {change}", flush=True)
    codes = []
    for label, argv in (("ORCA-3D", plan.orca_argv), ("network", plan.nn_argv)):
        if argv is None:
            print(f"fly: {label}: reusing {plan.orca_dataset} (--skip-orca)", flush=True)
            continue
        print(f"fly: {label} batch: {' '.join(argv)}", flush=True)
        code, interrupted = run_batch(argv)
        if interrupted or code == 130:
            print(f"fly: interrupted during the {label} batch; no comparison written", file=sys.stderr)
            return 130
        if code not in (0, 1):
            print(f"fly: the {label} batch failed (magna run exit status {code}); see its message above",
                  file=sys.stderr)
            return code
        codes.append(code)
    comparison = Comparison(read_batch(plan.orca_dataset, "ORCA-3D"), read_batch(plan.nn_dataset, "network"),
                            plan.world, plan.mission, str(plan.model), [str(c) for c in plan.changes])
    files = write_comparison(comparison, plan.out)
    print(comparison.markdown(), flush=True)
    print("fly: " + ", ".join(str(f) for f in files), flush=True)
    return 1 if any(codes) else 0


def run(args) -> int:
    from magna_master import storage
    from magna_master.batch import BatchError
    from magna_master.cli import UsageError

    try:
        plan = prepare(args)
        return fly(plan)
    except (FlyError, BatchError, storage.StorageError) as err:
        raise UsageError(" ".join(str(err).split())) from None


def main(argv: list[str] | None = None) -> int:
    """`python -m mlr.fly`: the subcommand on its own."""
    from magna_master.cli import UsageError

    parser = argparse.ArgumentParser(prog="fly", description=HELP)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except UsageError as error:
        print(f"fly: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fly: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
