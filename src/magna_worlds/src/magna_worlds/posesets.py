"""Pose-set layouts in a geometry's own frame, vectorised: where the poses of one set go and how they are turned.

Each layout returns positions (N, 3) and, for matrices, the cell index (N, 3) of each
position. Every position lies inside the geometry's solid (`shapes.contains`), which
the tests check for every shape.

Matrix by dimension: `dimensions` counts cells per axis and each pose sits at a cell
centre (edges excluded, one cell puts its pose in the middle). The axes follow the
shape: cube x, y, z; cylinder angle, radius, height; sphere azimuth, polar angle,
radius; torus ring angle, tube angle, tube radius; prism x, y, z of its bounding
box turned by `set_orientation`'s yaw, keeping the cells over the polygon.
Matrix by distance: `dimensions` are spacings in metres; cells of that size are
centred in the shape's bounding box (turned by the set yaw for a prism) and the ones
whose centre lies inside the solid are kept. `density` keeps each cell with that
probability. Zigzag: sweep lines `spacing[1]` apart, running at `sweep_angle` over
a prism's polygon at `height` above its base, shortened by `margins[0]` at each end,
centred across the polygon with the outer lines at least `margins[1]` inside it;
waypoints at each line's ends (and every `spacing[0]` metres along it when that is
positive), the first line flown towards +x of the sweep (`"right"`) or -x (`"left"`), then alternating.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from magna_worlds.model import OrientationSpec, PoseSetSpec
from magna_worlds.shapes import ShapeSpec, contains, half_extents, sample_uniform

# Far above any real world (the largest has a few hundred poses), and low enough that a typo (a spacing of
# 0.0001 m, a quantity of 1e9) is refused at once instead of filling the memory for minutes.
MAX_POSES_PER_SET = 100_000


class LayoutError(ValueError):
    """A pose set that cannot be laid out in its geometry; the message says which field and how to fix it."""


def _check_count(count: float, field: str, fix: str) -> None:
    """Refuse a set that would make more than MAX_POSES_PER_SET poses (`count` may be inf or nan)."""
    if not count <= MAX_POSES_PER_SET:
        shown = f"{count:.3g}" if math.isfinite(count) else "too many"
        raise LayoutError(f"{field}: this set would make {shown} poses; MAGNA lays out at most {MAX_POSES_PER_SET} "
                          f"per set: {fix}")


def matrix_layout(spec: ShapeSpec, pose_set: PoseSetSpec) -> tuple[np.ndarray, np.ndarray]:
    if pose_set.matrix_type == "distance":
        return _distance_grid(spec, pose_set)
    counts = tuple(int(n) for n in pose_set.matrix_dimensions)
    _check_count(math.prod(counts), "dimensions", "use fewer cells")
    cells = np.stack(np.meshgrid(*(np.arange(n) for n in counts), indexing="ij"), axis=-1).reshape(-1, 3)
    frac = (cells + 0.5) / np.array(counts)  # cell centres in (0, 1)
    d = spec.dimensions
    if spec.shape == "cube":
        positions = (frac - 0.5) * np.array(d)
    elif spec.shape == "cylinder":
        angle, radius = frac[:, 0] * 2.0 * math.pi, frac[:, 1] * d[0] / 2.0
        positions = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), (frac[:, 2] - 0.5) * d[2]])
    elif spec.shape == "sphere":
        azimuth, polar, radius = frac[:, 0] * 2.0 * math.pi, frac[:, 1] * math.pi, frac[:, 2] * d[0] / 2.0
        positions = np.column_stack([radius * np.sin(polar) * np.cos(azimuth), radius * np.sin(polar) * np.sin(azimuth),
                                     radius * np.cos(polar)])
    elif spec.shape == "torus":
        ring, tube, rho = frac[:, 0] * 2.0 * math.pi, frac[:, 1] * 2.0 * math.pi, frac[:, 2] * d[2] / 2.0
        reach = d[0] / 2.0 + rho * np.cos(tube)
        positions = np.column_stack([reach * np.cos(ring), reach * np.sin(ring), rho * np.sin(tube)])
    else:
        low, high, turn = _turned_prism_box(spec, pose_set.set_yaw)
        positions = (low + frac * (high - low)) @ turn.T
        keep = contains(spec, positions)
        if not keep.any():
            raise LayoutError("dimensions: no cell centre of this matrix falls inside the prism's polygon; "
                              "use more cells or check set_orientation")
        positions, cells = positions[keep], cells[keep]
    return positions, cells


def _distance_grid(spec: ShapeSpec, pose_set: PoseSetSpec) -> tuple[np.ndarray, np.ndarray]:
    spacing = np.array(pose_set.matrix_dimensions, dtype=float)
    if spec.shape == "prism":
        low, high, turn = _turned_prism_box(spec, pose_set.set_yaw)
    else:
        (low, high), turn = half_extents(spec), np.eye(3)
    extent = high - low
    with np.errstate(over="ignore", invalid="ignore"):
        cells_per_axis = np.floor(extent / spacing + 1e-9)
        _check_count(float(np.prod(np.maximum(cells_per_axis, 1.0))), "dimensions", "use larger spacings")
    counts = cells_per_axis.astype(int)
    for axis, n in enumerate(counts):
        if n < 1:
            raise LayoutError(f"dimensions[{axis}]: a spacing of {spacing[axis]:g} m does not fit the geometry's "
                              f"{extent[axis]:g} m along {'xyz'[axis]}; use a spacing <= {extent[axis]:g} m")
    cells = np.stack(np.meshgrid(*(np.arange(n) for n in counts), indexing="ij"), axis=-1).reshape(-1, 3)
    centre = (low + high) / 2.0
    positions = (centre + (cells - (counts - 1) / 2.0) * spacing) @ turn.T
    keep = contains(spec, positions)
    if not keep.any():
        raise LayoutError("dimensions: no cell centre of this matrix falls inside the geometry; use smaller spacings")
    return positions[keep], cells[keep]


def _turned_prism_box(spec: ShapeSpec, yaw: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bounding box of a prism in its frame turned by `yaw`, and that turn (3, 3)."""
    turn = Rotation.from_euler("z", yaw).as_matrix()
    poly = np.column_stack([np.array(spec.polygon), np.zeros(len(spec.polygon))]) @ turn  # into the turned frame
    low = np.append(poly[:, :2].min(axis=0), 0.0)
    high = np.append(poly[:, :2].max(axis=0), spec.dimensions[0])
    return low, high, turn


def random_layout(spec: ShapeSpec, quantity: int, rng: np.random.Generator) -> np.ndarray:
    _check_count(quantity, "quantity", "draw fewer")
    return sample_uniform(spec, quantity, rng)


def coordinates_layout(spec: ShapeSpec, pose_set: PoseSetSpec) -> tuple[np.ndarray, np.ndarray]:
    positions = np.array([xyz for xyz, _ in pose_set.coordinates], dtype=float)
    quaternions = np.array([q for _, q in pose_set.coordinates], dtype=float)
    outside = np.flatnonzero(~contains(spec, positions, tolerance=1e-6))
    if len(outside):
        i = int(outside[0])
        raise LayoutError(f"coordinates[{i}]: {positions[i].tolist()} lies outside the {spec.shape} (coordinates are "
                          "in the geometry's frame); move it inside or use the volume's coordinates in the mission")
    return positions, quaternions


def zigzag_layout(spec: ShapeSpec, pose_set: PoseSetSpec) -> np.ndarray:
    if not 0.0 <= pose_set.height <= spec.dimensions[0]:
        raise LayoutError(f"height: the sweep plane must lie within the prism, 0..{spec.dimensions[0]:g} m above its "
                          f"base, got {pose_set.height:g}")
    along, between = pose_set.spacing
    end_margin, side_margin = pose_set.margins
    turn = Rotation.from_euler("z", pose_set.sweep_angle).as_matrix()[:2, :2]
    poly = np.array(spec.polygon) @ turn  # polygon in the sweep frame: lines run along x
    y_low, y_high = poly[:, 1].min() + side_margin, poly[:, 1].max() - side_margin
    if y_high < y_low:
        raise LayoutError(f"margins[1]: {side_margin:g} m from both sides leaves no room across the polygon "
                          f"({np.ptp(poly[:, 1]):g} m); use a smaller margin")
    across = (y_high - y_low) / between
    lines = math.floor(across + 1e-9) + 1 if math.isfinite(across) else math.inf
    per_line = len(poly) + (float(np.ptp(poly[:, 0])) / along if along > 0 else 0.0)  # stretches <= edges / 2
    _check_count(lines * per_line, "spacing", "use larger spacings")
    count = int(lines)
    spare = (y_high - y_low) - (count - 1) * between  # centre the lines: equal room at both sides
    ys = y_low + spare / 2.0 + between * np.arange(count)
    eps = 1e-9 * max(1.0, float(np.ptp(poly)))
    ys_cut = np.clip(ys, poly[:, 1].min() + eps, poly[:, 1].max() - eps)  # a line along an edge still cuts
    points: list[np.ndarray] = []
    forward = pose_set.initial_sense == "right"
    for y, y_cut in zip(ys, ys_cut, strict=True):
        pieces = _line_pieces(poly, y_cut, end_margin, along)
        if not pieces:
            continue
        line = np.concatenate(pieces) if forward else np.concatenate([p[::-1] for p in pieces[::-1]])
        points.append(np.column_stack([line, np.full(len(line), y)]))
        forward = not forward
    if not points:
        raise LayoutError(f"margins[0]: {end_margin:g} m at each end leaves no line long enough; use a smaller margin")
    xy = np.concatenate(points) @ turn.T
    return np.column_stack([xy, np.full(len(xy), pose_set.height)])


def _line_pieces(poly: np.ndarray, y: float, end_margin: float, along: float) -> list[np.ndarray]:
    """x of the waypoints on the line at height y of the sweep frame, one array per stretch inside the polygon."""
    start, end = poly, np.roll(poly, -1, axis=0)
    crossing = (start[:, 1] > y) != (end[:, 1] > y)
    s, e = start[crossing], end[crossing]
    xs = np.sort(s[:, 0] + (y - s[:, 1]) * (e[:, 0] - s[:, 0]) / (e[:, 1] - s[:, 1]))
    stretches: list[list[float]] = []
    for a, b in zip(xs[0::2], xs[1::2], strict=True):
        if stretches and a - stretches[-1][1] <= 1e-9:  # the line only touches a vertex here: one stretch
            stretches[-1][1] = b
        else:
            stretches.append([a, b])
    pieces = []
    for a, b in stretches:
        a, b = a + end_margin, b - end_margin
        if b < a - 1e-12:
            continue
        if along > 0 and b - a > along:
            inner = a + along * np.arange(1, int(math.ceil((b - a) / along - 1e-9)))
            pieces.append(np.concatenate([[a], inner, [b]]))
        else:
            pieces.append(np.array([a]) if b - a < 1e-12 else np.array([a, b]))
    return pieces


def orientations(spec: OrientationSpec, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 4) quaternions [x, y, z, w] as the set asks: fixed, drawn in ranges, or any rotation."""
    if spec.any_rotation:
        return Rotation.random(count, random_state=rng).as_quat().reshape(count, 4)
    ranges = np.array(spec.ranges)
    if spec.fixed:
        rpy = np.tile(ranges[:, 0], (count, 1))
    else:
        rpy = ranges[:, 0] + rng.random((count, 3)) * (ranges[:, 1] - ranges[:, 0])
    return Rotation.from_euler("xyz", rpy).as_quat().reshape(count, 4)
