"""One simulation's report: report.html in its folder, self-contained (pictures inlined).

It shows the result (result.json), each UAV's figures, the mission's state machine with the states
that ran highlighted (the branch the mission took), and the plots of magna_viz.plots, which are
also kept as PNGs in `plots/` for papers and slides. A simulation without a usable recording
(it never started, or ran with --no-bag --skip-save) still gets a report: its result and why there
are no plots.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magna_common.records import Hyperparameters, RecordError, SimulationResult
from magna_common.storage_tree import MISSION_FILE, RESULT_FILE
from magna_viz import pages

REPORT_FILE = "report.html"
PLOTS_DIR = "plots"
MISSION_PICTURE = "mission_taken.png"

# The plots in the order the page shows them, with their captions.
CAPTIONS = {
    "trajectories_top": "Top view: each UAV's flown track over the world, planned paths dashed, goals and ends marked.",
    "trajectories_3d": "The same tracks in 3-D.",
    "distances": "Distance to the nearest UAV and to the nearest obstacle; dashed lines are the safety limits.",
    "velocities": "Speed of each UAV over time, with the airframe's maximum.",
    "timeline": "State-machine timeline: which state was active when, and the outcome it ended with.",
    "latency": "Command-to-motion latency (the thesis's Experiment III): from a UAV's action state starting "
               "to the UAV moving.",
}


class ReportError(RuntimeError):
    """A report that cannot be written: says which file and what to do."""


@dataclass
class Report:
    path: Path
    plots: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # what is missing from the page, and why


def read_result(sim_dir: Path) -> SimulationResult:
    path = Path(sim_dir) / RESULT_FILE
    try:
        return SimulationResult.read(path)
    except RecordError as error:
        if error.missing:
            raise ReportError(f"{path}: no such file; a simulation folder of `magna run` holds one "
                              "(give the folder simulation_<m>, or its dataset_<n>)") from None
        raise ReportError(str(error)) from None


def write_report(sim_dir: Path, overwrite: bool = False) -> Report:
    """Draw the plots and write `sim_dir/report.html`; an existing report is kept unless `overwrite`."""
    sim_dir = Path(sim_dir)
    target = sim_dir / REPORT_FILE
    if target.exists() and not overwrite:
        raise ReportError(f"{target}: already exists; pass --force to write it again")
    result = read_result(sim_dir)
    report = Report(target)
    recording = _load(sim_dir, report.notes)
    mission_png = None
    if recording is not None:
        from magna_viz.plots import draw_all

        report.notes += recording.notes
        drawn = draw_all(recording, sim_dir / PLOTS_DIR)
        report.plots = dict(drawn)
        report.notes += [f"no {name} plot: {why}" for name, why in drawn.skipped.items()]
        if recording.timeline is not None:
            mission_png = _mission_picture(sim_dir, recording.timeline, report.notes)
    pages.write_page(target, render(sim_dir, result, recording, report.plots, mission_png, report.notes))
    return report


def _load(sim_dir: Path, notes: list[str]):
    from magna_viz.recording import RecordingError, load_recording

    try:
        return load_recording(sim_dir)
    except RecordingError as error:
        notes.append(f"no plots: {error}")
        return None


def _mission_picture(sim_dir: Path, timeline, notes: list[str]) -> Path | None:
    """The mission's machine (from its mission.json) with every state that ran highlighted."""
    from magna_gs.mission.build import InertFactory, build_machine
    from magna_gs.mission.loader import MissionError, load_mission
    from magna_sm.draw import DrawError, draw_structures, structures_of

    try:
        loaded = load_mission(sim_dir / MISSION_FILE)
        machine = build_machine(loaded.mission, InertFactory(), loaded.plan)
        ran = {interval.path for interval in timeline.intervals}
        return draw_structures(structures_of(machine), sim_dir / PLOTS_DIR / MISSION_PICTURE, ran)
    except (MissionError, DrawError, OSError, ValueError) as error:
        notes.append(f"no mission picture: {error}")
        return None


# --- the page ------------------------------------------------------------------------------------------------------

def render(sim_dir: Path, result: SimulationResult, recording, plots: dict[str, Path], mission_png: Path | None,
           notes: list[str]) -> str:
    hyper = result.hyperparameters or Hyperparameters()
    where = f"{hyper.world or '?'}/{hyper.subworld or '?'}"
    what = f"{hyper.mission or '?'}/{hyper.submission or '?'}"
    title = f"Simulation {_or_blank(result.id) or '?'}: {what} in {where}"
    parts = [f"<h1>{pages.escape(title)}</h1>",
             f'<p class="sub">{pages.escape(str(sim_dir))}</p>',
             "<h2>Result</h2>", _result_table(result)]
    if recording is not None:
        parts += ["<h2>UAVs</h2>", uav_table(recording)]
    parts += [f'<p class="missing">{pages.escape(note)}</p>' for note in notes]
    if mission_png is not None:
        parts += ["<h2>Mission</h2>",
                  pages.figure(mission_png, "The mission's state machine; the states that ran are green.")]
    if plots:
        parts.append("<h2>Plots</h2>")
        parts += [pages.figure(plots[name], caption) for name, caption in CAPTIONS.items() if name in plots]
    parts += ["<h2>Files</h2>", _files(sim_dir),
              "<p>Replay it in rviz: <code>magna replay "
              f"{pages.escape(sim_dir)}</code> (add <code>--headless --gif</code> on a machine without a display). "
              f"Write this page again: <code>magna report {pages.escape(sim_dir)} --force</code>.</p>"]
    return pages.page(title, "\n".join(parts))


def _result_table(result: SimulationResult) -> str:
    verdict = '<span class="ok">success</span>' if result.success else '<span class="bad">failure</span>'
    duration, wall = result.sim_duration, result.wall_time
    rows = [
        ("result", f"{verdict}: {pages.escape(result.outcome)}"),
        ("message", pages.escape(result.message)),
        ("simulated time", f"{duration:.1f} s"),
        ("wall time", f"{wall:.1f} s" + (f" ({duration / wall:.1f}x real time)" if wall > 0 else "")),
        ("collisions", pages.escape(result.collisions or 0)),
        ("ended by", pages.escape(result.termination)),
        ("seed", pages.escape(_or_blank(result.seed))),
        ("world file", pages.escape(_or_blank(result.world_file))),
        ("mission file", pages.escape(_or_blank(result.mission_file))),
        ("started", pages.escape(result.started_at)),
    ]
    return pages.table(None, [(f"<b>{name}</b>", value) for name, value in rows])


def _or_blank(value) -> str:
    """A field of the result as the page shows it: "" when the file did not say."""
    return "" if value is None else str(value)


def uav_table(recording) -> str:
    """One row per UAV: colour, airframe, how far and fast it flew, how close it came to others and obstacles."""
    rows = []
    for uav in recording.uavs.values():
        flown = _path_length(uav.position.xyz)
        speed = uav.velocity.norm() if len(uav.velocity) else np.zeros(0)
        near = uav.proximity
        rows.append((f"{pages.swatch(uav.rgb)} {uav.id}", pages.escape(uav.model), _number(flown, "m"),
                     _number(np.nanmax(speed) if speed.size else math.nan, "m/s"),
                     _number(uav.max_speed, "m/s"),
                     _number(_least(near.uav_distance) if near else math.nan, "m"),
                     _number(_least(near.obstacle_distance) if near else math.nan, "m"),
                     _number(uav.safety_radius, "m"),
                     str(len(near.contact_episodes("uav")) + len(near.contact_episodes("obstacle"))) if near else ""))
    return pages.table(("UAV", "airframe", "flown", "top speed", "max speed", "nearest UAV (centres)",
                        "nearest obstacle", "safety radius", "contacts"), rows, numeric=range(2, 9))


def _path_length(xyz: np.ndarray) -> float:
    steps = np.linalg.norm(np.diff(xyz, axis=0), axis=1) if len(xyz) > 1 else np.zeros(0)
    return float(np.nansum(steps))


def _least(values: np.ndarray) -> float:
    return float(np.nanmin(values)) if values.size and not np.all(np.isnan(values)) else math.nan


def _number(value: float, unit: str) -> str:
    return "" if value is None or math.isnan(value) else f"{value:.2f} {unit}"


def _files(sim_dir: Path) -> str:
    names = sorted(p.name + ("/" if p.is_dir() else "") for p in sim_dir.iterdir()
                   if not p.name.startswith(".") and p.name != REPORT_FILE)
    return "<p>" + ", ".join(f'<a href="{pages.escape(n)}">{pages.escape(n)}</a>' for n in names) + "</p>"
