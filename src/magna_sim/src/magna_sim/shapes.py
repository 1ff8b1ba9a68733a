"""Obstacle primitives of the world files as static pybullet bodies.

The shapes, their dimension conventions and their checks live in
`magna_worlds.shapes` (the world model owns them); this module only turns a
checked shape into a pybullet body. Pybullet has no torus: it becomes a closed
triangle mesh (a concave trimesh, fine for static bodies). A convex prism is a
convex hull; a non-convex one a concave trimesh.
"""
from __future__ import annotations

import numpy as np
import pybullet as p

from magna_worlds.shapes import SHAPES, ShapeError, ShapeSpec, finite_vector, parse_shape, prism_mesh, torus_mesh

__all__ = ["SHAPES", "ShapeError", "ShapeSpec", "create_obstacle", "parse_shape", "prism_mesh", "torus_mesh"]


def create_obstacle(client: int, shape: str, dimensions, vertices=None, position=(0.0, 0.0, 0.0),
                    orientation_xyzw=(0.0, 0.0, 0.0, 1.0), rgba=(0.5, 0.5, 0.5, 1.0)) -> int:
    """A static (mass 0) body for one obstacle; returns its pybullet body id."""
    spec = parse_shape(shape, dimensions, vertices)
    pos = finite_vector(position, 3, "position", "give [x, y, z] in metres")
    quat = finite_vector(orientation_xyzw, 4, "orientation_xyzw", "give a quaternion [x, y, z, w]")
    norm = float(np.linalg.norm(quat))
    if norm < 1e-9:
        raise ShapeError("orientation_xyzw: a zero quaternion is no rotation; use [0, 0, 0, 1] for none")
    color = finite_vector(rgba, 4, "rgba", "give [r, g, b, a], each 0..1")
    if np.any(color < 0.0) or np.any(color > 1.0):
        raise ShapeError(f"rgba: each component must be 0..1 (divide 0-255 colours by 255), got {color.tolist()}")
    collision, visual = _pybullet_shapes(client, spec, color.tolist())
    return p.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual,
                             basePosition=pos.tolist(), baseOrientation=(quat / norm).tolist(),
                             physicsClientId=client)


# --- pybullet ---------------------------------------------------------------------------------------------------

def _pybullet_shapes(client: int, spec: ShapeSpec, rgba: list[float]) -> tuple[int, int]:
    d = spec.dimensions
    if spec.shape == "cube":
        half = [x / 2.0 for x in d]
        return (p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client),
                p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=rgba, physicsClientId=client))
    if spec.shape == "sphere":
        return (p.createCollisionShape(p.GEOM_SPHERE, radius=d[0] / 2.0, physicsClientId=client),
                p.createVisualShape(p.GEOM_SPHERE, radius=d[0] / 2.0, rgbaColor=rgba, physicsClientId=client))
    if spec.shape == "cylinder":
        return (p.createCollisionShape(p.GEOM_CYLINDER, radius=d[0] / 2.0, height=d[2], physicsClientId=client),
                p.createVisualShape(p.GEOM_CYLINDER, radius=d[0] / 2.0, length=d[2], rgbaColor=rgba,
                                    physicsClientId=client))
    if spec.shape == "torus":
        vertices, triangles = torus_mesh(d[0] / 2.0, d[2] / 2.0)
    else:
        vertices, triangles = prism_mesh(spec.polygon, d[0])
    verts, indices = vertices.tolist(), triangles.ravel().tolist()
    if spec.convex:
        collision = p.createCollisionShape(p.GEOM_MESH, vertices=verts, physicsClientId=client)  # convex hull
    else:
        collision = p.createCollisionShape(p.GEOM_MESH, vertices=verts, indices=indices,
                                           flags=p.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=client)
    visual = p.createVisualShape(p.GEOM_MESH, vertices=verts, indices=indices, rgbaColor=rgba,
                                 physicsClientId=client)
    return collision, visual
