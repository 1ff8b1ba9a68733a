"""A recorded simulation folder -> typed data for the plots and the report (no ROS master, no rospy).

A simulation folder (magna_common.storage_tree) holds:

    simulation.bag  what the ground station bagged: /uav_N/ual/pose and velocity, /magna/uav_N/goal,
                    path/raw and path/smoothed, /magna/world/markers, /magna/sm/<machine>/status and structure
                    (read through magna_common.simulation_bag)
    uav_<id>.csv    each UAV manager's recorder rows (magna_uav.recorder), about 10 per simulated second
                    while the UAV had a role, with the gaps its evaluator judged safety on
    mission.json    the mission flown: each UAV's model (-> airframe: safety radius, max speed) and colour
    world.json      the world node's record of every world part (magna_common.records.WorldRecord, drawn by
                    magna_viz.recorded_world)
    result.json     the batch's verdict (magna_common.records.SimulationResult)

Either the bag or the CSVs may be missing (`magna run --no-bag` / `--skip-save`): what exists is used and
`Recording.notes` says what is missing and what that costs. Per UAV, positions and velocities come from
the bag (the simulator's 30 Hz) when it has them, else from the CSV. So do distances: computed from the
bag as the managers' evaluator computes them (centre distance to every other UAV; distance to the real
shape of the obstacles of /magna/world/markers), which covers the whole flight where a manager records
rows only while a role runs, and agrees with the CSV's gaps where both exist (within the managers' pose
age, centimetres); the CSV's gaps and collision flags when the bag lacks the UAV's poses or the markers.
The state-machine timeline, paths and goals exist only in the bag. Times are simulated seconds, the
clock of the simulation (the bag starts near 0).
"""
from __future__ import annotations

import math
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from magna_common.records import RecordError, SimulationResult
from magna_common.ros_names import WORLD_MARKERS
from magna_common.simulation_bag import MARKERS, SM_KINDS, UAL_KINDS, BagError, read_simulation_bag
from magna_common.storage_tree import BAG_FILE, MISSION_FILE, RESULT_FILE, WORLD_FILE
from magna_viz.recorded_world import RecordedWorld, world_from_markers, world_from_record
from magna_viz.timeline import StatusEvent, Timeline, build_timeline

if TYPE_CHECKING:
    from magna_uav.shapes import ShapeTable

CSV_PATTERN = re.compile(r"uav_(\d+)\.csv")
DEFAULT_COLORS = ((0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
                  (0.58, 0.4, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5))
_BAG_KINDS = (*UAL_KINDS, "goal", "path/raw", "path/smoothed", *SM_KINDS, MARKERS)  # all but the navigation steps
_CSV_COLUMNS = ("time", "pos.x", "pos.y", "pos.z", "vel.x", "vel.y", "vel.z", "nearest_uav_gap",
                "nearest_obstacle_gap", "collision")


class RecordingError(ValueError):
    """A simulation folder that cannot be plotted; the message names the file and what to do."""


@dataclass(frozen=True)
class Samples:
    """Vectors over time: `time` (n,) in simulated s, increasing; `xyz` (n, 3)."""

    time: np.ndarray
    xyz: np.ndarray
    source: str = ""  # the file they came from

    @staticmethod
    def empty(source: str = "") -> Samples:
        return Samples(np.zeros(0), np.zeros((0, 3)), source)

    def __len__(self) -> int:
        return len(self.time)

    def norm(self) -> np.ndarray:
        return np.linalg.norm(self.xyz, axis=1)

    def at(self, times) -> np.ndarray:
        """(k, 3) the newest vector at or before each time; NaN before the first."""
        k = np.searchsorted(self.time, np.asarray(times, dtype=float), side="right") - 1
        out = np.full((len(k), 3), np.nan)
        out[k >= 0] = self.xyz[k[k >= 0]]
        return out


@dataclass(frozen=True)
class PathRecord:
    """One path a UAV was given (nav_msgs/Path), and when."""

    time: float
    points: np.ndarray  # (n, 3) in map


@dataclass(frozen=True)
class Proximity:
    """Distances to the nearest other UAV and obstacle over time. A distance below its threshold is a contact,
    what the UAV managers' evaluator calls a collision (the recorder's gap = distance - threshold < 0)."""

    time: np.ndarray
    uav_distance: np.ndarray  # centre to centre, nearest other UAV by gap (NaN: none known)
    uav_threshold: np.ndarray  # the pair's safety radii summed
    obstacle_distance: np.ndarray  # own centre to the nearest obstacle's surface (real shape; NaN: none)
    obstacle_threshold: float  # own safety radius
    uav_contact: np.ndarray  # bool per sample: touching another UAV
    obstacle_contact: np.ndarray  # bool per sample: touching an obstacle
    source: str

    def contact_episodes(self, kind: str) -> list[tuple[float, float]]:
        """(first, last sample time) of each run of contact samples; `kind` "uav" or "obstacle"."""
        flags = self.uav_contact if kind == "uav" else self.obstacle_contact
        edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
        return [(float(self.time[a]), float(self.time[b])) for a, b in zip(starts, ends, strict=True)]


@dataclass
class UavRecord:
    id: int
    model: str
    color: tuple[float, float, float, float]  # mission marker colour, 0..1 (alpha as the mission gives it)
    safety_radius: float  # m (NaN when the mission is missing)
    max_speed: float  # m/s (NaN when the mission is missing)
    position: Samples
    velocity: Samples
    raw_paths: list[PathRecord] = field(default_factory=list)
    smoothed_paths: list[PathRecord] = field(default_factory=list)
    goals: Samples = field(default_factory=Samples.empty)  # each new goal, when first given
    proximity: Proximity | None = None

    @property
    def name(self) -> str:
        return f"UAV {self.id}"

    @property
    def rgb(self) -> tuple[float, float, float]:
        return self.color[:3]


@dataclass
class Recording:
    sim_dir: Path
    uavs: dict[int, UavRecord]  # by id, sorted
    world: RecordedWorld
    timeline: Timeline | None  # None without a bag
    result: SimulationResult | None
    bag: Path | None  # None when missing or unreadable
    csvs: dict[int, Path]
    start: float  # first and last simulated time of any data
    end: float
    notes: list[str] = field(default_factory=list)  # what is missing and what it costs

    @property
    def title(self) -> str:
        h = self.result.hyperparameters if self.result else None
        if h is not None and h.mission:
            return (f"{h.mission}/{h.submission} in {h.world}/{h.subworld}, "
                    f"simulation {'?' if h.n_simulation is None else h.n_simulation}")
        return self.sim_dir.name


# --- loading -------------------------------------------------------------------------------------------------------

def load_recording(sim_dir: str | Path) -> Recording:
    """Read one simulation folder (module docstring); RecordingError when it holds nothing to plot."""
    sim_dir = Path(sim_dir)
    if not sim_dir.is_dir():
        raise RecordingError(f"{sim_dir}: no such simulation folder; give a .../dataset_N/simulation_M folder")
    notes: list[str] = []
    bag_file = sim_dir / BAG_FILE
    csvs = {int(m.group(1)): p for p in sorted(sim_dir.iterdir()) if (m := CSV_PATTERN.fullmatch(p.name))}
    if not bag_file.is_file() and not csvs:
        raise RecordingError(f"{sim_dir}: neither {BAG_FILE} nor any uav_<id>.csv: nothing to plot; fly the "
                             "simulation again without --no-bag / --skip-save (magna run)")
    bag = None
    if bag_file.is_file():
        try:
            bag = _read_bag(bag_file)
        except BagError as err:
            if not csvs:
                raise RecordingError(f"{bag_file}: cannot read the bag ({err.reason}) and there are no uav_<id>.csv: "
                                     "nothing to plot; fly the simulation again") from None
            notes.append(f"{BAG_FILE} cannot be read ({err.reason}): no state-machine timeline, paths, goals or "
                         "latency; trajectories from the CSVs")
    else:
        notes.append(f"{BAG_FILE} missing (flown with --no-bag?): no state-machine timeline, paths, goals or "
                     "latency; trajectories from the CSVs")
    if not csvs:
        notes.append("no uav_<id>.csv (flown with --skip-save?)")
    configs = _mission_configs(sim_dir, notes)
    frames = {}
    for uav, path in csvs.items():
        try:
            frames[uav] = _read_csv(path)
        except ValueError as err:
            notes.append(f"{err}: not used")
    if bag is None and not frames:
        raise RecordingError(f"{sim_dir}: no readable {BAG_FILE} and no usable uav_<id>.csv ({'; '.join(notes)}): "
                             "nothing to plot; fly the simulation again")
    ids = sorted(set(configs) | set(frames) | (set(bag.poses) | set(bag.velocities) if bag else set()))
    uavs = {uav: _uav_record(uav, k, configs.get(uav), frames.get(uav), csvs.get(uav), bag)
            for k, uav in enumerate(ids)}
    for uav, record in uavs.items():
        if not len(record.position):
            notes.append(f"UAV {uav}: no positions in the bag or a CSV")
    _fill_proximity(uavs, frames, csvs, bag, notes)
    world = _world(sim_dir, bag, notes)
    times = [t for u in uavs.values() for t in (u.position.time[:1], u.position.time[-1:])]
    if bag is not None and bag.start <= bag.end:  # an empty bag has neither
        times += [np.array([bag.start, bag.end])]
    stacked = np.concatenate(times) if times else np.zeros(0)
    start, end = (float(stacked.min()), float(stacked.max())) if stacked.size else (0.0, 0.0)
    timeline = None
    if bag is not None:
        timeline = build_timeline(bag.structures.values(), bag.statuses, end, set(uavs))
        if not timeline.intervals:
            notes.append(f"{BAG_FILE} has no state-machine status messages: the timeline is empty")
    return Recording(sim_dir, uavs, world, timeline, _result(sim_dir, notes), bag_file if bag else None, csvs,
                     start, end, notes)


def _mission_configs(sim_dir: Path, notes: list[str]) -> dict:
    from magna_uav.config import ConfigError, configs_from_mission_file

    mission = sim_dir / MISSION_FILE
    if not mission.is_file():
        notes.append(f"{MISSION_FILE} missing: UAV colours are made up, safety radii and max speeds unknown")
        return {}
    try:
        return {c.id: c for c in configs_from_mission_file(mission)}
    except ConfigError as err:
        notes.append(f"{err}: UAV colours are made up, safety radii and max speeds unknown")
        return {}


def _result(sim_dir: Path, notes: list[str]) -> SimulationResult | None:
    try:
        return SimulationResult.read(sim_dir / RESULT_FILE)
    except RecordError as err:
        notes.append(f"{RESULT_FILE} missing: the batch's verdict is unknown" if err.missing else str(err))
        return None


def _world(sim_dir: Path, bag, notes: list[str]) -> RecordedWorld:
    record = sim_dir / WORLD_FILE
    if record.is_file():
        try:
            world = world_from_record(record)
            notes += world.notes
            return world
        except ValueError as err:
            notes.append(str(err))
    else:
        notes.append(f"{WORLD_FILE} missing")
    if bag is not None and bag.markers:
        notes.append("world drawn as the obstacles' bounding spheres from the bag's markers")
        return world_from_markers([m for _, m in bag.markers])
    notes.append("no world to draw")
    return RecordedWorld()


# --- the bag -------------------------------------------------------------------------------------------------------

@dataclass
class _BagData:
    start: float = math.inf
    end: float = -math.inf
    poses: dict = field(default_factory=lambda: defaultdict(list))  # uav -> [(t, xyz)]
    velocities: dict = field(default_factory=lambda: defaultdict(list))
    goals: dict = field(default_factory=lambda: defaultdict(list))
    raw_paths: dict = field(default_factory=lambda: defaultdict(list))
    smoothed_paths: dict = field(default_factory=lambda: defaultdict(list))
    markers: list = field(default_factory=list)  # (t, MarkerArray)
    statuses: list = field(default_factory=list)  # StatusEvent, in recording order
    structures: dict = field(default_factory=dict)  # path -> ContainerStructure, the last heard


def _xyz(v) -> tuple[float, float, float]:
    return (float(v.x), float(v.y), float(v.z))


def _read_bag(path: Path) -> _BagData:
    from magna_sm.introspection import msg_to_structure

    bag = read_simulation_bag(path, kinds=_BAG_KINDS)
    data = _BagData()
    if bag.message_count:
        data.start, data.end = bag.start / 1e9, bag.end / 1e9
    data.markers = [(m.log_time / 1e9, m.msg) for m in bag.of(MARKERS)]
    for m in bag.of("pose"):
        data.poses[m.owner].append((m.time, _xyz(m.msg.pose.position)))
    for m in bag.of("velocity"):
        data.velocities[m.owner].append((m.time, _xyz(m.msg.twist.linear)))
    for m in bag.of("goal"):
        data.goals[m.owner].append((m.time, _xyz(m.msg.pose.position)))
    for kind, target in (("path/raw", data.raw_paths), ("path/smoothed", data.smoothed_paths)):
        for m in bag.of(kind):
            points = np.array([_xyz(p.pose.position) for p in m.msg.poses], dtype=float).reshape(-1, 3)
            target[m.owner].append(PathRecord(m.time, points))
    data.statuses = [StatusEvent(m.time, m.msg.path, tuple(m.msg.active_states), m.msg.last_outcome, m.msg.info)
                     for m in bag.of("status")]
    for m in bag.of("structure"):
        data.structures[m.msg.path] = msg_to_structure(m.msg)
    return data


def _samples(items: list, source: str) -> Samples:
    """Sorted by time; of equal stamps (the simulator re-sends while paused) the last heard wins."""
    if not items:
        return Samples.empty(source)
    t = np.array([i[0] for i in items], dtype=float)
    xyz = np.array([i[1] for i in items], dtype=float).reshape(-1, 3)
    order = np.argsort(t, kind="stable")
    t, xyz = t[order], xyz[order]
    keep = np.append(t[1:] != t[:-1], True)
    return Samples(t[keep], xyz[keep], source)


def _distinct_goals(items: list, source: str) -> Samples:
    """Each goal when first given: the managers publish the current goal at every step."""
    goals = _samples(items, source)
    if not len(goals):
        return goals
    changed = np.append(True, np.any(np.abs(np.diff(goals.xyz, axis=0)) > 1e-6, axis=1))
    return Samples(goals.time[changed], goals.xyz[changed], source)


# --- the CSVs ------------------------------------------------------------------------------------------------------

def _read_csv(path: Path):
    import pandas as pd

    try:
        frame = pd.read_csv(path, low_memory=False)
    except (OSError, ValueError) as err:  # pandas' parser errors are ValueErrors
        raise ValueError(f"{path}: cannot read it as a recorder CSV ({err})") from None
    missing = [c for c in _CSV_COLUMNS if c not in frame.columns]
    if missing:
        raise ValueError(f"{path}: not a recorder CSV (no column {', '.join(missing)})")
    return frame.sort_values("time", kind="stable").reset_index(drop=True)


def _csv_samples(frame, prefix: str, source: str) -> Samples:
    cols = [f"{prefix}.{a}" for a in "xyz"]
    t = frame["time"].to_numpy(dtype=float)
    xyz = frame[cols].to_numpy(dtype=float)
    keep = np.isfinite(t) & np.all(np.isfinite(xyz), axis=1)
    return Samples(t[keep], xyz[keep], source)


# --- per UAV -------------------------------------------------------------------------------------------------------

def _uav_record(uav: int, k: int, config, frame, csv: Path | None, bag: _BagData | None) -> UavRecord:
    if config is not None:
        r, g, b, a = config.marker_rgba
        color, model = (r, g, b, a), config.model
        radius, max_speed = float(config.safety_radius), float(config.max_speed)
    else:
        color, model, radius, max_speed = (*DEFAULT_COLORS[k % len(DEFAULT_COLORS)], 1.0), "?", math.nan, math.nan
    bag_name = BAG_FILE

    def pick(kind: str, prefix: str) -> Samples:
        items = getattr(bag, kind).get(uav, []) if bag is not None else []
        if items:
            return _samples(items, bag_name)
        if frame is not None:
            assert csv is not None  # a frame is read from the UAV's CSV
            return _csv_samples(frame, prefix, csv.name)
        return Samples.empty()

    record = UavRecord(uav, model, color, radius, max_speed, pick("poses", "pos"), pick("velocities", "vel"))
    if bag is not None:
        record.raw_paths = sorted(bag.raw_paths.get(uav, []), key=lambda p: p.time)
        record.smoothed_paths = sorted(bag.smoothed_paths.get(uav, []), key=lambda p: p.time)
        record.goals = _distinct_goals(bag.goals.get(uav, []), bag_name)
    return record


def _fill_proximity(uavs: dict[int, UavRecord], frames: dict, csvs: dict[int, Path], bag: _BagData | None,
                    notes: list[str]) -> None:
    """From the bag where it has the UAV's poses and the obstacle markers: every simulator pose, also while a
    manager records no rows (after an abort, between some roles); else from the UAV's CSV."""
    radii = {uav: u.safety_radius for uav, u in uavs.items()}
    markers = bag.markers if bag is not None else []
    epochs = _obstacle_epochs(markers) if markers else []
    for uav, record in uavs.items():
        from_bag = bag is not None and bool(bag.poses.get(uav))
        if from_bag and (markers or uav not in frames):
            record.proximity = _bag_proximity(record, uavs, epochs)
        elif uav in frames:
            record.proximity = _csv_proximity(frames[uav], uav, radii, csvs[uav].name)
    if bag is not None and not markers and any(u.proximity is not None for u in uavs.values()):
        notes.append(f"{BAG_FILE} has no {WORLD_MARKERS}: obstacle distances from the CSVs only")


def _csv_proximity(frame, uav: int, radii: dict[int, float], source: str) -> Proximity:
    t = frame["time"].to_numpy(dtype=float)
    own = radii.get(uav, math.nan)
    uav_gap = frame["nearest_uav_gap"].to_numpy(dtype=float)
    # the pair's threshold: the other UAV whose gap is the nearest (uav<j>.gap columns), both radii summed
    others = [int(m.group(1)) for c in frame.columns if (m := re.fullmatch(r"uav(\d+)\.gap", c))]
    if others:
        gaps = np.column_stack([frame[f"uav{j}.gap"].to_numpy(dtype=float) for j in others])
        filled = np.where(np.isfinite(gaps), gaps, np.inf)
        nearest = np.array(others)[np.argmin(filled, axis=1)]
        threshold = own + np.array([radii.get(int(j), math.nan) for j in nearest])
    else:
        threshold = np.full(len(t), math.nan)
    uav_gap = np.where(np.isfinite(uav_gap), uav_gap, np.nan)
    obstacle_gap = frame["nearest_obstacle_gap"].to_numpy(dtype=float)
    obstacle_gap = np.where(np.isfinite(obstacle_gap), obstacle_gap, np.nan)
    # the evaluator's verdict per row, split by what it touched ("uav_<id>" or an obstacle's name)
    collided = frame["collision"].fillna(0).to_numpy(dtype=float) > 0
    names = frame["collided_with"].astype("string").fillna("") if "collided_with" in frame.columns else None
    with_uav = names.str.contains(r"(?:^|;)uav_\d+", regex=True).to_numpy() if names is not None else collided
    with_obstacle = names.str.replace(r"(?:^|;)uav_\d+", "", regex=True).str.strip(";").str.len().to_numpy() > 0 \
        if names is not None else collided
    return Proximity(t, uav_gap + threshold, threshold, obstacle_gap + own, own, collided & with_uav,
                     collided & with_obstacle, source)


def _obstacle_epochs(markers: list) -> list[tuple[float, ShapeTable | None]]:
    """(from time, the obstacles' shapes) after each MarkerArray, as the managers' ObstacleMarkers keep them: the
    distances are measured to each obstacle's real shape, as the managers' evaluator measures them."""
    from magna_uav.ros_data import ObstacleMarkers
    from magna_uav.shapes import ShapeTable

    table = ObstacleMarkers()
    epochs: list[tuple[float, ShapeTable | None]] = []
    for t, message in markers:
        table.apply(message)
        obstacles = table.obstacles()
        epochs.append((t, ShapeTable([o.shape for o in obstacles]) if obstacles else None))
    return epochs


def _bag_proximity(record: UavRecord, uavs: dict[int, UavRecord], epochs: list[tuple[float, ShapeTable | None]]
                   ) -> Proximity:
    t, p = record.position.time, record.position.xyz
    best_gap = np.full(len(t), np.inf)
    distance = np.full(len(t), np.nan)
    threshold = np.full(len(t), np.nan)
    for other in uavs.values():
        if other.id == record.id or not len(other.position):
            continue
        d = np.linalg.norm(other.position.at(t) - p, axis=1)
        pair = record.safety_radius + other.safety_radius
        gap = d - (pair if math.isfinite(pair) else 0.0)
        better = np.isfinite(d) & (gap < best_gap)
        best_gap[better], distance[better], threshold[better] = gap[better], d[better], pair
    obstacle = np.full(len(t), np.nan)
    for k, (since, shapes) in enumerate(epochs):
        until = epochs[k + 1][0] if k + 1 < len(epochs) else math.inf
        inside = np.flatnonzero((t >= since) & (t < until))
        if shapes is not None:
            for i in inside:
                obstacle[i] = float(shapes.signed_distances(p[i]).min()) if np.isfinite(p[i]).all() else math.nan
    own = record.safety_radius
    with np.errstate(invalid="ignore"):  # NaN compares False: no contact where nothing is known
        return Proximity(t, distance, threshold, obstacle, own, distance < threshold, obstacle < own,
                         BAG_FILE)


__all__ = ["PathRecord", "Proximity", "Recording", "RecordingError", "Samples", "UavRecord", "load_recording"]
