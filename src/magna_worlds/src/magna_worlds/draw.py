"""A resolved world as a 3-D picture (PNG): geometries, obstacles and free-space poses, in `map`, metres.

- Geometries: translucent surfaces in their own colour, plus a thin outline (box
  edges, rims, equators) in a darker shade so that white, black and alpha-0
  geometries still show. The file's alpha 0..1 maps linearly onto a face alpha
  MIN_ALPHA..MAX_ALPHA: never invisible, never hiding what is inside, never as
  dark as an obstacle.
- Obstacles: opaque dark solids.
- Poses: one scatter per pose set, one colour per set; a zigzag set is also drawn as
  a line in flying order with its first waypoint marked.
- The view box fits the content (geometries, obstacles, poses), not the
  world_boundaries, which are often hundreds of metres wide; every axis has the same
  scale, and a thin axis is widened (never stretched) to at least MIN_AXIS_SHARE of
  the widest so flat worlds do not become a line.

Drawing uses matplotlib's Agg canvas directly (no pyplot, no global backend), and
the file is written atomically (magna_common.files).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from mpl_toolkits.mplot3d import Axes3D  # importing it registers the 3-D projection
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from magna_common.files import write_atomically
from magna_worlds.generate import Obstacle, PlacedGeometry, ResolvedWorld
from magna_worlds.shapes import ShapeSpec, parse_shape, prism_mesh, torus_mesh
from magna_worlds.transforms import Frame

MIN_ALPHA = 0.08  # face alpha of an alpha-0 geometry: still a faint surface, and its outline
MAX_ALPHA = 0.4  # face alpha of an opaque geometry: its poses and obstacles still show through
OBSTACLE_COLOR = (0.22, 0.22, 0.25)
MIN_AXIS_SHARE = 0.3  # a thin axis spans at least this share of the widest one
MAX_LEGEND_ENTRIES = 24
POSE_COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#17becf", "#e377c2", "#8c564b",
               "#bcbd22", "#7f7f7f")
SEGMENTS = 32  # around round shapes


# --- meshes in a shape's own frame: (faces, outline) -------------------------------------------------------------
# faces: a list of (V, 3) polygons; outline: a list of (K, 3) polylines.

def shape_mesh(spec: ShapeSpec) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Surface polygons and outline polylines of a shape in its own frame (conventions of `shapes`)."""
    d = spec.dimensions
    if spec.shape == "cube":
        return _box(np.array(d) / 2.0)
    if spec.shape == "sphere":
        return _sphere(d[0] / 2.0)
    if spec.shape == "cylinder":
        return _cylinder(d[0] / 2.0, d[2])
    if spec.shape == "torus":
        return _torus(d[0] / 2.0, d[2] / 2.0)
    return _prism(np.array(spec.polygon), d[0])


def _box(half: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float) * half
    quads = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    edges = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)]
    return [corners[list(q)] for q in quads], [corners[list(e)] for e in edges]


def _circle(radius: float, z: float = 0.0, n: int = SEGMENTS * 2) -> np.ndarray:
    t = np.linspace(0.0, 2.0 * math.pi, n + 1)
    return np.column_stack([radius * np.cos(t), radius * np.sin(t), np.full(n + 1, z)])


def _sphere(radius: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    lon = np.linspace(0.0, 2.0 * math.pi, SEGMENTS + 1)
    lat = np.linspace(-math.pi / 2.0, math.pi / 2.0, SEGMENTS // 2 + 1)
    lo, la = np.meshgrid(lon, lat, indexing="ij")
    grid = radius * np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
    quads = np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=2).reshape(-1, 4, 3)
    equator = _circle(radius)
    meridian_xz = equator[:, [0, 2, 1]]
    meridian_yz = equator[:, [2, 0, 1]]
    return list(quads), [equator, meridian_xz, meridian_yz]


def _cylinder(radius: float, height: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    t = np.linspace(0.0, 2.0 * math.pi, SEGMENTS * 2 + 1)
    x, y = radius * np.cos(t), radius * np.sin(t)
    low, high = -height / 2.0, height / 2.0
    bottom = np.column_stack([x, y, np.full_like(x, low)])
    top = np.column_stack([x, y, np.full_like(x, high)])
    sides = np.stack([bottom[:-1], bottom[1:], top[1:], top[:-1]], axis=1)
    verticals = [np.array([[radius * c, radius * s, low], [radius * c, radius * s, high]])
                 for c, s in ((1, 0), (0, 1), (-1, 0), (0, -1))]
    return [*sides, bottom[:-1], top[:-1]], [bottom, top, *verticals]


def _torus(major: float, minor: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    vertices, triangles = torus_mesh(major, minor, ring_segments=SEGMENTS * 2, tube_segments=SEGMENTS // 2)
    outline = [_circle(major + minor), _circle(major - minor), _circle(major, minor), _circle(major, -minor)]
    for angle in np.arange(8) * (math.pi / 4.0):  # cross-sections of the tube
        tube = _circle(minor, n=SEGMENTS)
        reach = major + tube[:, 0]
        outline.append(np.column_stack([reach * math.cos(angle), reach * math.sin(angle), tube[:, 1]]))
    return list(vertices[triangles]), outline


def _prism(polygon: np.ndarray, height: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    vertices, triangles = prism_mesh(polygon, height)
    n = len(polygon)
    base = np.column_stack([polygon, np.zeros(n)])
    top = np.column_stack([polygon, np.full(n, height)])
    faces = [base, top] + [np.array([base[a], base[(a + 1) % n], top[(a + 1) % n], top[a]]) for a in range(n)]
    if n > 3 and not _convex(polygon):  # matplotlib fills a non-convex polygon badly: use the triangulated caps
        faces = list(vertices[triangles])
    outline = [np.vstack([base, base[:1]]), np.vstack([top, top[:1]])] + [np.array([base[a], top[a]]) for a in range(n)]
    return faces, outline


def _convex(polygon: np.ndarray) -> bool:
    edges = np.roll(polygon, -1, axis=0) - polygon
    cross = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    return bool(np.all(cross >= -1e-12) or np.all(cross <= 1e-12))


def obstacle_spec(obstacle: Obstacle) -> ShapeSpec:
    if obstacle.shape == "prism":
        return ShapeSpec("prism", tuple(obstacle.dimensions), tuple(obstacle.polygon))
    return parse_shape(obstacle.shape, list(obstacle.dimensions))


# --- the picture ---------------------------------------------------------------------------------------------------

def draw_world(resolved: ResolvedWorld, path, elev: float = 25.0, azim: float = -60.0, title: str | None = None,
               overwrite: bool = False, dpi: int = 120) -> Path:
    """Draw `resolved` into the PNG `path` and return it; FileExistsError if it exists and not `overwrite`."""
    path = Path(path)
    if path.exists() and not overwrite:
        raise _exists(path)
    fig = Figure(figsize=(12.0, 8.0), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((-0.02, -0.04, 0.74, 1.0), projection="3d")
    assert isinstance(ax, Axes3D)  # what projection="3d" makes
    ax.computed_zorder = False  # draw by layer (surfaces, obstacles, poses), so poses are never hidden
    points: list[np.ndarray] = []  # everything drawn, for the view box
    legend: list = []

    for placed in resolved.geometries:
        points.append(_draw_geometry(ax, placed))
        legend.append(Patch(facecolor=(*placed.geometry.color, _face_alpha(placed.geometry.alpha)),
                            edgecolor=_outline_color(placed.geometry.color),
                            label=f"{placed.volume.name}/{placed.geometry.name} ({placed.geometry.spec.shape})"))

    obstacles = resolved.obstacles()
    if obstacles:
        points.append(_draw_obstacles(ax, obstacles))
        legend.append(Patch(facecolor=OBSTACLE_COLOR, edgecolor="black", label=f"obstacles ({len(obstacles)})"))

    palette = 0
    for placed in resolved.geometries:
        for pose_set in placed.poses():
            if not len(pose_set):
                continue
            color, palette = _pose_color(palette, placed.geometry.color)
            points.append(pose_set.positions)
            legend.append(_draw_poses(ax, placed, pose_set, color))

    _fit_view(ax, points)
    ax.view_init(elev=elev, azim=azim)
    ax.set_xlabel("x (m)", labelpad=8)
    ax.set_ylabel("y (m)", labelpad=8)
    ax.set_zlabel("z (m)", labelpad=10)
    if title is None:
        title = f"{Path(resolved.world.source).name}  (seed {resolved.seed}, {resolved.pose_count()} poses, " \
                f"{len(obstacles)} obstacles)"
    fig.suptitle(title, x=0.02, y=0.98, ha="left")
    if len(legend) > MAX_LEGEND_ENTRIES:  # drop geometry entries first: obstacles and pose sets matter more
        others = legend[len(resolved.geometries):]
        keep = max(MAX_LEGEND_ENTRIES - 1 - len(others), 0)
        shown = (legend[:keep] + others)[:MAX_LEGEND_ENTRIES - 1]
        legend = shown + [Patch(facecolor="none", edgecolor="none", label=f"... and {len(legend) - len(shown)} more")]
    if legend:
        fig.legend(handles=legend, loc="upper left", bbox_to_anchor=(0.74, 0.92), fontsize=8, frameon=False)
    return _save(fig, path, overwrite)


def _pose_color(start: int, avoid) -> tuple[str, int]:
    """The next palette colour that stands out from the geometry's colour `avoid`; also the next start."""
    for k in range(len(POSE_COLORS)):
        color = POSE_COLORS[(start + k) % len(POSE_COLORS)]
        if np.linalg.norm(np.array(to_rgb(color)) - np.asarray(avoid)) > 0.4:
            return color, start + k + 1
    return POSE_COLORS[start % len(POSE_COLORS)], start + 1


def _draw_poses(ax, placed: PlacedGeometry, pose_set, color: str):
    """One scatter for the set (a zigzag also as a line in flying order, its start marked); its legend entry."""
    xyz = pose_set.positions
    size = float(np.clip(3000.0 / len(xyz), 3.0, 36.0))  # smaller markers for crowded sets
    ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=size, color=color, depthshade=False, edgecolors="white",
               linewidths=0.4 if size > 10 else 0.0, zorder=6)
    if pose_set.spec.type == "zigzag":
        ax.plot(xyz[:, 0], xyz[:, 1], xyz[:, 2], color=color, linewidth=1.2, zorder=5)
        ax.scatter(xyz[:1, 0], xyz[:1, 1], xyz[:1, 2], s=90.0, marker="^", color=color, edgecolors="black",
                   linewidths=0.8, depthshade=False, zorder=7)
        label = f"{placed.frame_name}: {pose_set.path_name} ({len(xyz)} waypoints, \u25b2 start)"
        return Line2D([], [], color=color, marker="o", markersize=4, label=label)
    label = f"{placed.frame_name}: {pose_set.spec.type} ({len(xyz)})"
    return Line2D([], [], color=color, marker="o", linestyle="", markersize=6, label=label)


def _face_alpha(alpha: float) -> float:
    return MIN_ALPHA + (MAX_ALPHA - MIN_ALPHA) * float(min(max(alpha, 0.0), 1.0))


def _outline_color(color: tuple[float, float, float]) -> tuple[float, float, float]:
    """The geometry's colour pulled towards dark grey: visible on white and on the grey panes."""
    red, green, blue = (0.55 * c + 0.45 * 0.15 for c in color)
    return red, green, blue


def _draw_geometry(ax, placed: PlacedGeometry) -> np.ndarray:
    faces, outline = shape_mesh(placed.geometry.spec)
    frame = placed.frame
    faces = [frame.apply(f) for f in faces]
    outline = [frame.apply(o) for o in outline]
    color = placed.geometry.color
    face = [(*color, _face_alpha(placed.geometry.alpha))]  # shaded, so that even a white surface shows its form
    # autolim=False: the view box is set from the content at the end, and matplotlib's autoscaling reads the
    # uninitialised padding of polygons with different vertex counts (random NaN/1e308 limits).
    ax.add_collection3d(Poly3DCollection(faces, facecolors=face, edgecolors=face, linewidths=0.0, shade=True,
                                         zorder=1), autolim=False)
    ax.add_collection3d(Line3DCollection(outline, colors=[(*_outline_color(color), 0.9)], linewidths=0.9, zorder=2),
                        autolim=False)
    return np.vstack(outline)


def _draw_obstacles(ax, obstacles: list[Obstacle]) -> np.ndarray:
    faces_all, outline_all = [], []
    for obstacle in obstacles:
        faces, outline = shape_mesh(obstacle_spec(obstacle))
        frame = Frame.from_xyz_quaternion(obstacle.position, obstacle.quaternion)
        faces_all += [frame.apply(f) for f in faces]
        outline_all += [frame.apply(o) for o in outline]
    solid = [(*OBSTACLE_COLOR, 1.0)]
    ax.add_collection3d(Poly3DCollection(faces_all, facecolors=solid, edgecolors=solid, linewidths=0.0, shade=True,
                                         zorder=3), autolim=False)
    ax.add_collection3d(Line3DCollection(outline_all, colors="black", linewidths=0.6, zorder=4), autolim=False)
    return np.vstack(outline_all)


def content_bounds(points: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) per axis of the view box: the content plus a margin, every axis at least MIN_AXIS_SHARE wide."""
    pts = [p for p in points if len(p)]
    if not pts:
        return np.full(3, -1.0), np.full(3, 1.0)
    stacked = np.vstack(pts)
    low, high = stacked.min(axis=0), stacked.max(axis=0)
    centre, span = (low + high) / 2.0, high - low
    widest = max(float(span.max()), 1.0)
    span = np.maximum(span, MIN_AXIS_SHARE * widest) * 1.08
    return centre - span / 2.0, centre + span / 2.0


def _fit_view(ax, points: list[np.ndarray]) -> None:
    low, high = content_bounds(points)
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_zlim(low[2], high[2])
    ax.set_box_aspect(tuple(high - low), zoom=1.0)  # the same metres per unit length on every axis


def _exists(path: Path) -> FileExistsError:
    return FileExistsError(f"{path}: already exists; pass --force to overwrite it")


def _save(fig: Figure, path: Path, overwrite: bool) -> Path:
    try:
        return write_atomically(path, lambda out: fig.savefig(out, format="png"), overwrite=overwrite, binary=True)
    except FileExistsError:  # it appeared while drawing: never overwritten by accident
        raise _exists(path) from None
