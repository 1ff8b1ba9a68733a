"""What a batch did, and the table `magna run` prints at its end."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from magna_common.records import GROUND_STATION, SimulationResult
from magna_common.storage_tree import BAG_FILE
from magna_master.batch_config import BatchConfig
from magna_master.storage import StoragePlan


@dataclass
class BatchResult:
    config: BatchConfig
    plan: StoragePlan
    simulations: list[SimulationResult]  # each with its folder as `directory` (None when nothing was saved)
    interrupted: bool
    wall_time: float
    storage_error: str = ""  # why the batch stopped early for its storage (a full disk); empty when it did not

    @property
    def dataset_dir(self) -> Path | None:
        return self.plan.dataset_dir

    @property
    def successes(self) -> int:
        return sum(s.success for s in self.simulations)

    @property
    def sim_time(self) -> float:
        return sum(s.sim_duration for s in self.simulations)

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second over the simulations the ground station reported."""
        reported = [s for s in self.simulations if s.reported]
        wall = sum(s.wall_time for s in reported)
        return sum(s.sim_duration for s in reported) / wall if wall > 0 else 0.0

    @property
    def failed_to_run(self) -> list[SimulationResult]:
        return [s for s in self.simulations if s.failed_to_run]

    def bags(self) -> list[Path]:
        return sorted(s.directory / BAG_FILE for s in self.simulations
                      if s.directory is not None and (s.directory / BAG_FILE).is_file())


def status(result: SimulationResult) -> str:
    """One simulation's verdict in a few words: 'success (succeeded)', 'failure (collision)', 'time limit'."""
    if result.termination == GROUND_STATION:
        return ("success" if result.success else "failure") + f" ({result.outcome})"
    return result.termination.replace("_", " ")


def format_summary(batch: BatchResult) -> str:
    """The table `magna run` prints at the end, and where the data is."""
    rows = [("id", "seed", "success", "outcome", "sim s", "wall s", "collisions", "message")]
    for s in batch.simulations:
        message = s.message if len(s.message) <= 70 else s.message[:67] + "..."
        rows.append((str(s.id), str(s.seed), "yes" if s.success else "no", s.outcome, f"{s.sim_duration:.1f}",
                     f"{s.wall_time:.1f}", str(s.collisions or 0), message))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:-1], widths, strict=True)) + "  " + row[-1]
             for row in rows]
    done = [s for s in batch.simulations if not s.interrupted]
    lines.append("")
    lines.append(f"{len(done)} of {len(batch.plan.ids)} simulation(s) run, {batch.successes} succeeded; "
                 f"{batch.sim_time:.1f} simulated s in {batch.wall_time:.1f} wall s "
                 f"({batch.speed:.1f}x faster than real time while simulating)")
    if batch.interrupted:
        stopped = [s for s in batch.simulations if s.interrupted]
        if stopped:
            lines.append(f"interrupted: simulation {stopped[-1].id} was stopped and is marked 'interrupted' (its "
                         "result.json and summary row); the finished ones are kept; no further simulation started")
        else:
            lines.append("interrupted between simulations: every simulation run is complete; no further "
                         "simulation started")
        if batch.plan.save:
            lines.append("         run again with --append to continue the dataset")
    if batch.storage_error:
        lines.append(f"stopped: {batch.storage_error}")
    if batch.plan.save:
        lines.append(f"data:    {batch.dataset_dir} (summary.csv, simulation_<m>/)")
        bags = batch.bags()
        if bags:
            lines.append(f"bags:    {len(bags)} in {batch.dataset_dir}/simulation_<m>/{BAG_FILE}")
        else:
            lines.append("bags:    none" + (" (--no-bag)" if not batch.config.bag else ""))
    else:
        lines.append(f"data:    not saved: {batch.plan.reason}")
    return "\n".join(lines)
