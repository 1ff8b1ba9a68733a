"""Metrics of the batches `magna learn fly` compares (step 4): collision-free rate and time to goal per batch,
side by side, as Markdown, JSON and a figure."""
from __future__ import annotations

import json
import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.files import write_atomically, write_text_atomically
from magna_common.records import NOT_FLOWN, RecordError, SimulationResult, SummaryRow
from magna_common.storage_tree import RESULT_FILE, SUMMARY_FILE, simulation_dir
from mlr.nn_mission import FlyError

TARGET_RATIO = 0.95  # the project's target: missions flown by the network collision-free at >= 95% of ORCA's rate
MIN_GAP = ("per simulation: the smallest gap between two UAVs' safety spheres (m; below 0 they overlap, a "
           "collision) that any UAV's recorder saw while it flew a `path` role")
TIME_TO_GOAL = ("per UAV and simulation: the time of the UAV's last `path` control step minus its first, "
                "counted when every path role it flew ended 'succeeded' (the recorder's outcome column)")


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
    min_gaps: list[float] = field(default_factory=list)  # per simulation: MIN_GAP

    @property
    def min_gap(self) -> float | None:
        return min(self.min_gaps) if self.min_gaps else None

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
                "times_to_goal": self.times_to_goal, "seeds": self.seeds, "min_gaps": self.min_gaps,
                "min_gap": self.min_gap}


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
    from magna_uav.recorder import read_csv

    dataset_dir = Path(dataset_dir)
    try:
        rows = SummaryRow.read(dataset_dir / SUMMARY_FILE)
    except RecordError as err:
        if not err.missing:
            raise FlyError(str(err)) from None
        rows = []
    if not rows:
        raise FlyError(f"{dataset_dir}: no {SUMMARY_FILE} with simulations; run the batch first "
                       f"(without --skip-orca for the ORCA-3D one)")
    metrics = BatchMetrics(label, dataset_dir)
    for row in rows:
        sim_dir = simulation_dir(dataset_dir, row.id)
        try:
            result: SimulationResult | None = SimulationResult.read(sim_dir / RESULT_FILE)
        except RecordError:
            result = None  # a simulation that never finished writing it: the summary row tells
        if row.outcome in NOT_FLOWN or (result is not None and result.termination in NOT_FLOWN):
            metrics.left_out += 1
            continue
        metrics.simulations += 1
        gaps: list[float] = []
        metrics.successes += row.success
        metrics.collision_free += row.collisions == 0
        if result is not None and result.seed is not None:
            metrics.seeds.append(result.seed)
        for csv_path in sorted(sim_dir.glob("uav_*.csv")):
            try:
                _, uav_rows = read_csv(csv_path)
            except ValueError as err:
                raise FlyError(str(err)) from None
            gaps += [float(row["nearest_uav_gap"]) for row in uav_rows
                     if row["role"] == "path" and math.isfinite(float(row["nearest_uav_gap"]))]
            flew, seconds = path_time_to_goal(uav_rows)
            metrics.uav_paths += flew
            if seconds is not None:
                metrics.times_to_goal.append(seconds)
        if gaps:
            metrics.min_gaps.append(min(gaps))
    return metrics


def side_by_side(batches: list[BatchMetrics], title: str) -> str:
    """A Markdown table of several batches of one mission (`magna learn fly`'s rows, and the minimum gap)."""
    def count(n, total):
        return f"{n}/{total} ({100 * n / total:.0f}%)" if total else "-"

    def seconds(m: BatchMetrics):
        return "-" if m.mean_time_to_goal is None else f"{m.mean_time_to_goal:.1f} ± {m.std_time_to_goal:.1f}"

    def gap(m: BatchMetrics):
        if not m.min_gaps:
            return "-"
        return f"{m.min_gap:.2f} (median {statistics.median(m.min_gaps):.2f})"

    rows = [("simulations", lambda m: str(m.simulations)),
            ("collision-free", lambda m: count(m.collision_free, m.simulations)),
            ("successful missions", lambda m: count(m.successes, m.simulations)),
            ("UAV paths to the goal", lambda m: count(m.goals_reached, m.uav_paths)),
            ("time to goal (s, mean ± std)", seconds),
            ("minimum gap between UAVs (m)", gap)]
    lines = [f"## {title}", "", "| | " + " | ".join(m.label for m in batches) + " |",
             "|---|" + "---:|" * len(batches)]
    lines += [f"| {name} | " + " | ".join(cell(m) for m in batches) + " |" for name, cell in rows]
    lines += ["", f"- time to goal: {TIME_TO_GOAL}", f"- minimum gap: {MIN_GAP}"]
    lines += [f"- {m.label}: `{m.dataset}`" for m in batches]
    return "\n".join(lines) + "\n"


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
    return write_atomically(path, lambda out: figure.savefig(out, format="png", dpi=100), overwrite=True,
                            binary=True)


def write_comparison(comparison: Comparison, out: Path) -> list[Path]:
    """comparison.md, comparison.json and comparison.png in `out`."""

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / "comparison.md", out / "comparison.json"
    write_text_atomically(md, comparison.markdown(), overwrite=True)
    write_text_atomically(js, json.dumps(comparison.to_json(), indent=2) + "\n", overwrite=True)
    return [md, js, draw_comparison(comparison, out / "comparison.png")]


