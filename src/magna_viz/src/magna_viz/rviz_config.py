"""The rviz configurations: which one a world family uses, the camera fitted to a world, the headless copy.

No ROS here. The configurations live in magna_viz/rviz/ (one per world family); a replay or a
live run writes a copy of one with its orbit camera fitted to the world (and, headless, with
every dock, menu and tool bar gone and the window filling the screen, so a screen grab is
just the 3-D view).
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml

from magna_common.files import write_atomically
from magna_common.records import RecordedGeometry, RecordedObstacle, RecordError, SimulationResult, WorldRecord
from magna_common.storage_tree import RESULT_FILE

RVIZ_DIR = Path(__file__).resolve().parents[2] / "rviz"
DEFAULT_FAMILY = "gym"
# Camera sizes of rviz's render panel: Ogre's default vertical field of view.
FOV_Y = math.pi / 4


@dataclass(frozen=True)
class Family:
    """A world family: its rviz file and the sizes that suit its worlds."""

    name: str
    config: str
    marker_scale: float  # UAV marker sizes (magna_viz.scene) when no fitted view says better


FAMILIES = {
    "gym": Family("gym", "gym.rviz", 1.0),
    "delivery": Family("delivery", "delivery.rviz", 1.0),
    "solarplant": Family("solar_plant", "solar_plant.rviz", 4.0),
    "inspection": Family("inspection", "inspection.rviz", 8.0),
}


@dataclass(frozen=True)
class ConfigChoice:
    path: Path
    family: Family
    world: str  # the world name it was chosen from ("" when unknown)
    note: str = ""  # said to the user when the choice is a fallback


def family_of(world: str) -> Family | None:
    """The family of a world name: Gym, Delivery, SolarPlant or Solar_Plant, Inspection (any case)."""
    key = re.sub(r"[^a-z0-9]", "", world.lower())
    return FAMILIES.get(key)


def world_of_sim_dir(sim_dir: Path) -> str:
    """The world of a simulation folder: result.json's hyperparameters, else the storage path
    <root>/Simulations/<world>/...; "" when neither says."""
    try:
        hyperparameters = SimulationResult.read(sim_dir / RESULT_FILE).hyperparameters
    except RecordError:
        hyperparameters = None
    if hyperparameters is not None and hyperparameters.world:
        return hyperparameters.world
    parts = sim_dir.resolve().parts
    if "Simulations" in parts:
        index = len(parts) - 1 - parts[::-1].index("Simulations")
        if index + 1 < len(parts):
            return parts[index + 1]
    return ""


def choose_config(world: str, override: Path | None = None, rviz_dir: Path = RVIZ_DIR) -> ConfigChoice:
    """The rviz file for a world: `override` when given, else its family's, else gym.rviz (with a note)."""
    family = family_of(world) if world else None
    if override is not None:
        return ConfigChoice(Path(override), family or FAMILIES[DEFAULT_FAMILY], world)
    if family is not None:
        return ConfigChoice(rviz_dir / family.config, family, world)
    fallback = FAMILIES[DEFAULT_FAMILY]
    why = f"world {world!r} has no rviz configuration of its own" if world else "the world is not known"
    return ConfigChoice(rviz_dir / fallback.config, fallback, world, note=f"{why}; using {fallback.config}")


# --- boxes and the camera ---------------------------------------------------------------------------------------

Box = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]  # (xmin, xmax), (ymin, ymax), (zmin, zmax)


def _box(ranges: Iterable[tuple[float, float]]) -> Box:
    """The three (low, high) ranges x, y, z as a Box."""
    x, y, z = ranges
    return x, y, z


def box_of_points(points: Iterable[Sequence[float]]) -> Box | None:
    pts = [p for p in points if all(math.isfinite(v) for v in p[:3])]
    if not pts:
        return None
    return _box((min(p[i] for p in pts), max(p[i] for p in pts)) for i in range(3))


def union(*boxes: Box | None) -> Box | None:
    present = [b for b in boxes if b is not None]
    if not present:
        return None
    return _box((min(b[i][0] for b in present), max(b[i][1] for b in present)) for i in range(3))


def clip(box: Box | None, limits: Box | None) -> Box | None:
    """`box` inside `limits`; `box` itself when they do not meet or one is missing."""
    if box is None or limits is None:
        return box or limits
    out = _box((max(b[0], lim[0]), min(b[1], lim[1])) for b, lim in zip(box, limits, strict=True))
    return out if all(lo <= hi for lo, hi in out) else box


def world_boxes(world: WorldRecord) -> tuple[Box | None, Box | None]:
    """(boundaries, content) of a recorded world. Content: the geometries and obstacles, roughly."""
    boundaries: Box | None = None
    content: Box | None = None
    for part in world.parts.values():
        boundaries = union(boundaries, _as_box(part.world_boundaries))
        items: list[RecordedGeometry | RecordedObstacle] = [*part.geometries, *part.obstacles]
        for item in items:
            content = union(content, _item_box(item))
    return boundaries, content


def _as_box(value: tuple[tuple[float, float], ...] | None) -> Box | None:
    if value is None or not all(lo <= hi for lo, hi in value):
        return None
    return _box(value)  # the record reads boundaries as three (low, high) pairs


def _item_box(item: RecordedGeometry | RecordedObstacle) -> Box | None:
    """A geometry or obstacle of a recorded world: its position and a radius from its sizes."""
    if len(item.position) != 3:
        return None
    x, y, z = item.position
    if item.polygon:
        pts = [(x + p[0], y + p[1], z + p[2] if len(p) > 2 else z) for p in item.polygon]
        height = item.dimensions[0] if item.dimensions else 0.0
        pts += [(px, py, pz + height) for px, py, pz in pts]
        return box_of_points(pts)
    radius = max(item.dimensions) / 2.0 if item.dimensions else 0.0
    return ((x - radius, x + radius), (y - radius, y + radius), (z - radius, z + radius))


def pad(box: Box, fraction: float = 0.05, minimum: float = 4.0) -> Box:
    """The box grown by `fraction` of its size on each side, and to at least `minimum` metres per axis."""
    out = []
    for lo, hi in box:
        grow = (hi - lo) * fraction
        lo, hi = lo - grow, hi + grow
        if hi - lo < minimum:
            mid = (lo + hi) / 2.0
            lo, hi = mid - minimum / 2.0, mid + minimum / 2.0
        out.append((lo, hi))
    return _box(out)


@dataclass(frozen=True)
class OrbitView:
    focal: tuple[float, float, float]
    distance: float
    yaw: float
    pitch: float


def fit_orbit(box: Box, yaw: float, pitch: float, aspect: float, fov_y: float = FOV_Y) -> OrbitView:
    """The orbit camera looking from (yaw, pitch) at the box's centre, just far enough to see all of it.

    rviz's orbit camera sits at focal + distance * (cos yaw cos pitch, sin yaw cos pitch, sin pitch).
    """
    back = (math.cos(yaw) * math.cos(pitch), math.sin(yaw) * math.cos(pitch), math.sin(pitch))
    right = _normalise((-back[1], back[0], 0.0)) if abs(pitch) < math.pi / 2 - 1e-6 else (1.0, 0.0, 0.0)
    up = _cross(back, right)
    tan_y = math.tan(fov_y / 2.0)
    tan_x = tan_y * aspect
    corners = _corners(box)
    focal = tuple((lo + hi) / 2.0 for lo, hi in box)

    def needed(focal) -> float:  # the least distance at which every corner is in the picture
        distance = 0.0
        for corner in corners:
            rel = tuple(c - f for c, f in zip(corner, focal, strict=True))
            depth = _dot(rel, back)  # towards the camera
            distance = max(distance, depth + abs(_dot(rel, right)) / tan_x, depth + abs(_dot(rel, up)) / tan_y)
        return distance

    distance = needed(focal)
    # Perspective makes near corners look bigger: move the focal point so the box's picture is centred,
    # which lets the camera come closer. A few rounds settle it.
    for _ in range(8):
        xs, ys = [], []
        for corner in corners:
            rel = tuple(c - f for c, f in zip(corner, focal, strict=True))
            depth = max(distance - _dot(rel, back), 1e-6)
            xs.append(_dot(rel, right) / (depth * tan_x))
            ys.append(_dot(rel, up) / (depth * tan_y))
        shift_x = (max(xs) + min(xs)) / 2.0 * tan_x * distance
        shift_y = (max(ys) + min(ys)) / 2.0 * tan_y * distance
        focal = tuple(f + shift_x * r + shift_y * u for f, r, u in zip(focal, right, up, strict=True))
        distance = needed(focal)
    x, y, z = focal
    return OrbitView((x, y, z), max(distance, 1.0), yaw, pitch)


def _corners(box: Box):
    (x0, x1), (y0, y1), (z0, z1) = box
    return [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]


def _dot(a, b) -> float:
    return sum(x * y for x, y in zip(a, b, strict=True))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _normalise(v):
    n = math.sqrt(_dot(v, v)) or 1.0
    return tuple(c / n for c in v)


def marker_scale_for(box: Box | None, family: Family) -> float:
    """UAV marker sizes for a view of this box: 1 up to about 40 m across, then growing with it."""
    if box is None:
        return family.marker_scale
    span = max(hi - lo for lo, hi in box[:2])
    return max(1.0, round(span / 40.0, 1))


# --- reading and rewriting a configuration ---------------------------------------------------------------------

class ConfigError(ValueError):
    """An rviz file that cannot be read or is not an rviz configuration."""


def load_config(path: Path) -> dict:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as err:
        raise ConfigError(f"{path}: cannot read: {err.strerror or err}") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not an rviz configuration (YAML): {err}") from None
    if not isinstance(data, dict) or not isinstance(data.get("Visualization Manager"), dict):
        raise ConfigError(f"{path}: not an rviz configuration (no 'Visualization Manager')")
    return data


def current_view(config: dict) -> dict:
    views = config["Visualization Manager"].setdefault("Views", {})
    current = views.get("Current")
    if not isinstance(current, dict):
        current = views["Current"] = {"Class": "rviz/Orbit", "Name": "Current View", "Target Frame": "<Fixed Frame>"}
    return current


def adapt(config: dict, view: OrbitView | None = None, headless: tuple[int, int] | None = None,
          grid_box: Box | None = None) -> dict:
    """A copy of the configuration with the orbit camera at `view` and, when `headless` = (width,
    height), no panels and the window at 0,0 filling a screen of that size."""
    import copy

    out = copy.deepcopy(config)
    manager = out["Visualization Manager"]
    if view is not None:
        current = current_view(out)
        current.update({
            "Class": "rviz/Orbit", "Distance": round(view.distance, 3),
            "Focal Point": {"X": round(view.focal[0], 3), "Y": round(view.focal[1], 3),
                            "Z": round(view.focal[2], 3)},
            "Yaw": round(view.yaw, 4), "Pitch": round(view.pitch, 4), "Target Frame": "<Fixed Frame>",
        })
        current.setdefault("Name", "Current View")
        current["Near Clip Distance"] = 0.01
        current.pop("Value", None)
    if grid_box is not None:
        _fit_grid(manager, grid_box)
    if headless is not None:
        width, height = headless
        out["Panels"] = []
        out["Window Geometry"] = {"Height": int(height), "Width": int(width), "X": 0, "Y": 0,
                                  "Hide Left Dock": True, "Hide Right Dock": True}
        options = manager.setdefault("Global Options", {})
        options["Frame Rate"] = 30
    return out


def _fit_grid(manager: dict, box: Box) -> None:
    """The grid centred under the box, its cells a round size, about 20-40 across."""
    span = max(hi - lo for lo, hi in box[:2])
    cell = _round_step(span / 30.0)
    count = int(math.ceil(span / cell)) + 2
    for display in manager.get("Displays", []):
        if isinstance(display, dict) and display.get("Class") == "rviz/Grid":
            display["Cell Size"] = cell
            display["Plane Cell Count"] = count
            display["Offset"] = {"X": round((box[0][0] + box[0][1]) / 2.0, 3),
                                 "Y": round((box[1][0] + box[1][1]) / 2.0, 3), "Z": round(box[2][0], 3)}


def _round_step(value: float) -> float:
    """1, 2 or 5 times a power of ten, at least `value` (and at least 0.5)."""
    value = max(value, 0.5)
    power = 10 ** math.floor(math.log10(value))
    for step in (1, 2, 5, 10):
        if step * power >= value:
            return float(step * power)
    return float(10 * power)


def write_config(config: dict, path: Path) -> Path:
    """Write an rviz file atomically."""
    return write_atomically(path, lambda out: yaml.safe_dump(config, out, default_flow_style=False, sort_keys=False),
                            overwrite=True)


def view_of(config: dict) -> tuple[float, float]:
    """The (yaw, pitch) the configuration looks from; the fitted camera keeps them."""
    current = current_view(config)
    try:
        return float(current.get("Yaw", 0.785)), float(current.get("Pitch", 0.785))
    except (TypeError, ValueError):
        return 0.785, 0.785
