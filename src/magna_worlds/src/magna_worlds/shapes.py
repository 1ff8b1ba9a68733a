"""The five shapes of the world files: checked specs, meshes, point-inside tests and uniform sampling.

`dimensions` follow the original ROS-MAGNA world JSON, where a geometry's
dimensions are the scale of its rviz marker and of its Gazebo model
(Worlds/Geometries.py and Worlds/PoseElements.py of JoseAndresMR/ros_magna):

=========  ===========================================  ==========================================
shape      dimensions                                   solid, in the shape's own frame
=========  ===========================================  ==========================================
cube       [size_x, size_y, size_z] full edge lengths   box centred on the origin
sphere     [diameter, diameter, diameter]               sphere centred on the origin
cylinder   [diameter, diameter, height]                 cylinder centred on the origin, axis z
torus      [2R, 2R + 2r, 2r]: centre-line diameter,     ring about the z axis, centred on the origin
           outer diameter, tube diameter
prism      [height, [[x, y, z], ...]] base vertices     the polygon (x, y) extruded from z = 0 up to
           (or [height] plus the `vertices` argument,   z = height: the base lies in the origin's
           as the world_config spawn service sends it)  xy plane, not centred
=========  ===========================================  ==========================================

Examples from the real worlds (ros_magna_corpus/Worlds): Gym/1Obs_Central_Cylinder.json has
a torus [6.0, 9.0, 3.0] (R = 3, r = 1.5, so it spans 1.5 .. 4.5 m from its axis) around
a cylinder [3.0, 3.0, 3.0] that exactly fills its hole; the Gazebo spawner used radius
dimensions[0]/2 for spheres and cylinders and dimensions[2] as the cylinder length.
A prism vertex's z is ignored, as in the original, whose prism worlds give 0
(e.g. Code/JSONs/Worlds/GAUSSUseCase1/CropField.json: [10.0, [[-210,-125,0], ...]]).

Ellipsoids and elliptic cylinders are refused (neither the simulator nor the sampler
has them). `contains` and `sample_uniform` work on the exact solids, vectorised over
points; the meshes are for bodies and pictures: their facets lie on the true surface at
their vertices and at most ~0.5% of a radius inside it between them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from magna_common.json_fields import is_number
from magna_worlds.vocabulary import SHAPES, Shape

TORUS_RING_SEGMENTS = 64  # around the z axis
TORUS_TUBE_SEGMENTS = 32  # around the tube

_USAGE = {
    "cube": "a cube needs [size_x, size_y, size_z] (full edge lengths, m)",
    "sphere": "a sphere needs [diameter, diameter, diameter] (m, the three equal)",
    "cylinder": "a cylinder needs [diameter, diameter, height] (m, axis z, the two diameters equal)",
    "torus": "a torus needs [2R, 2R + 2r, 2r]: centre-line diameter, outer diameter, tube diameter (m)",
    "prism": "a prism needs [height, [[x, y, z], ...]] with 3 or more base vertices, "
             "or [height] and the vertices argument",
}


class ShapeError(ValueError):
    """Bad obstacle input; the message starts with the field and says how to fix it."""


@dataclass(frozen=True)
class ShapeSpec:
    """A checked obstacle description (see the module docstring for the conventions)."""

    shape: Shape
    dimensions: tuple[float, ...]  # prism: (height,)
    polygon: tuple[tuple[float, float], ...] = ()  # prism only: base vertices, counter-clockwise

    @property
    def convex(self) -> bool:
        return self.shape != "torus" and (self.shape != "prism" or is_convex(np.array(self.polygon)))


def parse_shape(shape: Any, dimensions: Any, vertices: Any = None) -> ShapeSpec:
    """Check `shape`/`dimensions`/`vertices`; raise ShapeError naming the field."""
    if shape not in SHAPES:
        raise ShapeError(f"shape: unknown shape {shape!r}; use one of {', '.join(SHAPES)}")
    dims = _sequence(dimensions, "dimensions", _USAGE[shape])
    if shape == "prism":
        return _parse_prism(dims, vertices)
    if vertices is not None:
        raise ShapeError(f"vertices: only a prism has vertices; a {shape} takes none (pass None)")
    if len(dims) != 3:
        raise ShapeError(f"dimensions: {_USAGE[shape]}, got {len(dims)} value(s)")
    d = tuple(_positive(v, f"dimensions[{i}]", _USAGE[shape]) for i, v in enumerate(dims))
    if shape == "sphere" and not (math.isclose(d[0], d[1]) and math.isclose(d[0], d[2])):
        raise ShapeError(f"dimensions: {_USAGE['sphere']}; ellipsoids are not supported, got {list(d)}")
    if shape == "cylinder" and not math.isclose(d[0], d[1]):
        raise ShapeError(f"dimensions: {_USAGE['cylinder']}; elliptic cylinders are not supported, got {list(d)}")
    if shape == "torus":
        if not math.isclose(d[1], d[0] + d[2], rel_tol=1e-6):
            raise ShapeError(f"dimensions[1]: {_USAGE['torus']}; the outer diameter must be "
                             f"{d[0]} + {d[2]} = {d[0] + d[2]}, got {d[1]}")
        if d[2] > d[0]:
            raise ShapeError(f"dimensions[2]: {_USAGE['torus']}; the tube diameter {d[2]} must not exceed "
                             f"the centre-line diameter {d[0]} (the ring would overlap itself)")
    return ShapeSpec(shape, d)


def torus_mesh(major_radius: float, minor_radius: float, ring_segments: int = TORUS_RING_SEGMENTS,
               tube_segments: int = TORUS_TUBE_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """Closed torus about z: vertices (N, 3) and outward-facing (counter-clockwise) triangles (M, 3)."""
    phi = np.arange(ring_segments) * (2.0 * np.pi / ring_segments)  # around z
    theta = np.arange(tube_segments) * (2.0 * np.pi / tube_segments)  # around the tube
    ph, th = np.meshgrid(phi, theta, indexing="ij")
    rho = major_radius + minor_radius * np.cos(th)
    vertices = np.stack([rho * np.cos(ph), rho * np.sin(ph), minor_radius * np.sin(th)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(ring_segments), np.arange(tube_segments), indexing="ij")
    i1, j1 = (i + 1) % ring_segments, (j + 1) % tube_segments

    def at(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a * tube_segments + b).ravel()

    # d/dphi x d/dtheta points outward, so (i,j) -> (i+1,j) -> (i+1,j+1) winds counter-clockwise outside.
    triangles = np.concatenate([np.stack([at(i, j), at(i1, j), at(i1, j1)], axis=1),
                                np.stack([at(i, j), at(i1, j1), at(i, j1)], axis=1)])
    return vertices, triangles


def prism_mesh(polygon: npt.ArrayLike, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed extrusion of a simple counter-clockwise polygon from z = 0 to z = height."""
    base = np.asarray(polygon, dtype=float)
    n = len(base)
    vertices = np.vstack([np.column_stack([base, np.zeros(n)]), np.column_stack([base, np.full(n, height)])])
    caps = triangulate(base)
    sides = []
    for a in range(n):
        b = (a + 1) % n
        sides += [(a, b, n + b), (a, n + b, n + a)]  # outward for a counter-clockwise base
    triangles = np.vstack([caps[:, ::-1], caps + n, np.array(sides)])  # bottom faces down, top faces up
    return vertices, triangles



# --- solids: inside tests, bounds, volume, uniform sampling (all in the shape's own frame) ----------------------

def half_extents(spec: ShapeSpec) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (low, high) of the solid."""
    d = spec.dimensions
    if spec.shape == "prism":
        poly = np.array(spec.polygon)
        return np.append(poly.min(axis=0), 0.0), np.append(poly.max(axis=0), d[0])
    if spec.shape == "torus":
        outer = d[1] / 2.0
        half = np.array([outer, outer, d[2] / 2.0])
    else:
        half = np.array(d) / 2.0
    return -half, half


def solid_volume(spec: ShapeSpec) -> float:
    d = spec.dimensions
    if spec.shape == "cube":
        return d[0] * d[1] * d[2]
    if spec.shape == "sphere":
        return math.pi * d[0] ** 3 / 6.0
    if spec.shape == "cylinder":
        return math.pi * (d[0] / 2.0) ** 2 * d[2]
    if spec.shape == "torus":
        return 2.0 * math.pi ** 2 * (d[0] / 2.0) * (d[2] / 2.0) ** 2
    return abs(signed_area(np.array(spec.polygon))) * d[0]


def contains(spec: ShapeSpec, points: npt.ArrayLike, tolerance: float = 1e-9) -> np.ndarray:
    """Which of `points` (N, 3) lie inside the closed solid, boundary included (up to `tolerance` m)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    d, tol = spec.dimensions, tolerance
    if spec.shape == "cube":
        return np.all(np.abs(pts) <= np.array(d) / 2.0 + tol, axis=1)
    if spec.shape == "sphere":
        return np.linalg.norm(pts, axis=1) <= d[0] / 2.0 + tol
    if spec.shape == "cylinder":
        return (np.hypot(x, y) <= d[0] / 2.0 + tol) & (np.abs(z) <= d[2] / 2.0 + tol)
    if spec.shape == "torus":
        return np.hypot(np.hypot(x, y) - d[0] / 2.0, z) <= d[2] / 2.0 + tol
    inside_height = (z >= -tol) & (z <= d[0] + tol)
    return inside_height & _in_polygon(np.array(spec.polygon), x, y, tol)


def sample_uniform(spec: ShapeSpec, count: int, rng: np.random.Generator) -> np.ndarray:
    """`count` points (count, 3) drawn uniformly from the solid's volume."""
    d = spec.dimensions
    if spec.shape == "cube":
        return (rng.random((count, 3)) - 0.5) * np.array(d)
    if spec.shape == "sphere":
        direction = rng.normal(size=(count, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        return direction * (d[0] / 2.0 * np.cbrt(rng.random(count)))[:, None]
    if spec.shape == "cylinder":
        radius = d[0] / 2.0 * np.sqrt(rng.random(count))  # area grows with r^2
        angle = rng.random(count) * 2.0 * math.pi
        return np.column_stack([radius * np.cos(angle), radius * np.sin(angle), (rng.random(count) - 0.5) * d[2]])
    if spec.shape == "torus":
        return _sample_torus(d[0] / 2.0, d[2] / 2.0, count, rng)
    return _sample_prism(np.array(spec.polygon), d[0], count, rng)


def _sample_torus(major: float, minor: float, count: int, rng: np.random.Generator) -> np.ndarray:
    # Uniform in the tube's disc, then keep a sample with probability (R + rho cos theta) / (R + r): the outer
    # side of the ring holds more volume than the inner side. Acceptance is at least R / (R + r) >= 1/2.
    chunks, have = [np.empty((0, 3))], 0  # count 0 gives an empty (0, 3) array, as the other shapes do
    while have < count:
        n = 2 * (count - have) + 16
        rho = minor * np.sqrt(rng.random(n))
        theta = rng.random(n) * 2.0 * math.pi
        ring = major + rho * np.cos(theta)
        keep = rng.random(n) * (major + minor) <= ring
        phi = rng.random(n) * 2.0 * math.pi
        chunk = np.column_stack([ring * np.cos(phi), ring * np.sin(phi), rho * np.sin(theta)])[keep]
        chunks.append(chunk)
        have += len(chunk)
    return np.concatenate(chunks)[:count]


def _sample_prism(polygon: np.ndarray, height: float, count: int, rng: np.random.Generator) -> np.ndarray:
    triangles = polygon[triangulate(polygon)]  # (T, 3, 2)
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    areas = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    pick = rng.choice(len(triangles), size=count, p=areas / areas.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0  # fold the far half of the parallelogram back into the triangle
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    xy = a[pick] + u[:, None] * (b[pick] - a[pick]) + v[:, None] * (c[pick] - a[pick])
    return np.column_stack([xy, rng.random(count) * height])


def _in_polygon(poly: np.ndarray, x: np.ndarray, y: np.ndarray, tol: float) -> np.ndarray:
    """Even-odd rule, vectorised over points; points within `tol` of an edge count as inside."""
    inside = np.zeros(x.shape, dtype=bool)
    near_edge = np.zeros(x.shape, dtype=bool)
    for (x0, y0), (x1, y1) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        crosses = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (x < x_at)
        ex, ey = x1 - x0, y1 - y0
        t = np.clip(((x - x0) * ex + (y - y0) * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        near_edge |= np.hypot(x - (x0 + t * ex), y - (y0 + t * ey)) <= tol
    return inside | near_edge


# --- checks -----------------------------------------------------------------------------------------------------

def _parse_prism(dims: list[Any], vertices: Any) -> ShapeSpec:
    usage = _USAGE["prism"]
    if len(dims) == 2:
        if vertices is not None:
            raise ShapeError("vertices: given twice (in dimensions[1] and in the vertices argument); keep one")
        vertices, where = dims[1], "dimensions[1]"
    elif len(dims) == 1:
        if vertices is None:
            raise ShapeError(f"vertices: missing; {usage}")
        where = "vertices"
    else:
        raise ShapeError(f"dimensions: {usage}, got {len(dims)} values")
    height = _positive(dims[0], "dimensions[0]", usage + " (the height)")
    raw = _sequence(vertices, where, usage)
    points = []
    for k, vertex in enumerate(raw):
        xyz = _sequence(vertex, f"{where}[{k}]", "a vertex is [x, y] or [x, y, z]")
        if len(xyz) not in (2, 3):
            raise ShapeError(f"{where}[{k}]: a vertex is [x, y] or [x, y, z], got {len(xyz)} value(s)")
        points.append([_finite(xyz[0], f"{where}[{k}][0]"), _finite(xyz[1], f"{where}[{k}][1]")])
    if len(points) > 3 and points[0] == points[-1]:
        points.pop()  # a polygon closed by repeating its first vertex
    if len(points) < 3:
        raise ShapeError(f"{where}: {usage}, got {len(points)} vertex(es)")
    for k, point in enumerate(points):
        if point in points[:k]:
            raise ShapeError(f"{where}[{k}]: repeats vertex {points.index(point)}; give each corner once")
    poly = np.array(points)
    crossing = _self_intersection(poly)
    if crossing is not None:
        raise ShapeError(f"{where}: the polygon's edges {crossing[0]} and {crossing[1]} cross; list the "
                         "vertices in order around the boundary")
    area = signed_area(poly)
    scale = float(np.ptp(poly, axis=0).max()) or 1.0
    if abs(area) <= 1e-9 * scale * scale:
        raise ShapeError(f"{where}: the base polygon has no area (repeated or collinear vertices); "
                         "give the corners of a real polygon in order")
    if area < 0:
        poly = poly[::-1]  # either winding is accepted; the meshes want counter-clockwise
    return ShapeSpec("prism", (height,), tuple((float(x), float(y)) for x, y in poly))


def _sequence(value: Any, where: str, usage: str) -> list[Any]:
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or not hasattr(value, "__getitem__"):
        raise ShapeError(f"{where}: expected a list; {usage}, got {value!r}")
    return list(value)


def _finite(value: Any, where: str) -> float:
    if not is_number(value):
        raise ShapeError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _positive(value: Any, where: str, usage: str) -> float:
    x = _finite(value, where)
    if x <= 0.0:
        raise ShapeError(f"{where}: must be positive; {usage}, got {x}")
    return x


def finite_vector(value: Any, n: int, where: str, usage: str) -> np.ndarray:
    items = _sequence(value, where, usage)
    if len(items) != n:
        raise ShapeError(f"{where}: {usage}, got {len(items)} value(s)")
    return np.array([_finite(v, f"{where}[{i}]") for i, v in enumerate(items)])


# --- 2-D polygon helpers ----------------------------------------------------------------------------------------

def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def is_convex(poly: np.ndarray) -> bool:
    n = len(poly)
    return all(_cross(poly[i], poly[(i + 1) % n], poly[(i + 2) % n]) >= 0.0 for i in range(n))


def _segments_cross(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether closed segments ab and cd share a point."""
    d1, d2, d3, d4 = _cross(c, d, a), _cross(c, d, b), _cross(a, b, c), _cross(a, b, d)
    if ((d1 > 0) != (d2 > 0) and d1 != 0 and d2 != 0) and ((d3 > 0) != (d4 > 0) and d3 != 0 and d4 != 0):
        return True

    def on(p_: np.ndarray, q: np.ndarray, r: np.ndarray) -> bool:  # r collinear with pq and inside its box
        return (min(p_[0], q[0]) <= r[0] <= max(p_[0], q[0]) and min(p_[1], q[1]) <= r[1] <= max(p_[1], q[1]))

    return ((d1 == 0 and on(c, d, a)) or (d2 == 0 and on(c, d, b)) or (d3 == 0 and on(a, b, c))
            or (d4 == 0 and on(a, b, d)))


def _self_intersection(poly: np.ndarray) -> tuple[int, int] | None:
    """The first pair of non-adjacent edges that touch, as edge indices (edge i runs from vertex i to i+1)."""
    n = len(poly)
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue  # neighbours share a vertex by construction
            if _segments_cross(poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]):
                return i, j
    return None


def triangulate(poly: np.ndarray) -> np.ndarray:
    """Ear clipping of a simple counter-clockwise polygon; triangles (n-2, 3) of vertex indices."""
    remaining = list(range(len(poly)))
    triangles: list[tuple[int, ...]] = []
    while len(remaining) > 3:
        for k in range(len(remaining)):
            a, b, c = remaining[k - 1], remaining[k], remaining[(k + 1) % len(remaining)]
            if _cross(poly[a], poly[b], poly[c]) <= 0.0:
                continue  # reflex or flat corner: not an ear
            if any(_inside_triangle(poly[q], poly[a], poly[b], poly[c]) for q in remaining if q not in (a, b, c)):
                continue
            triangles.append((a, b, c))
            remaining.pop(k)
            break
        else:  # only flat corners left (collinear runs): drop one, it adds no area
            flat = next(k for k in range(len(remaining))
                        if _cross(poly[remaining[k - 1]], poly[remaining[k]],
                                  poly[remaining[(k + 1) % len(remaining)]]) == 0.0)
            remaining.pop(flat)
    triangles.append(tuple(remaining))
    return np.array(triangles, dtype=int)


def _inside_triangle(q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
    return _cross(a, b, q) >= 0.0 and _cross(b, c, q) >= 0.0 and _cross(c, a, q) >= 0.0
