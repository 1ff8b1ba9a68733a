"""Obstacle solids and the signed distance from a point to each of them, vectorised with numpy.

An obstacle reaches a UAV manager as an rviz marker: the world node publishes a cube,
sphere or cylinder as that primitive and a torus or prism as the triangles of its closed
surface. `magna_uav.ros_data` turns each marker into one or more parts, all in map:

    Sphere(centre, radius)
    Box(centre, rotation, half)                      half edge lengths along the box frame's axes
    Cylinder(centre, rotation, radius, half_height)  the axis is the frame's z
    Capsule(a, b, radius)                            a thick segment (line markers)
    Mesh(triangles)                                  (m, 3, 3) corners of a surface's triangles

`rotation` turns the part's own frame into map (a column per own axis). The signed
distance from a point to an obstacle is the smallest over its parts: the distance to the
solid's surface, negative inside it. It is exact for spheres, boxes, cylinders and
capsules; for a mesh it is the exact distance to the triangles, negative when the point is
inside the surface (generalised winding number above one half), so it is exact for a
prism, and for a torus it is the distance to the drawn facets, which lie on the true
surface at their corners and at most ~0.5 % of the tube radius inside it in between.

`ShapeTable` stacks the parts of a whole obstacle list by kind once, so one query costs
a handful of array operations however many obstacles there are.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np


def _vector(value, n: int = 3) -> np.ndarray:
    return np.asarray(value, dtype=float).reshape(n)


def _matrix(value) -> np.ndarray:
    return np.eye(3) if value is None else np.asarray(value, dtype=float).reshape(3, 3)


@dataclass(frozen=True, eq=False)
class Sphere:
    centre: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _vector(self.centre))
        object.__setattr__(self, "radius", float(self.radius))


@dataclass(frozen=True, eq=False)
class Box:
    centre: np.ndarray
    rotation: np.ndarray  # own frame -> map
    half: np.ndarray  # half edge lengths, own frame

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _vector(self.centre))
        object.__setattr__(self, "rotation", _matrix(self.rotation))
        object.__setattr__(self, "half", np.abs(_vector(self.half)))


@dataclass(frozen=True, eq=False)
class Cylinder:
    centre: np.ndarray
    rotation: np.ndarray  # own frame -> map; the axis is the own z
    radius: float
    half_height: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _vector(self.centre))
        object.__setattr__(self, "rotation", _matrix(self.rotation))
        object.__setattr__(self, "radius", float(self.radius))
        object.__setattr__(self, "half_height", float(self.half_height))


@dataclass(frozen=True, eq=False)
class Capsule:
    a: np.ndarray
    b: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _vector(self.a))
        object.__setattr__(self, "b", _vector(self.b))
        object.__setattr__(self, "radius", float(self.radius))


@dataclass(frozen=True, eq=False)
class Mesh:
    triangles: np.ndarray  # (m, 3, 3): triangle, corner, xyz

    def __post_init__(self) -> None:
        object.__setattr__(self, "triangles", np.asarray(self.triangles, dtype=float).reshape(-1, 3, 3))


Part = Sphere | Box | Cylinder | Capsule | Mesh


class ShapeTable:
    """The parts of a list of obstacles, stacked by kind; `signed_distances(point)` gives one value per obstacle.

    `parts_of[i]` are obstacle i's parts (an obstacle given none counts as the sphere
    `fallback[i]`, its bounding sphere).
    """

    def __init__(self, parts_of: Sequence[Sequence[Part]]):
        self.count = len(parts_of)
        spheres: list[tuple[int, Sphere]] = []
        boxes: list[tuple[int, Box]] = []
        cylinders: list[tuple[int, Cylinder]] = []
        capsules: list[tuple[int, Capsule]] = []
        meshes: list[tuple[int, Mesh]] = []
        for owner, parts in enumerate(parts_of):
            for part in parts:
                if isinstance(part, Sphere):
                    spheres.append((owner, part))
                elif isinstance(part, Box):
                    boxes.append((owner, part))
                elif isinstance(part, Cylinder):
                    cylinders.append((owner, part))
                elif isinstance(part, Capsule):
                    capsules.append((owner, part))
                elif isinstance(part, Mesh):
                    meshes.append((owner, part))
                else:
                    raise TypeError(f"obstacle {owner}: {part!r} is not a Sphere, Box, Cylinder, Capsule or Mesh")
        # (reduceat starts, unique owners, distance function) per kind present
        self._groups: list[tuple[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]] = []

        def group(items: Sequence[tuple[int, Part]], fn: Callable[[np.ndarray], np.ndarray]) -> None:
            if not items:
                return
            owners = np.array([o for o, _ in items], dtype=np.intp)  # nondecreasing
            starts = np.flatnonzero(np.r_[True, owners[1:] != owners[:-1]])
            self._groups.append((starts, owners[starts], fn))

        if spheres:
            self._sph_c = np.array([p.centre for _, p in spheres])
            self._sph_r = np.array([p.radius for _, p in spheres], dtype=float)
        group(spheres, self._spheres)

        if boxes:
            self._box_c = np.array([p.centre for _, p in boxes])
            self._box_r = np.array([p.rotation for _, p in boxes])
            self._box_h = np.array([p.half for _, p in boxes])
        group(boxes, self._boxes)

        if cylinders:
            self._cyl_c = np.array([p.centre for _, p in cylinders])
            self._cyl_r = np.array([p.rotation for _, p in cylinders])
            self._cyl_rad = np.array([p.radius for _, p in cylinders], dtype=float)
            self._cyl_hh = np.array([p.half_height for _, p in cylinders], dtype=float)
        group(cylinders, self._cylinders)

        if capsules:
            self._cap_a = np.array([p.a for _, p in capsules])
            self._cap_ab = np.array([p.b - p.a for _, p in capsules])
            self._cap_ab2 = np.einsum("ij,ij->i", self._cap_ab, self._cap_ab)
            self._cap_r = np.array([p.radius for _, p in capsules], dtype=float)
        group(capsules, self._capsules)

        meshes = [(o, p) for o, p in meshes if len(p.triangles)]
        if meshes:
            self._mesh_prepare([p.triangles for _, p in meshes])
        group(meshes, self._meshes)

    def signed_distances(self, point) -> np.ndarray:
        """(count,) signed distance (m) from `point` to each obstacle's solid, negative inside; inf without parts."""
        p = _vector(point)
        out = np.full(self.count, math.inf)
        for starts, owners, fn in self._groups:
            d = fn(p)
            best = np.minimum.reduceat(d, starts) if len(starts) != len(d) else d
            out[owners] = np.minimum(out[owners], best)
        return out

    # --- one kind each: the signed distance to every part of that kind -------------------------------------------

    def _spheres(self, p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(self._sph_c - p, axis=1) - self._sph_r

    def _boxes(self, p: np.ndarray) -> np.ndarray:
        q = np.einsum("nji,nj->ni", self._box_r, p - self._box_c)  # R^T (p - c): the point in each box's frame
        d = np.abs(q) - self._box_h
        return np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)

    def _cylinders(self, p: np.ndarray) -> np.ndarray:
        q = np.einsum("nji,nj->ni", self._cyl_r, p - self._cyl_c)
        dr = np.hypot(q[:, 0], q[:, 1]) - self._cyl_rad
        dz = np.abs(q[:, 2]) - self._cyl_hh
        return np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(np.maximum(dr, dz), 0.0)

    def _capsules(self, p: np.ndarray) -> np.ndarray:
        return _segment_distance(p, self._cap_a, self._cap_ab, self._cap_ab2) - self._cap_r

    def _mesh_prepare(self, meshes: list[np.ndarray]) -> None:
        tri = np.concatenate(meshes)
        self._tri_mesh = np.repeat(np.arange(len(meshes)), [len(m) for m in meshes])  # mesh of each triangle
        self._mesh_count = len(meshes)
        self._mesh_starts = np.r_[0, np.cumsum([len(m) for m in meshes])[:-1]].astype(np.intp)
        corners = [m.reshape(-1, 3) for m in meshes]
        self._mesh_lo = np.array([c.min(axis=0) for c in corners])
        self._mesh_hi = np.array([c.max(axis=0) for c in corners])
        self._v0, self._v1, self._v2 = tri[:, 0], tri[:, 1], tri[:, 2]
        self._e0, self._e1 = self._v1 - self._v0, self._v2 - self._v0
        self._e2 = self._v2 - self._v1
        self._d00, self._d01, self._d11 = _dot(self._e0, self._e0), _dot(self._e0, self._e1), _dot(self._e1, self._e1)
        self._e2sq = _dot(self._e2, self._e2)
        self._denom = self._d00 * self._d11 - self._d01 ** 2  # |e0 x e1|^2: 0 for a degenerate triangle
        normal = np.cross(self._e0, self._e1)
        length = np.linalg.norm(normal, axis=1)
        self._flat = length > 1e-12 * np.maximum(self._d00 + self._d11, 1e-300)
        self._unit_normal = normal / np.where(self._flat, length, 1.0)[:, None]
        # a ball about each triangle's centroid holding it: bounds that spare the exact distance to far triangles
        self._centroid = tri.mean(axis=1)
        self._reach = np.linalg.norm(tri - self._centroid[:, None, :], axis=2).max(axis=1)

    def _meshes(self, p: np.ndarray) -> np.ndarray:
        """Per mesh: the distance to its nearest triangle, negative when the mesh holds `p` (winding > 1/2)."""
        to_centroid = np.linalg.norm(self._centroid - p, axis=1)
        upper = np.minimum.reduceat(to_centroid + self._reach, self._mesh_starts)
        # only triangles that may be nearer than some triangle of their mesh surely is
        k = np.flatnonzero(to_centroid - self._reach <= upper[self._tri_mesh])
        w = p - self._v0[k]
        e0, e1 = self._e0[k], self._e1[k]
        d00, d01, d11 = self._d00[k], self._d01[k], self._d11[k]
        d20, d21 = _dot(w, e0), _dot(w, e1)
        flat = self._flat[k]
        denom = np.where(flat, self._denom[k], 1.0)
        v = (d11 * d20 - d01 * d21) / denom
        u = (d00 * d21 - d01 * d20) / denom
        over_face = flat & (v >= 0.0) & (u >= 0.0) & (u + v <= 1.0)
        plane = np.abs(_dot(w, self._unit_normal[k]))
        edges = np.minimum(np.minimum(_segment_distance(p, self._v0[k], e0, d00),
                                      _segment_distance(p, self._v0[k], e1, d11)),
                           _segment_distance(p, self._v1[k], self._e2[k], self._e2sq[k]))
        nearest = np.full(self._mesh_count, math.inf)
        owner = self._tri_mesh[k]  # nondecreasing, as k is: one run per mesh (every mesh keeps a triangle)
        runs = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
        nearest[owner[runs]] = np.minimum.reduceat(np.where(over_face, plane, edges), runs)

        # inside only within the mesh's bounding box: there, the winding number of the mesh about p,
        # its triangles' solid angles (Van Oosterom and Strackee) over 4 pi
        boxed = np.all((self._mesh_lo <= p) & (p <= self._mesh_hi), axis=1)
        if boxed.any():
            t = np.flatnonzero(boxed[self._tri_mesh])
            a, b, c = self._v0[t] - p, self._v1[t] - p, self._v2[t] - p
            la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
            numerator = _dot(a, np.cross(b, c))
            denominator = la * lb * lc + _dot(a, b) * lc + _dot(b, c) * la + _dot(c, a) * lb
            winding = np.bincount(self._tri_mesh[t], weights=2.0 * np.arctan2(numerator, denominator),
                                  minlength=self._mesh_count) / (4.0 * math.pi)
            nearest = np.where(np.abs(winding) > 0.5, -nearest, nearest)
        return nearest


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _segment_distance(p: np.ndarray, a: np.ndarray, ab: np.ndarray, ab2: np.ndarray) -> np.ndarray:
    """Distance from p to each segment a + t ab, t in [0, 1] (a point when ab is 0)."""
    ap = p - a
    t = np.clip(np.einsum("ij,ij->i", ap, ab) / np.where(ab2 > 0.0, ab2, 1.0), 0.0, 1.0)
    return np.linalg.norm(ap - t[:, None] * ab, axis=1)


def signed_distance(parts: Sequence[Part], point) -> float:
    """The signed distance from `point` to the union of `parts` (one obstacle); inf for no parts."""
    return float(ShapeTable([parts]).signed_distances(point)[0])


def bounding_sphere(parts: Sequence[Part]) -> tuple[np.ndarray, float]:
    """A sphere holding every part, about the centre of their bounding box (for pictures and tests)."""
    lo, hi = [], []
    for part in parts:
        if isinstance(part, Sphere):
            lo.append(part.centre - part.radius)
            hi.append(part.centre + part.radius)
        elif isinstance(part, Box | Cylinder):
            half = part.half if isinstance(part, Box) else np.array([part.radius, part.radius, part.half_height])
            reach = np.abs(part.rotation) @ half
            lo.append(part.centre - reach)
            hi.append(part.centre + reach)
        elif isinstance(part, Capsule):
            lo.append(np.minimum(part.a, part.b) - part.radius)
            hi.append(np.maximum(part.a, part.b) + part.radius)
        elif len(part.triangles):
            lo.append(part.triangles.reshape(-1, 3).min(axis=0))
            hi.append(part.triangles.reshape(-1, 3).max(axis=0))
    if not lo:
        raise ValueError("no parts to bound")
    lo_, hi_ = np.min(lo, axis=0), np.max(hi, axis=0)
    return (lo_ + hi_) / 2.0, float(np.linalg.norm(hi_ - lo_)) / 2.0
