"""Signed distances from a point to obstacle solids: exact for boxes, cylinders, spheres, capsules and prisms."""
import math

import numpy as np
import pytest

from magna_uav.shapes import Box, Capsule, Cylinder, Mesh, ShapeTable, Sphere, signed_distance
from magna_worlds.shapes import prism_mesh, torus_mesh


def yaw(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def pitch(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def mesh(vertices, triangles, rotation=np.eye(3), offset=(0, 0, 0)):
    return Mesh((vertices @ rotation.T + np.asarray(offset, float))[triangles])


@pytest.mark.parametrize("point, expected", [
    ((0, 0, 5), 4.0),  # above the top face
    ((3, 0, 0), 2.0),  # beside a face
    ((3, 3, 0), math.hypot(2, 2)),  # beside an edge
    ((3, 3, 3), math.sqrt(12)),  # beyond a corner
    ((0, 0, 0), -1.0),  # the centre: 1 m from every face
    ((0.8, 0, 0.1), -0.2),  # inside, nearest the +x face
])
def test_box(point, expected):
    assert signed_distance([Box((0, 0, 0), None, (1, 1, 1))], point) == pytest.approx(expected)


def test_box_turned_by_yaw_measures_in_its_own_frame():
    # a 10 x 1 x 1 m box turned 90 degrees: its long side now runs along y
    box = Box((5, 5, 0), yaw(math.pi / 2), (5, 0.5, 0.5))
    assert signed_distance([box], (5, 9, 0)) == pytest.approx(-0.5)  # inside the long side
    assert signed_distance([box], (9, 5, 0)) == pytest.approx(3.5)  # 4 m off the axis, 0.5 half width
    assert signed_distance([box], (5, 12, 0)) == pytest.approx(2.0)  # beyond its end
    # 45 degrees: the corner (5 + 0.5, 0.5) of a 10 x 1 box in its frame lies at 45 degrees in map
    turned = Box((0, 0, 0), yaw(math.pi / 4), (5, 0.5, 0.5))
    along = np.array([1.0, 1.0, 0]) / math.sqrt(2)
    assert signed_distance([turned], 7 * along) == pytest.approx(2.0)
    assert signed_distance([turned], 3 * np.array([-1.0, 1.0, 0]) / math.sqrt(2)) == pytest.approx(2.5)


@pytest.mark.parametrize("point, expected", [
    ((0, 0, 95), 95 - 0.15),  # 95 m above the middle of the wire
    ((150, 3, 0), 3 - 0.15),  # beside it, far from the centre
    ((205, 0, 0), 5.0),  # beyond an end, on the axis
    ((203, 4, 0), math.hypot(3, 4 - 0.15)),  # beyond an end, off the axis: to the end's rim
    ((0, 0.05, 0), -0.1),  # inside the wire
])
def test_a_long_thin_cylinder_along_x(point, expected):
    wire = Cylinder((0, 0, 0), pitch(math.pi / 2), 0.15, 200.0)  # axis z turned onto x, as the world files do
    assert signed_distance([wire], point) == pytest.approx(expected)


def test_sphere_capsule_and_the_union_of_parts():
    assert signed_distance([Sphere((1, 2, 3), 2.0)], (1, 2, 8)) == pytest.approx(3.0)
    capsule = Capsule((0, 0, 0), (10, 0, 0), 0.5)
    assert signed_distance([capsule], (5, 2, 0)) == pytest.approx(1.5)
    assert signed_distance([capsule], (-3, 4, 0)) == pytest.approx(4.5)
    assert signed_distance([Capsule((1, 1, 1), (1, 1, 1), 0.5)], (1, 1, 3)) == pytest.approx(1.5)  # a point
    # an obstacle of several parts is as near as its nearest part
    assert signed_distance([Sphere((0, 0, 0), 1.0), Sphere((10, 0, 0), 1.0)], (8, 0, 0)) == pytest.approx(1.0)
    assert signed_distance([], (0, 0, 0)) == math.inf


def test_prism_mesh_is_exact_even_when_not_convex():
    # an L: the square [0, 2] x [0, 2] without its corner [1, 2] x [1, 2], from z = 0 to z = 1
    poly = [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]
    solid = [mesh(*prism_mesh(poly, 1.0))]
    assert signed_distance(solid, (1.5, 1.5, 0.5)) == pytest.approx(0.5)  # in the notch: outside
    assert signed_distance(solid, (0.5, 0.5, 0.5)) == pytest.approx(-0.5)  # inside, 0.5 from four faces
    assert signed_distance(solid, (0.25, 1.5, 0.5)) == pytest.approx(-0.25)
    assert signed_distance(solid, (3, 0.5, 0.5)) == pytest.approx(1.0)
    assert signed_distance(solid, (1.5, 1.5, 3)) == pytest.approx(math.hypot(0.5, 2))  # above the notch


def test_torus_mesh_is_within_its_facet_error_of_the_true_torus():
    major, minor = 3.0, 1.5
    rotation, offset = yaw(0.3) @ pitch(0.4), np.array([2.0, -1.0, 4.0])
    solid = [mesh(*torus_mesh(major, minor), rotation, offset)]
    rng = np.random.default_rng(7)
    local = rng.uniform([-6, -6, -4], [6, 6, 4], (300, 3))
    true = np.hypot(np.hypot(local[:, 0], local[:, 1]) - major, local[:, 2]) - minor
    got = np.array([signed_distance(solid, offset + rotation @ q) for q in local])
    # the facets lie at most ~0.5 % of the tube radius inside the surface (magna_worlds.shapes)
    np.testing.assert_allclose(got, true, atol=0.01 * minor)
    assert signed_distance(solid, offset) == pytest.approx(1.5, abs=0.01)  # the hole's centre is outside


def test_a_table_gives_one_distance_per_obstacle_in_order():
    table = ShapeTable([
        [Sphere((0, 0, 10), 1.0)],
        [],  # nothing: infinitely far
        [Box((0, 5, 0), None, (1, 1, 1)), Cylinder((0, -3, 0), None, 0.5, 2.0)],
        [mesh(*torus_mesh(3.0, 1.0))],
        [Capsule((0, 0, -4), (0, 0, -8), 0.5)],
    ])
    np.testing.assert_allclose(table.signed_distances((0, 0, 0)), [9.0, math.inf, 2.5, 2.0, 3.5], atol=0.02)
