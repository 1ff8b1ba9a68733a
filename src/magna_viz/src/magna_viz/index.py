"""A dataset's index.html: the summary table of its simulations, each linked to its report.

It reads every simulation_<m>/result.json (magna_common.records.SimulationResult: the same facts
summary.csv holds, and a few more) and
shows the dataset's world.png and mission.png when `magna run` has drawn them. The page links to
the files beside it, so it moves with its dataset folder.
"""
from __future__ import annotations

from pathlib import Path

from magna_common.records import RecordError, SimulationResult
from magna_common.storage_tree import RESULT_FILE, existing_simulations, simulation_dir
from magna_viz import pages
from magna_viz.report import REPORT_FILE

INDEX_FILE = "index.html"


def simulation_dirs(dataset_dir: Path) -> list[Path]:
    """The simulation_<m> folders of a dataset, by m."""
    return [simulation_dir(dataset_dir, m) for m in existing_simulations(dataset_dir)]


def _result(sim_dir: Path) -> SimulationResult | None:
    try:
        return SimulationResult.read(sim_dir / RESULT_FILE)
    except RecordError:
        return None


def write_index(dataset_dir: Path) -> Path:
    """Write (or rewrite: it is derived from the folders) `dataset_dir/index.html`."""
    dataset_dir = Path(dataset_dir)
    rows, durations, successes, collisions = [], [], 0, 0
    sims = simulation_dirs(dataset_dir)
    for sim_dir in sims:
        result = _result(sim_dir)
        report = sim_dir / REPORT_FILE
        name = pages.escape(sim_dir.name)
        link = f'<a href="{name}/{REPORT_FILE}">{name}</a>' if report.exists() else f"{name} (no report)"
        if result is None:
            rows.append((link, "", '<span class="missing">no result.json</span>', "", "", "", "", ""))
            continue
        successes += result.success
        collisions += result.collisions or 0
        durations.append(result.sim_duration)
        rows.append((link, pages.escape("" if result.seed is None else result.seed),
                     '<span class="ok">yes</span>' if result.success else '<span class="bad">no</span>',
                     pages.escape(result.outcome), f"{result.sim_duration:.1f}", f"{result.wall_time:.1f}",
                     pages.escape(result.collisions or 0), pages.escape(result.message)))
    title = "Dataset " + " / ".join(dataset_dir.parts[-6:])
    mean = sum(durations) / len(durations) if durations else 0.0
    parts = [f"<h1>{pages.escape(title)}</h1>", f'<p class="sub">{pages.escape(str(dataset_dir))}</p>',
             f"<p>{len(sims)} simulation(s), {successes} succeeded, {collisions} collision(s) in all; "
             f"mean simulated duration {mean:.1f} s.</p>",
             pages.table(("simulation", "seed", "success", "outcome", "sim s", "wall s", "collisions", "message"),
                         rows, numeric=(1, 4, 5, 6))]
    for picture, caption in (("world.png", "The world"), ("mission.png", "The mission's state machine")):
        if (dataset_dir / picture).exists():
            parts.append(pages.figure(dataset_dir / picture, caption, inline=False, base=dataset_dir))
    return pages.write_page(dataset_dir / INDEX_FILE, pages.page(title, "\n".join(parts)))
