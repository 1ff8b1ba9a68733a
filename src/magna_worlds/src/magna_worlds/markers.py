"""rviz markers of a resolved world: geometries in their colour, free-space poses, obstacles.

All markers sit in `map` with the full pose, so rviz draws them without waiting
for tf. Namespaces: `geometries`, `poses` (one SPHERE_LIST per pose set, a
LINE_STRIP more for a zigzag path) and `obstacles`. Geometry colours come from
the file (0-255 there, 0..1 here) with its alpha; a torus and a prism are drawn
as their triangle faces. Builds messages only: publishing is the node's job.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from magna_worlds.generate import ResolvedWorld
from magna_worlds.shapes import parse_shape, prism_mesh, torus_mesh
from magna_worlds.transforms import Frame

MAP_FRAME = "map"
POSE_SIZE = 0.15  # m, diameter of a free-space pose's sphere
PATH_WIDTH = 0.05  # m
OBSTACLE_COLOR = (0.25, 0.25, 0.28, 1.0)
POSE_COLORS = [(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.4, 0.74)]
_PRIMITIVE = {"cube": Marker.CUBE, "sphere": Marker.SPHERE, "cylinder": Marker.CYLINDER}


def world_markers(worlds: list[ResolvedWorld]) -> MarkerArray:
    """Every marker of every world part, ids unique per namespace, preceded by a DELETEALL so stale ones vanish."""
    clear = Marker(action=Marker.DELETEALL)
    clear.header.frame_id = MAP_FRAME
    out = MarkerArray(markers=[clear])
    ids = {"geometries": 0, "poses": 0, "obstacles": 0}

    def add(marker: Marker, ns: str) -> None:
        marker.header.frame_id = MAP_FRAME
        marker.ns, marker.id = ns, ids[ns]
        ids[ns] += 1
        out.markers.append(marker)

    for world in worlds:
        for placed in world.geometries:
            g = placed.geometry
            rgba = (*g.color, g.alpha)
            add(_solid(g.spec.shape, g.spec.dimensions, g.spec.polygon, placed.frame, rgba), "geometries")
            for pose_set in placed.poses():
                color = POSE_COLORS[ids["poses"] % len(POSE_COLORS)]
                add(_points(pose_set.positions, Marker.SPHERE_LIST, POSE_SIZE, (*color, 1.0)), "poses")
                if pose_set.path_name and len(pose_set.positions) > 1:
                    add(_points(pose_set.positions, Marker.LINE_STRIP, PATH_WIDTH, (*color, 0.8)), "poses")
            for obstacle in placed.obstacles:
                frame = Frame.from_xyz_quaternion(obstacle.position, obstacle.quaternion)
                marker = _solid(obstacle.shape, obstacle.dimensions, obstacle.polygon, frame, OBSTACLE_COLOR)
                marker.text = obstacle.name  # rviz ignores text on solids; UAV managers name obstacles by it
                add(marker, "obstacles")
    return out


def _solid(shape: str, dimensions, polygon, frame: Frame, rgba) -> Marker:
    marker = Marker(action=Marker.ADD, color=ColorRGBA(*rgba), pose=_pose(frame))
    if shape in _PRIMITIVE:
        marker.type = _PRIMITIVE[shape]
        marker.scale = Vector3(*dimensions)  # rviz scales are full sizes, as the world files write them
        return marker
    if shape == "torus":
        spec = parse_shape("torus", dimensions)
        vertices, triangles = torus_mesh(spec.dimensions[0] / 2.0, spec.dimensions[2] / 2.0)
    else:
        vertices, triangles = prism_mesh(polygon, dimensions[0])
    marker.type = Marker.TRIANGLE_LIST
    marker.scale = Vector3(1.0, 1.0, 1.0)
    marker.points = [Point(*v) for v in vertices[triangles.ravel()]]
    return marker


def _points(positions: np.ndarray, kind: int, size: float, rgba) -> Marker:
    marker = Marker(type=kind, action=Marker.ADD, color=ColorRGBA(*rgba), scale=Vector3(size, size, size))
    marker.pose.orientation.w = 1.0
    marker.points = [Point(*p) for p in positions.tolist()]
    return marker


def _pose(frame: Frame) -> Pose:
    x, y, z, w = frame.quaternion()
    return Pose(position=Point(*frame.translation.tolist()), orientation=Quaternion(x, y, z, w))
