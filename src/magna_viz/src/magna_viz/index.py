"""A dataset's index.html: the summary table of its simulations, each linked to its report.

It reads every simulation_<m>/result.json (the same facts summary.csv holds, and a few more) and
shows the dataset's world.png and mission.png when `magna run` has drawn them. The page links to
the files beside it, so it moves with its dataset folder.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from magna_viz import pages
from magna_viz.report import REPORT_FILE, RESULT_FILE

INDEX_FILE = "index.html"
_SIMULATION = re.compile(r"^simulation_(\d+)$")


def simulation_dirs(dataset_dir: Path) -> list[Path]:
    """The simulation_<m> folders of a dataset, by m."""
    found = [(int(m.group(1)), p) for p in Path(dataset_dir).iterdir()
             if p.is_dir() and (m := _SIMULATION.match(p.name))]
    return [p for _, p in sorted(found)]


def _result(sim_dir: Path) -> dict | None:
    try:
        data = json.loads((sim_dir / RESULT_FILE).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


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
        ok = bool(result.get("success"))
        successes += ok
        collisions += int(result.get("collisions") or 0)
        duration = float(result.get("sim_duration") or 0.0)
        durations.append(duration)
        rows.append((link, pages.escape(result.get("seed", "")),
                     '<span class="ok">yes</span>' if ok else '<span class="bad">no</span>',
                     pages.escape(result.get("outcome", "")), f"{duration:.1f}",
                     f"{float(result.get('wall_time') or 0.0):.1f}", pages.escape(result.get("collisions", 0)),
                     pages.escape(result.get("message", ""))))
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
