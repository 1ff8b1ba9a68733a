"""The figures of one recorded simulation (magna_viz.recording), as PNGs for the per-simulation report.

    recording = load_recording(sim_dir)
    drawn = draw_all(recording, sim_dir / "plots")   # {"trajectories_3d": Path, ...}; drawn.skipped: {name: why}

One function per figure, each `(recording, out_png) -> out_png`; a figure whose data the recording
lacks (no bag: no timeline, no latency) raises PlotUnavailable, and `draw_all` lists it in `skipped`.

- trajectories_3d / trajectories_top: the world's geometries (translucent, their colours) and obstacles
  (dark), meshed by magna_worlds.draw.shape_mesh; each UAV's flown track in its mission colour, start
  (circle) and end (square), its raw path (dashed, waypoints dotted), smoothed path (dotted) and goals
  (crosses). The top view fills each solid's silhouette. Equal scale on every axis.
- distances: per UAV, the centre distance to the nearest other UAV and the distance from its centre to
  the nearest obstacle's bounding sphere, with the contact thresholds dashed (the safety radii: below
  the line the recorder's gap is negative) and contacts shaded, a cross where each began.
- velocities: speed and vertical velocity per UAV, the airframe's max_speed dashed.
- timeline: one row per state (containers in bold, their children indented under them), bars while
  active, in the UAV's colour for a UAV's state, grey otherwise, with the outcome and the next state
  (the branch taken); states never active while the bag recorded are listed in grey ("not seen": the
  branches not taken, and the first states, which usually end before the bag subscribes).
- latency: command-to-motion latency per UAV (magna_viz.latency), box plot and empirical CDF.

Figures use matplotlib's Agg canvas directly (no pyplot state, safe in any thread), FIGSIZE at DPI
(1000 x 500 pixels), and are written atomically (a temporary file in the target folder, renamed).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, PathPatch
from matplotlib.path import Path as MplPath
from mpl_toolkits.mplot3d import Axes3D
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from magna_common.files import write_atomically
from magna_viz.latency import DEFAULT_THRESHOLD, command_latencies, latency_samples
from magna_viz.recorded_world import WorldShape
from magna_viz.recording import Proximity, Recording, UavRecord
from magna_worlds.draw import MAX_ALPHA, MIN_ALPHA, OBSTACLE_COLOR, content_bounds, shape_mesh

FIGSIZE = (10.0, 5.0)  # inches
DPI = 100
FIGURES = ("trajectories_3d", "trajectories_top", "distances", "velocities", "timeline", "latency")
NEUTRAL = (0.55, 0.55, 0.58)  # states not tied to one UAV
CONTACT = "#d62728"
ROW_HEIGHT = 0.15  # inches per timeline row: the figure grows past FIGSIZE beyond this many rows
MAX_LEGEND_UAVS = 12


class PlotUnavailable(RuntimeError):
    """The recording lacks what a figure needs; the message says what."""


class DrawnPlots(dict[str, Path]):
    """{name: PNG path} of the figures drawn, and `skipped` {name: why} for the others."""

    def __init__(self) -> None:
        super().__init__()
        self.skipped: dict[str, str] = {}


# --- shared helpers ------------------------------------------------------------------------------------------------

def _figure(size: tuple[float, float] = FIGSIZE) -> Figure:
    fig = Figure(figsize=size, dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, out_png: Path, dpi: int = DPI) -> Path:
    return write_atomically(out_png, lambda out: fig.savefig(out, format="png", dpi=dpi), overwrite=True, binary=True)


def _uavs_with(recording: Recording, what: str) -> list[UavRecord]:
    return [u for u in recording.uavs.values() if len(getattr(u, what))]


def _face_alpha(alpha: float) -> float:
    """magna_worlds.draw's mapping: never invisible, never hiding the tracks inside."""
    return MIN_ALPHA + (MAX_ALPHA - MIN_ALPHA) * float(min(max(alpha, 0.0), 1.0))


def _outline_rgb(color: Sequence[float]) -> tuple[float, float, float]:
    r, g, b = 0.55 * np.asarray(color, dtype=float) + 0.45 * 0.15
    return float(r), float(g), float(b)


def _mesh(shape: WorldShape) -> tuple[list[np.ndarray], list[np.ndarray]]:
    faces, outline = shape_mesh(shape.spec)
    return [shape.frame.apply(f) for f in faces], [shape.frame.apply(o) for o in outline]


def _uav_label(u: UavRecord) -> str:
    return f"{u.name} ({u.model})" if u.model != "?" else u.name


def _style_legend(has_paths: bool, has_goals: bool, n_obstacles: int, n_geometries: int) -> list[Artist]:
    handles: list[Artist] = [
        Line2D([], [], color="black", marker="o", linestyle="", markersize=6, markerfacecolor="white", label="start"),
        Line2D([], [], color="black", marker="s", linestyle="", markersize=6, label="end")]
    if has_paths:
        handles += [Line2D([], [], color="black", linestyle="--", linewidth=0.9, label="raw path"),
                    Line2D([], [], color="black", linestyle=":", linewidth=1.4, label="smoothed path")]
    if has_goals:
        handles.append(Line2D([], [], color="black", marker="x", linestyle="", markersize=6, label="goals"))
    if n_geometries:
        handles.append(Patch(facecolor=(*NEUTRAL, 0.3), edgecolor=NEUTRAL, label=f"world geometries ({n_geometries})"))
    if n_obstacles:
        handles.append(Patch(facecolor=OBSTACLE_COLOR, edgecolor="black", label=f"obstacles ({n_obstacles})"))
    return handles


def _uav_legend(uavs: list[UavRecord]) -> list[Artist]:
    shown = uavs[:MAX_LEGEND_UAVS]
    handles: list[Artist] = [Line2D([], [], color=u.rgb, linewidth=2.0, label=_uav_label(u)) for u in shown]
    if len(uavs) > len(shown):
        handles.append(Patch(facecolor="none", edgecolor="none", label=f"... and {len(uavs) - len(shown)} more"))
    return handles


def _gapped(t: np.ndarray, *series: np.ndarray) -> tuple[np.ndarray, ...]:
    """The series with a NaN put in every pause of the recording (a step over 5 typical steps and over 1 s),
    so a line is not drawn across time without data (a manager records nothing between some roles)."""
    if len(t) < 3:
        return (t, *series)
    step = np.diff(t)
    pause = np.flatnonzero(step > max(1.0, 5.0 * float(np.median(step))))
    if not len(pause):
        return (t, *series)
    at = pause + 1
    return (np.insert(t, at, t[pause] + step[pause] / 2.0), *(np.insert(np.asarray(y, dtype=float), at, np.nan, axis=0)
                                                               for y in series))


def _shared(values: Sequence[float]) -> float | None:
    """The one finite value all of `values` have, else None (several, or none finite)."""
    finite = {round(float(v), 9) for v in values if math.isfinite(v)}
    return finite.pop() if len(finite) == 1 else None


def _no_tracks(recording: Recording) -> PlotUnavailable:
    return PlotUnavailable(f"{recording.sim_dir}: no UAV positions in the bag or the CSVs")


# --- trajectories --------------------------------------------------------------------------------------------------

def plot_trajectories_3d(recording: Recording, out_png: Path) -> Path:
    """The flown tracks over the world, in 3-D."""
    uavs = _uavs_with(recording, "position")
    if not uavs:
        raise _no_tracks(recording)
    fig = _figure()
    # computed_zorder=False: by layer: world, obstacles, then tracks on top
    ax = Axes3D(fig, (-0.06, -0.1, 0.84, 1.12), computed_zorder=False)
    fig.add_axes(ax)
    points: list[np.ndarray] = []
    for shape in recording.world.geometries:
        faces, outline = _mesh(shape)
        face = [(*shape.color, _face_alpha(shape.alpha))]
        # autolim=False: the limits come from the content (matplotlib's autoscale misreads ragged polygons)
        ax.add_collection3d(Poly3DCollection(faces, facecolors=face, edgecolors=face, linewidths=0.0, shade=True,
                                             zorder=1), autolim=False)
        ax.add_collection3d(Line3DCollection(outline, colors=[(*_outline_rgb(shape.color), 0.6)], linewidths=0.6,
                                             zorder=2), autolim=False)
        points.append(np.vstack(outline))
    obstacle_faces: list[np.ndarray] = []
    obstacle_lines: list[np.ndarray] = []
    for shape in recording.world.obstacles:
        faces, outline = _mesh(shape)
        obstacle_faces += faces
        obstacle_lines += outline
    if obstacle_faces:
        solid = [(*OBSTACLE_COLOR, 1.0)]
        ax.add_collection3d(Poly3DCollection(obstacle_faces, facecolors=solid, edgecolors=solid, linewidths=0.0,
                                             shade=True, zorder=3), autolim=False)
        ax.add_collection3d(Line3DCollection(obstacle_lines, colors="black", linewidths=0.4, zorder=4), autolim=False)
        points.append(np.vstack(obstacle_lines))
    for u in uavs:
        xyz = u.position.xyz
        points.append(xyz)
        for path in u.raw_paths:
            ax.plot(*path.points.T, color=u.rgb, linestyle="--", linewidth=0.9, alpha=0.8, zorder=5)
            points.append(path.points)
        for path in u.smoothed_paths:
            ax.plot(*path.points.T, color=u.rgb, linestyle=":", linewidth=1.4, alpha=0.9, zorder=5)
        ax.plot(*xyz.T, color=u.rgb, linewidth=1.8, zorder=6)
        ax.scatter(*xyz[:1].T, s=36, marker="o", facecolors="white", edgecolors=[u.rgb], linewidths=1.5,
                   depthshade=False, zorder=7)
        ax.scatter(*xyz[-1:].T, s=30, marker="s", color=[u.rgb], edgecolors="black", linewidths=0.5,
                   depthshade=False, zorder=7)
        if len(u.goals):
            ax.scatter(*u.goals.xyz.T, s=30, marker="x", color=[u.rgb], depthshade=False, zorder=7)
    low, high = content_bounds(points)
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_zlim(low[2], high[2])
    ax.set_box_aspect(tuple(high - low))  # equal metres per unit on every axis
    ax.view_init(elev=28.0, azim=-60.0)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.tick_params(labelsize=7)
    return _finish_trajectories(fig, recording, uavs, "Trajectories", legend_x=0.73, out_png=out_png)


def _silhouette(faces: list[np.ndarray]) -> MplPath | None:
    """The union of the faces seen from above: every face counter-clockwise in one path, filled non-zero."""
    verts: list[np.ndarray] = []
    codes: list[np.uint8] = []
    for face in faces:
        xy = face[:, :2]
        area = 0.5 * float(np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]))
        if abs(area) < 1e-9:  # an upright face: an edge from above
            continue
        if area < 0:
            xy = xy[::-1]
        verts += [*xy, xy[0]]
        codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(xy) - 1) + [MplPath.CLOSEPOLY]
    return MplPath(np.array(verts), codes) if verts else None


def _flat_outline(outline: list[np.ndarray]) -> list[np.ndarray]:
    """The horizontal rims of an outline (box edges, circles): from above, the others are points or chords."""
    flat = [o[:, :2] for o in outline if np.ptp(o[:, 2]) < 1e-6 * max(1.0, float(np.ptp(o[:, :2])))]
    return flat or [o[:, :2] for o in outline]


def plot_trajectories_top(recording: Recording, out_png: Path) -> Path:
    """The flown tracks over the world, seen from above."""
    uavs = _uavs_with(recording, "position")
    if not uavs:
        raise _no_tracks(recording)
    fig = _figure()
    ax = fig.add_axes((0.07, 0.1, 0.6, 0.8))
    points: list[np.ndarray] = []
    # lower solids first, so what is on top of them draws over
    shapes = sorted(recording.world.shapes, key=lambda s: (s.kind == "obstacle", float(s.frame.translation[2])))
    for shape in shapes:
        faces, outline = _mesh(shape)
        silhouette = _silhouette(faces)
        if silhouette is None:
            continue
        if shape.kind == "obstacle":
            ax.add_patch(PathPatch(silhouette, facecolor=OBSTACLE_COLOR, edgecolor="none", zorder=3))
        else:
            ax.add_patch(PathPatch(silhouette, facecolor=(*shape.color, _face_alpha(shape.alpha)), edgecolor="none",
                                   zorder=1))
            for line in _flat_outline(outline):
                ax.plot(line[:, 0], line[:, 1], color=_outline_rgb(shape.color), linewidth=0.6, alpha=0.7, zorder=2)
        points.append(np.asarray(silhouette.vertices))
    for u in uavs:
        xy = u.position.xyz[:, :2]
        points.append(xy)
        for path in u.raw_paths:
            ax.plot(*path.points[:, :2].T, color=u.rgb, linestyle="--", linewidth=0.9, alpha=0.8, zorder=4)
            ax.plot(*path.points[:, :2].T, color=u.rgb, linestyle="", marker=".", markersize=3, zorder=4)
            points.append(path.points[:, :2])
        for path in u.smoothed_paths:
            ax.plot(*path.points[:, :2].T, color=u.rgb, linestyle=":", linewidth=1.4, alpha=0.9, zorder=4)
        ax.plot(*xy.T, color=u.rgb, linewidth=1.8, zorder=5)
        ax.plot(*xy[0], marker="o", markersize=7, markerfacecolor="white", markeredgecolor=u.rgb,
                markeredgewidth=1.5, zorder=6)
        ax.plot(*xy[-1], marker="s", markersize=6, color=u.rgb, markeredgecolor="black", markeredgewidth=0.5,
                zorder=6)
        if len(u.goals):
            ax.plot(*u.goals.xyz[:, :2].T, linestyle="", marker="x", markersize=6, color=u.rgb, zorder=6)
    stacked = np.vstack(points)
    low, high = stacked.min(axis=0), stacked.max(axis=0)
    margin = 0.04 * max(float(np.max(high - low)), 1.0)
    ax.set_xlim(low[0] - margin, high[0] + margin)
    ax.set_ylim(low[1] - margin, high[1] + margin)
    ax.set_aspect("equal", adjustable="box")
    ax.set_anchor("E")  # a tall world's narrowed axes stay next to the legend
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.tick_params(labelsize=8)
    ax.grid(True, linewidth=0.3, alpha=0.5)
    return _finish_trajectories(fig, recording, uavs, "Top view", legend_x=0.7, out_png=out_png)


def _finish_trajectories(fig: Figure, recording: Recording, uavs: list[UavRecord], title: str, legend_x: float,
                         out_png: Path) -> Path:
    """The legend both trajectory figures share (UAVs, then the kinds of line and shape), the title, the file."""
    has_paths = any(u.raw_paths or u.smoothed_paths for u in uavs)
    handles = _uav_legend(uavs) + _style_legend(has_paths, any(len(u.goals) for u in uavs),
                                                len(recording.world.obstacles), len(recording.world.geometries))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(legend_x, 0.9), fontsize=8, frameon=False)
    fig.suptitle(f"{title}: {recording.title}", x=0.02, y=0.97, ha="left", fontsize=10)
    return _save(fig, out_png)


# --- distances and velocities --------------------------------------------------------------------------------------

def plot_distances(recording: Recording, out_png: Path) -> Path:
    """Distance to the nearest UAV and obstacle over time per UAV, contact thresholds dashed, contacts marked."""
    measured: list[tuple[UavRecord, Proximity]] = [(u, u.proximity) for u in recording.uavs.values()
                                                   if u.proximity is not None and len(u.proximity.time)]
    if not measured:
        raise PlotUnavailable(f"{recording.sim_dir}: no distances: no CSV gaps and no positions in the bag")
    fig = _figure()
    top = fig.add_axes((0.08, 0.55, 0.68, 0.35))
    bottom = fig.add_axes((0.08, 0.1, 0.68, 0.35), sharex=top)
    episodes = 0
    # one black line when every UAV has the same threshold, else each its own in its colour
    pair = _shared([v for _, p in measured for v in p.uav_threshold])
    own = _shared([p.obstacle_threshold for _, p in measured])
    for value, ax in ((pair, top), (own, bottom)):
        if value is not None:
            ax.axhline(value, color="black", linestyle="--", linewidth=0.9)
    for k, (u, p) in enumerate(measured):
        t, uav_distance, obstacle_distance, threshold = _gapped(p.time, p.uav_distance, p.obstacle_distance,
                                                                p.uav_threshold)
        # a pair's distance is the same for both: the first drawn wider, so both colours show
        width = max(1.0, 2.4 - 0.6 * k)
        top.plot(t, uav_distance, color=u.rgb, linewidth=width)
        bottom.plot(t, obstacle_distance, color=u.rgb, linewidth=width)
        if pair is None:
            top.plot(t, threshold, color=u.rgb, linestyle="--", linewidth=0.9, alpha=0.8)
        if own is None and math.isfinite(p.obstacle_threshold):
            bottom.axhline(p.obstacle_threshold, color=u.rgb, linestyle="--", linewidth=0.9, alpha=0.8)
        for ax, kind, values in ((top, "uav", p.uav_distance), (bottom, "obstacle", p.obstacle_distance)):
            for start, end in p.contact_episodes(kind):  # shaded while touching, a cross where it began
                ax.axvspan(start, max(end, start + 0.05), color=CONTACT, alpha=0.15, linewidth=0)
                at = float(np.interp(start, p.time, np.nan_to_num(values, nan=0.0)))
                ax.plot(start, at, linestyle="", marker="x", markersize=7, markeredgewidth=1.6, color=CONTACT,
                        zorder=5)
                episodes += 1
    top.set_ylabel("nearest UAV\ncentre distance (m)", fontsize=8)
    bottom.set_ylabel("nearest obstacle\ndistance (m)", fontsize=8)
    bottom.set_xlabel("simulated time (s)")
    for ax in (top, bottom):
        ax.set_ylim(bottom=0.0)
        ax.grid(True, linewidth=0.3, alpha=0.5)
        ax.tick_params(labelsize=8)
    top.tick_params(labelbottom=False)
    sources = sorted({p.source for _, p in measured})
    handles = _uav_legend([u for u, _ in measured]) + [
        Line2D([], [], color="black", linestyle="--", linewidth=0.9, label="contact below: the safety radii\n"
               "(UAV pair: both; obstacle: own)"),
        Line2D([], [], color=CONTACT, marker="x", linestyle="", markersize=7, label=f"contact began ({episodes})"),
        Patch(facecolor=CONTACT, alpha=0.15, label="in contact")]
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.78, 0.9), fontsize=8, frameon=False)
    fig.text(0.78, 0.12, "obstacles: their bounding spheres,\nas the UAVs see them\nfrom: " + ", ".join(sources),
             fontsize=7, color="0.3", va="bottom")
    collisions = recording.result.collisions if recording.result else None
    fig.suptitle(f"Distances: {recording.title}" + (f" ({collisions} collisions)" if collisions is not None else ""),
                 x=0.02, y=0.97, ha="left", fontsize=10)
    return _save(fig, out_png)


def plot_velocities(recording: Recording, out_png: Path) -> Path:
    """Speed and vertical velocity per UAV over time, the airframes' max speeds dashed."""
    uavs = _uavs_with(recording, "velocity")
    if not uavs:
        raise PlotUnavailable(f"{recording.sim_dir}: no UAV velocities in the bag or the CSVs")
    fig = _figure()
    top = fig.add_axes((0.08, 0.45, 0.68, 0.45))
    bottom = fig.add_axes((0.08, 0.1, 0.68, 0.27), sharex=top)
    shared = _shared([u.max_speed for u in uavs])
    for u in uavs:
        t, speed, vz = _gapped(u.velocity.time, u.velocity.norm(), u.velocity.xyz[:, 2])
        top.plot(t, speed, color=u.rgb, linewidth=1.2)
        bottom.plot(t, vz, color=u.rgb, linewidth=1.0)
        if shared is None and math.isfinite(u.max_speed):
            top.axhline(u.max_speed, color=u.rgb, linestyle="--", linewidth=0.9, alpha=0.8)
    if shared is not None:
        top.axhline(shared, color="black", linestyle="--", linewidth=0.9)
    bottom.axhline(0.0, color="0.5", linewidth=0.6)
    top.set_ylabel("speed |v| (m/s)", fontsize=8)
    bottom.set_ylabel("vertical vz (m/s)", fontsize=8)
    bottom.set_xlabel("simulated time (s)")
    top.set_ylim(bottom=0.0)
    top.tick_params(labelbottom=False)
    for ax in (top, bottom):
        ax.grid(True, linewidth=0.3, alpha=0.5)
        ax.tick_params(labelsize=8)
    handles = _uav_legend(uavs) + [Line2D([], [], color="black", linestyle="--", linewidth=0.9,
                                          label="airframe max_speed")]
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.78, 0.9), fontsize=8, frameon=False)
    sources = sorted({u.velocity.source for u in uavs})
    fig.text(0.78, 0.12, "from: " + ", ".join(sources), fontsize=7, color="0.3", va="bottom")
    fig.suptitle(f"Velocities: {recording.title}", x=0.02, y=0.97, ha="left", fontsize=10)
    return _save(fig, out_png)


# --- the state-machine timeline ------------------------------------------------------------------------------------

def plot_timeline(recording: Recording, out_png: Path) -> Path:
    """Which state was active when: one row per state, grouped under its container."""
    timeline = recording.timeline
    if timeline is None:
        raise PlotUnavailable(f"{recording.sim_dir}: no state-machine timeline without simulation.bag")
    if not timeline.intervals:
        raise PlotUnavailable(f"{recording.sim_dir}: the bag has no state-machine status messages")
    rows = list(timeline.states)
    n = len(rows)
    height = max(FIGSIZE[1], ROW_HEIGHT * n + 1.1)
    fig = _figure((FIGSIZE[0], height))
    ax = fig.add_axes((0.2, 0.7 / height, 0.62, 1.0 - 1.2 / height))
    index = {s.path: k for k, s in enumerate(rows)}
    t0 = min(i.start for i in timeline.intervals)
    t1 = max(i.end for i in timeline.intervals)
    span = max(t1 - t0, 1e-3)
    for interval in timeline.intervals:
        y = index[interval.path]
        uav = recording.uavs.get(interval.uav_id) if interval.uav_id is not None else None
        state = timeline.state(interval.path)
        container = state.is_container if state else False
        color = uav.rgb if uav else NEUTRAL
        width = max(interval.duration, span * 0.002)  # an instant state still shows
        ax.broken_barh([(interval.start, width)], (y - 0.35, 0.7), facecolors=[(*color, 0.35 if container else 0.9)],
                       edgecolors=[color], linewidths=0.6)
        if interval.started_before:
            ax.plot(interval.start, y, marker="<", color="black", markersize=4)
        text = interval.outcome or ("(still active)" if interval.unfinished else "")
        if interval.next_state:
            text += f" \u2192 {interval.next_state}"
        if text:
            ax.text(interval.start + width + span * 0.005, y, text, fontsize=6, va="center", color="0.2",
                    clip_on=True)
    labels = []
    for s in rows:
        ran = timeline.ran(s.path)
        labels.append(("    " * s.depth) + s.label + ("" if ran else "  (not seen)"))
    ax.set_yticks(range(n), labels)
    for tick, s in zip(ax.get_yticklabels(), rows, strict=True):
        tick.set_fontsize(7)
        if s.is_container:
            tick.set_fontweight("bold")
        if not timeline.ran(s.path):
            tick.set_color("0.6")
            tick.set_fontstyle("italic")
    ax.set_ylim(n - 0.5, -0.5)
    ax.set_xlim(t0 - span * 0.01, t1 + span * 0.25)  # room for the last outcome
    ax.set_xlabel("simulated time (s)")
    ax.grid(True, axis="x", linewidth=0.3, alpha=0.5)
    ax.tick_params(axis="x", labelsize=8)
    uavs = [u for u in recording.uavs.values() if any(i.uav_id == u.id for i in timeline.intervals)]
    handles: list[Artist] = [Patch(facecolor=(*u.rgb, 0.9), edgecolor=u.rgb, label=f"{u.name}'s state")
                             for u in uavs]
    handles += [Patch(facecolor=(*NEUTRAL, 0.9), edgecolor=NEUTRAL, label="mission state"),
                Patch(facecolor=(*NEUTRAL, 0.35), edgecolor=NEUTRAL, label="container (bold)")]
    if any(i.started_before for i in timeline.intervals):
        handles.append(Line2D([], [], color="black", marker="<", linestyle="", markersize=4,
                              label="began before the bag"))
    if any(not timeline.ran(s.path) for s in rows):
        handles.append(Patch(facecolor="none", edgecolor="none", label="(not seen): never active\nwhile the bag "
                             "recorded"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.83, 1.0 - 0.5 / height), fontsize=7,
               frameon=False)
    outcome = f", mission outcome: {timeline.outcome}" if timeline.outcome else ""
    fig.suptitle(f"State machine: {recording.title}{outcome}", x=0.02, y=1.0 - 0.15 / height, ha="left",
                 va="top", fontsize=10)
    return _save(fig, out_png)


# --- latency -------------------------------------------------------------------------------------------------------

def plot_latency_distribution(samples: Mapping[str, Sequence[float]], out_png: Path, title: str, unit: str = "ms",
                              *, value_label: str | None = None, group_label: str = "",
                              reference: tuple[float, str] | None = None, whiskers: tuple[float, float] = (5, 95),
                              colors: Mapping[str, object] | None = None) -> Path:
    """Box plot (whiskers at the `whiskers` percentiles, every sample dotted over it) and empirical CDF of
    latencies per group, side by side.

    `samples` maps a group's name to its latencies, already in `unit`; empty groups are left out (ValueError
    if all are). `reference` (value, label) draws a dashed red line on both panels, e.g. a target; `colors`
    gives groups their colours (matplotlib colours), the others take the default cycle.
    """
    groups = {str(k): np.asarray(v, dtype=float) for k, v in samples.items() if len(v)}
    if not groups:
        raise ValueError("no latency samples to draw")
    cycle = [f"C{k}" for k in range(10)]
    palette = {name: (colors or {}).get(name, cycle[k % len(cycle)]) for k, name in enumerate(groups)}
    label = value_label or f"latency ({unit})"
    fig = _figure()
    box = fig.add_axes((0.08, 0.14, 0.38, 0.7))
    cdf = fig.add_axes((0.57, 0.14, 0.4, 0.7))
    box.boxplot(list(groups.values()), whis=whiskers, showfliers=False, medianprops={"color": "black"})
    jitter = np.random.default_rng(0)  # fixed: the same data draws the same picture
    for k, (name, values) in enumerate(groups.items(), start=1):
        box.plot(k + jitter.uniform(-0.12, 0.12, len(values)), values, linestyle="", marker="o", markersize=3.5,
                 alpha=0.8, color=palette[name], zorder=3)
    box.set_xticks(range(1, len(groups) + 1), [f"{name}\n(n={len(v)})" for name, v in groups.items()])
    box.set_xlabel(group_label)
    box.set_ylabel(label)
    box.set_title(f"boxes: quartiles and median; whiskers: p{whiskers[0]:g}-p{whiskers[1]:g}", fontsize=9)
    for name, values in groups.items():
        ordered = np.sort(values)
        cdf.step(np.concatenate([[ordered[0]], ordered]), np.arange(len(ordered) + 1) / len(ordered), where="post",
                 label=name, color=palette[name])
    if reference is not None:
        box.axhline(reference[0], color="tab:red", linestyle="--", linewidth=1, label=reference[1])
        cdf.axvline(reference[0], color="tab:red", linestyle="--", linewidth=1)
        box.legend(loc="upper left", fontsize=8)
    cdf.axhline(0.5, color="grey", linestyle=":", linewidth=1)
    cdf.set_xlabel(label)
    cdf.set_ylabel("fraction of commands")
    cdf.set_ylim(0.0, 1.02)
    cdf.set_title("empirical CDF", fontsize=9)
    cdf.legend(loc="lower right", fontsize=8)
    for ax in (box, cdf):
        ax.grid(True, linewidth=0.3, alpha=0.5)
        ax.tick_params(labelsize=8)
    fig.suptitle(title, x=0.02, y=0.98, ha="left", va="top", fontsize=10)
    return _save(fig, out_png)


def plot_latency(recording: Recording, out_png: Path, threshold: float = DEFAULT_THRESHOLD) -> Path:
    """Command-to-motion latency of this simulation's commands from rest, per UAV (magna_viz.latency)."""
    if recording.timeline is None:
        raise PlotUnavailable(f"{recording.sim_dir}: no commands without simulation.bag (the timeline)")
    latencies = command_latencies(recording, threshold)
    samples = latency_samples(latencies)
    if not samples:
        raise PlotUnavailable(f"{recording.sim_dir}: no action state of a UAV began while it hovered and was "
                              f"followed by motion above {threshold:g} m/s")
    unmoved = sum(1 for c in latencies if c.latency is None)
    title = (f"Command-to-motion latency: {recording.title}\naction state of a hovering UAV active -> its first "
             f"|v| > {threshold:g} m/s, simulated time" + (f"; {unmoved} command(s) without motion" if unmoved else ""))
    colors = {f"UAV {u.id}": u.rgb for u in recording.uavs.values()}
    return plot_latency_distribution(samples, out_png, title, "ms", value_label="command -> first motion (ms)",
                                     group_label="UAV", colors=colors)


# --- all of them ---------------------------------------------------------------------------------------------------

PLOTTERS = {
    "trajectories_3d": plot_trajectories_3d,
    "trajectories_top": plot_trajectories_top,
    "distances": plot_distances,
    "velocities": plot_velocities,
    "timeline": plot_timeline,
    "latency": plot_latency,
}


def draw_all(recording: Recording, out_dir: Path) -> DrawnPlots:
    """Every figure the recording has data for, as `out_dir/<name>.png`; the others in `.skipped` with why."""
    out_dir = Path(out_dir)
    drawn = DrawnPlots()
    for name, plot in PLOTTERS.items():
        try:
            drawn[name] = plot(recording, out_dir / f"{name}.png")
        except PlotUnavailable as why:
            drawn.skipped[name] = str(why)
    return drawn


__all__ = ["DPI", "FIGSIZE", "FIGURES", "DrawnPlots", "PlotUnavailable", "draw_all", "plot_distances",
           "plot_latency", "plot_latency_distribution", "plot_timeline", "plot_trajectories_3d",
           "plot_trajectories_top", "plot_velocities"]
