"""rviz markers built from a resolved world (no ROS master needed: messages only)."""
from pathlib import Path

import numpy as np
from visualization_msgs.msg import Marker

from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world
from magna_worlds.markers import world_markers
from magna_worlds.shapes import contains
from magna_worlds.transforms import Frame
from tests.support import CORPUS

ALL_SHAPES = Path(__file__).resolve().parent / "worlds" / "Test" / "All_Shapes.json"


def markers_of(path, seed=0):
    resolved = resolve_world(load_world(path), seed)
    return resolved, world_markers([resolved]).markers


def by_ns(markers, ns):
    return [m for m in markers if m.ns == ns]


def test_one_marker_per_geometry_in_the_file_colour_and_alpha():
    resolved, markers = markers_of(CORPUS / "Worlds" / "Gym" / "1Obs_Central_Cylinder.json")
    geometries = by_ns(markers, "geometries")
    assert [m.id for m in geometries] == list(range(len(resolved.geometries)))
    torus = geometries[1]  # CentralZone/Accessible: torus, colour [255, 255, 255], alpha 0.7
    assert torus.type == Marker.TRIANGLE_LIST
    assert (torus.color.r, torus.color.g, torus.color.b) == (1.0, 1.0, 1.0)
    assert np.isclose(torus.color.a, 0.7)
    cylinder = geometries[2]  # dimensions [3, 3, 3] at z 2.5
    assert cylinder.type == Marker.CYLINDER
    assert (cylinder.scale.x, cylinder.scale.y, cylinder.scale.z) == (3.0, 3.0, 3.0)
    assert np.isclose(cylinder.pose.position.z, 2.5)
    assert all(m.header.frame_id == "map" for m in markers)


def test_torus_triangles_lie_on_its_surface_in_map():
    resolved, markers = markers_of(CORPUS / "Worlds" / "Gym" / "1Obs_Central_Cylinder.json")
    torus = by_ns(markers, "geometries")[1]
    points = np.array([[p.x, p.y, p.z] for p in torus.points])
    assert len(points) % 3 == 0 and len(points) > 300
    radius_from_axis = np.hypot(points[:, 0], points[:, 1])
    tube = np.hypot(radius_from_axis - 3.0, points[:, 2])  # marker points are in the torus frame (pose carries z)
    np.testing.assert_allclose(tube, 1.5, atol=1e-9)
    np.testing.assert_allclose(torus.pose.position.z, 2.5)


def test_prism_is_drawn_as_its_faces_and_rotated_volumes_carry_their_pose():
    resolved, markers = markers_of(ALL_SHAPES, seed=4)
    sweep = next(g for g in resolved.geometries if g.geometry.name == "Sweep")
    prism = by_ns(markers, "geometries")[resolved.geometries.index(sweep)]
    assert prism.type == Marker.TRIANGLE_LIST
    local = np.array([[p.x, p.y, p.z] for p in prism.points])
    assert contains(sweep.geometry.spec, local, tolerance=1e-9).all()
    assert set(np.round(local[:, 2], 9)) == {0.0, 3.0}
    q = prism.pose.orientation
    frame = Frame.from_xyz_quaternion([prism.pose.position.x, prism.pose.position.y, prism.pose.position.z],
                                      [q.x, q.y, q.z, q.w])
    np.testing.assert_allclose(frame.translation, sweep.frame.translation, atol=1e-12)
    np.testing.assert_allclose(frame.rotation, sweep.frame.rotation, atol=1e-12)


def test_poses_paths_and_obstacles_are_all_shown():
    resolved, markers = markers_of(ALL_SHAPES, seed=4)
    spheres = [m for m in by_ns(markers, "poses") if m.type == Marker.SPHERE_LIST]
    shown = np.array([[p.x, p.y, p.z] for m in spheres for p in m.points])
    expected = np.concatenate([s.positions for g in resolved.geometries for s in g.poses()])
    np.testing.assert_allclose(shown, expected)
    lines = [m for m in by_ns(markers, "poses") if m.type == Marker.LINE_STRIP]
    assert len(lines) == 1 and len(lines[0].points) == 10  # the zigzag, in flying order
    obstacles = by_ns(markers, "obstacles")
    assert len(obstacles) == len(resolved.obstacles())
    for marker, obstacle in zip(obstacles, resolved.obstacles(), strict=True):
        assert marker.text == obstacle.name
        np.testing.assert_allclose([marker.pose.position.x, marker.pose.position.y, marker.pose.position.z],
                                   obstacle.position)
        if obstacle.shape == "sphere":
            assert marker.type == Marker.SPHERE and np.isclose(marker.scale.x, obstacle.dimensions[0])


def test_markers_start_by_clearing_stale_ones():
    _, markers = markers_of(ALL_SHAPES)
    assert markers[0].action == Marker.DELETEALL
    assert world_markers([]).markers[0].action == Marker.DELETEALL
    assert len(world_markers([]).markers) == 1
