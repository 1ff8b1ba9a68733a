"""A replay's plan: the options, and everything checked before anything starts.

make_plan reads the simulation folder (the bag's extent, UAVs and flights through
magna_common.simulation_bag; the mission's colours; the recorded world) and the tools on PATH, picks the
rviz configuration and fits its camera (view_box), and refuses with ReplayError (nothing
started, nothing written) whatever would stop the replay later.
"""
from __future__ import annotations

import math
import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.records import RecordError, WorldRecord
from magna_common.simulation_bag import BagError, read_simulation_bag
from magna_common.storage_tree import BAG_FILE, MISSION_FILE, WORLD_FILE
from magna_viz import rviz_config as rc
from magna_viz.replay.errors import ReplayError

OUT_DIR_NAME = "replay"
FINAL_NAME, GIF_NAME, MP4_NAME = "final.png", "replay.gif", "replay.mp4"
FITS = ("world", "uavs", "none")
FLIGHT_KINDS = ("pose", "goal", "path/raw", "path/smoothed")  # where the UAVs flew and were sent


@dataclass
class ReplayOptions:
    source: Path  # a bag, or a simulation folder holding simulation.bag
    headless: bool = False
    out_dir: Path | None = None  # headless outputs; default <simulation folder>/replay
    every: float = 1.0  # s of bag time between screenshots; 0: only the final frame
    speed: float = 1.0
    gif: bool = False
    mp4: bool = False
    fps: float = 5.0  # frames per second of the GIF and MP4
    force: bool = False
    config: Path | None = None
    mission_file: Path | None = None
    size: tuple[int, int] = (1280, 720)
    fit: str = "world"
    loop: bool = False
    progress: bool = True
    start_timeout: float = 120.0  # wall s for Xvfb, rviz and the scene node to come up


@dataclass
class BagSummary:
    path: Path
    start: float
    end: float
    messages: int
    uav_ids: list[int]
    flight_box: rc.Box | None

    @property
    def duration(self) -> float:
        return max(self.end - self.start, 0.0)


@dataclass
class Plan:
    """Everything checked before anything starts."""

    options: ReplayOptions
    bag: BagSummary
    sim_dir: Path
    mission_file: Path
    choice: rc.ConfigChoice
    config: dict
    view: rc.OrbitView | None
    box: rc.Box | None
    scale: float
    out_dir: Path | None
    uav_ids: list[int] = field(default_factory=list)  # the mission's agents: the scene node draws these
    notes: list[str] = field(default_factory=list)

    def outputs(self) -> list[Path]:
        """The files a headless replay writes (frames are numbered as they come)."""
        if self.out_dir is None:
            return []
        names = [FINAL_NAME] + ([GIF_NAME] if self.options.gif else []) + ([MP4_NAME] if self.options.mp4 else [])
        return [self.out_dir / n for n in names]


# --- checking the input ------------------------------------------------------------------------------------------

def resolve_source(source: Path) -> tuple[Path, Path]:
    """(bag, simulation folder) of a bag file or a simulation folder."""
    source = Path(source).expanduser()
    if source.is_dir():
        bag = source / BAG_FILE
        if not bag.is_file():
            raise ReplayError(f"{source}: no {BAG_FILE} in this folder (was the simulation run with --no-bag?)")
        return bag.resolve(), source.resolve()
    if not source.exists():
        raise ReplayError(f"{source}: no such bag file or simulation folder")
    if not source.is_file():
        raise ReplayError(f"{source}: not a file or folder")
    return source.resolve(), source.resolve().parent


def read_bag(bag: Path) -> BagSummary:
    """Duration, UAVs and where they flew; ReplayError when the file is not a readable bag."""
    try:
        data = read_simulation_bag(bag, kinds=FLIGHT_KINDS)
    except BagError as err:
        raise ReplayError(str(err)) from None
    if data.message_count == 0:
        raise ReplayError(f"{bag}: the bag holds no messages; nothing to replay")
    points = []
    for message in (m for kind in FLIGHT_KINDS for m in data.of(kind)):
        if hasattr(message.msg, "poses"):  # a path
            points += [(s.pose.position.x, s.pose.position.y, s.pose.position.z) for s in message.msg.poses]
        else:
            p = message.msg.pose.position
            points.append((p.x, p.y, p.z))
    return BagSummary(bag, data.start / 1e9, data.end / 1e9, data.message_count, data.uav_ids("pose"),
                      rc.box_of_points(points))


def read_world(sim_dir: Path) -> WorldRecord | None:
    """The simulation's world.json; None when it is missing or unreadable (the camera then fits the flights)."""
    try:
        return WorldRecord.read(sim_dir / WORLD_FILE)
    except RecordError:
        return None


def view_box(world: WorldRecord | None, flights: rc.Box | None, fit: str) -> rc.Box | None:
    """What the camera shows: the world's content inside its boundaries and the flights ('world'), or the
    flights only ('uavs'), padded; None for 'none' or when nothing is known."""
    if fit == "none":
        return None
    boundaries, content = rc.world_boxes(world) if world is not None else (None, None)
    if fit == "uavs" and flights is not None:
        return rc.pad(flights, 0.15)
    inside = rc.clip(content, boundaries) if content is not None else None
    box = rc.union(inside, flights)
    if box is None:
        box = boundaries
    return rc.pad(box) if box is not None else None


def make_plan(options: ReplayOptions, environ: Mapping[str, str] | None = None) -> Plan:
    """Check everything a replay needs; ReplayError (nothing started, nothing written) when something is off."""
    from magna_viz.scene import styles_from_mission

    environ = os.environ if environ is None else environ
    if not options.speed > 0 or not math.isfinite(options.speed):
        raise ReplayError(f"--speed must be > 0, got {options.speed:g}")
    if options.every < 0 or not math.isfinite(options.every):
        raise ReplayError(f"--every must be >= 0 seconds (0: only the final frame), got {options.every:g}")
    if not options.fps > 0:
        raise ReplayError(f"--fps must be > 0, got {options.fps:g}")
    if options.fit not in FITS:
        raise ReplayError(f"--fit must be one of {', '.join(FITS)}, got {options.fit!r}")
    width, height = options.size
    if not (160 <= width <= 7680 and 120 <= height <= 4320):
        raise ReplayError(f"--size {width}x{height}: give WIDTHxHEIGHT between 160x120 and 7680x4320")
    if options.headless and options.loop:
        raise ReplayError("--loop plays the bag forever: it needs a display, not --headless")

    bag_path, sim_dir = resolve_source(options.source)
    mission_file = Path(options.mission_file) if options.mission_file else sim_dir / MISSION_FILE
    if not mission_file.is_file():
        raise ReplayError(f"{mission_file}: no mission file (the UAVs' colours come from it); give one with "
                          "--mission FILE")
    try:
        styles = styles_from_mission(mission_file)
    except ValueError as err:
        raise ReplayError(str(err)) from None
    if not styles:
        raise ReplayError(f"{mission_file}: the mission has no agents to draw")
    if options.config is not None and not Path(options.config).is_file():
        raise ReplayError(f"--config {options.config}: no such file")

    tools = ["rosmaster", "rosbag", "rviz"] + (["Xvfb"] if options.headless else []) + (["ffmpeg"] if options.mp4
                                                                                           else [])

    missing = [t for t in tools if shutil.which(t) is None]
    if missing:
        raise ReplayError(f"{', '.join(missing)} not on PATH: run through ./magna, or install the Debian packages "
                          "of scripts/apt-packages.txt (make setup)")
    if not options.headless and not environ.get("DISPLAY"):
        raise ReplayError("no display (DISPLAY is not set) for rviz: use --headless to write screenshots instead")

    out_dir = None
    if options.headless:
        out_dir = Path(options.out_dir).expanduser() if options.out_dir else sim_dir / OUT_DIR_NAME
        if out_dir.exists() and not out_dir.is_dir():
            raise ReplayError(f"{out_dir}: exists and is not a folder; choose another with -o/--output")

    bag = read_bag(bag_path)
    world = rc.world_of_sim_dir(sim_dir)
    try:
        choice = rc.choose_config(world, Path(options.config) if options.config else None)
        config = rc.load_config(choice.path)
    except rc.ConfigError as err:
        raise ReplayError(str(err)) from None
    box = view_box(read_world(sim_dir), bag.flight_box, options.fit)
    view = None
    if box is not None:
        yaw, pitch = rc.view_of(config)
        aspect = width / height if options.headless else 1.2  # the 3-D view between rviz's docks
        view = rc.fit_orbit(box, yaw, pitch, aspect)
    plan = Plan(options, bag, sim_dir, mission_file, choice, config, view, box,
                rc.marker_scale_for(box, choice.family), out_dir, [s.id for s in styles])
    if choice.note:
        plan.notes.append(choice.note)
    missing_uavs = sorted(set(bag.uav_ids) - {s.id for s in styles})
    if missing_uavs:
        plan.notes.append(f"UAVs {', '.join(map(str, missing_uavs))} of the bag are not in {mission_file.name}: "
                          "not drawn")
    if out_dir is not None:
        in_the_way = [p for p in plan.outputs() if p.exists()]
        if options.every > 0 and out_dir.is_dir():
            in_the_way += sorted(out_dir.glob("frame_*.png"))[:1]
        if in_the_way and not options.force:
            raise ReplayError(f"{in_the_way[0]} exists; use --force to replace the replay's outputs in {out_dir} "
                              "(or -o/--output another folder)")
    return plan
