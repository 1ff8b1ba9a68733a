"""Obstacle primitives: where their surfaces are (by ray casts), their meshes, and the errors on bad input."""
import json
import math

import numpy as np
import pybullet as p
import pytest

from magna_sim.shapes import SHAPES, ShapeError, create_obstacle, parse_shape, prism_mesh, torus_mesh
from tests.support import CORPUS

CORPUS_WORLDS = CORPUS / "Worlds"


@pytest.fixture
def client():
    cid = p.connect(p.DIRECT)
    yield cid
    p.disconnect(cid)


def hit(client, start, end):
    """(body id, hit point) of the first body on the segment start -> end; body -1 when nothing is hit."""
    body, _link, _fraction, point, _normal = p.rayTest(start, end, physicsClientId=client)[0]
    return body, np.array(point)


def assert_hit(client, body, start, end, expected, tol=1e-3):
    got_body, point = hit(client, start, end)
    assert got_body == body, f"ray {start} -> {end} hit {got_body}, expected body {body}"
    np.testing.assert_allclose(point, expected, atol=tol)


def assert_miss(client, start, end):
    got_body, point = hit(client, start, end)
    assert got_body == -1, f"ray {start} -> {end} hit body {got_body} at {point}"


def quat_from_euler(roll, pitch, yaw):
    return p.getQuaternionFromEuler([roll, pitch, yaw])


# --- surfaces -----------------------------------------------------------------------------------------------------

def test_cube_dimensions_are_full_edge_lengths_centred_on_the_origin(client):
    body = create_obstacle(client, "cube", [2.0, 4.0, 6.0])
    assert_hit(client, body, [10, 0, 0], [0, 0, 0], [1, 0, 0])
    assert_hit(client, body, [-10, 0, 0], [0, 0, 0], [-1, 0, 0])
    assert_hit(client, body, [0, 10, 0], [0, 0, 0], [0, 2, 0])
    assert_hit(client, body, [0, 0, 10], [0, 0, 0], [0, 0, 3])
    assert_hit(client, body, [0, 0, -10], [0, 0, 0], [0, 0, -3])


def test_cube_is_placed_and_rotated(client):
    # Yawed by 90 degrees its 4 m side lies along x: faces at x = 10 -+ 2.
    body = create_obstacle(client, "cube", [2.0, 4.0, 6.0], position=[10, 0, 3],
                           orientation_xyzw=quat_from_euler(0, 0, math.pi / 2))
    assert_hit(client, body, [0, 0, 3], [20, 0, 3], [8, 0, 3])
    assert_hit(client, body, [10, -10, 3], [10, 0, 3], [10, -1, 3])
    assert_hit(client, body, [10, 0, 20], [10, 0, 0], [10, 0, 6])


def test_sphere_dimensions_are_diameters(client):
    body = create_obstacle(client, "sphere", [1.0, 1.0, 1.0], position=[0, 0, 5])
    assert_hit(client, body, [0, 0, 10], [0, 0, 0], [0, 0, 5.5])
    diagonal = np.array([1.0, 1.0, 1.0]) / math.sqrt(3.0)
    assert_hit(client, body, [0, 0, 5] + 5 * diagonal, [0, 0, 5], [0, 0, 5] + 0.5 * diagonal)


def test_cylinder_is_diameter_and_height_about_z_centred(client):
    body = create_obstacle(client, "cylinder", [3.0, 3.0, 2.0], position=[0, 0, 2.5])
    assert_hit(client, body, [10, 0, 2.5], [0, 0, 2.5], [1.5, 0, 2.5])
    s = 1.5 / math.sqrt(2.0)  # round in the xy plane, not a box
    assert_hit(client, body, [10, 10, 2.5], [0, 0, 2.5], [s, s, 2.5])
    assert_hit(client, body, [0, 0, 10], [0, 0, 0], [0, 0, 3.5])
    assert_hit(client, body, [0, 0, -10], [0, 0, 2.5], [0, 0, 1.5])


def test_cylinder_axis_follows_the_orientation(client):
    # Rolled by 90 degrees the axis lies along y: the flat ends are at y = -+3.
    body = create_obstacle(client, "cylinder", [2.0, 2.0, 6.0], orientation_xyzw=quat_from_euler(math.pi / 2, 0, 0))
    assert_hit(client, body, [0, 10, 0], [0, 0, 0], [0, 3, 0])
    assert_hit(client, body, [0, 0, 10], [0, 0, 0], [0, 0, 1])


def test_torus_is_centre_line_outer_and_tube_diameters_about_z(client):
    # [2R, 2R + 2r, 2r] = [6, 9, 3]: the solid spans 1.5 .. 4.5 m from the z axis, 1.5 m up and down.
    body = create_obstacle(client, "torus", [6.0, 9.0, 3.0], position=[0, 0, 2.5])
    assert_hit(client, body, [10, 0, 2.5], [0, 0, 2.5], [4.5, 0, 2.5])
    assert_hit(client, body, [0, 0, 2.5], [10, 0, 2.5], [1.5, 0, 2.5])  # from the hole outward
    assert_hit(client, body, [0, -10, 2.5], [0, 0, 2.5], [0, -4.5, 2.5])
    assert_hit(client, body, [3, 0, 10], [3, 0, 2.5], [3, 0, 4.0])
    # Between the vertices the facets lie just inside the true surface.
    c, s = math.cos(0.3), math.sin(0.3)
    got_body, point = hit(client, [10 * c, 10 * s, 2.5], [0, 0, 2.5])
    assert got_body == body and 4.5 * 0.995 < np.hypot(point[0], point[1]) <= 4.5 + 1e-6
    assert_miss(client, [0, 0, 10], [0, 0, -10])  # down the hole
    assert_miss(client, [1.2, 0, 10], [1.2, 0, -10])
    assert_miss(client, [6, 0, 10], [6, 0, -10])


def test_torus_tilted_stands_up(client):
    body = create_obstacle(client, "torus", [6.0, 9.0, 3.0], orientation_xyzw=quat_from_euler(math.pi / 2, 0, 0))
    assert_hit(client, body, [0, 0, 10], [0, 0, 0], [0, 0, 4.5])
    assert_miss(client, [0, 10, 0], [0, -10, 0])  # the hole now faces along y


def test_prism_base_is_at_the_origin_and_extrudes_up(client):
    square = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
    body = create_obstacle(client, "prism", [3.0, square], position=[0, 0, 1])
    assert_hit(client, body, [0, 0, 10], [0, 0, 0], [0, 0, 4])
    assert_hit(client, body, [0, 0, -10], [0, 0, 2], [0, 0, 1])
    assert_hit(client, body, [10, 0.5, 2], [0, 0.5, 2], [1, 0.5, 2])
    assert_miss(client, [10, 0, 4.5], [-10, 0, 4.5])
    assert_miss(client, [10, 0, 0.5], [-10, 0, 0.5])


def test_non_convex_prism_keeps_its_notch(client):
    ell = [[0, 0, 0], [4, 0, 0], [4, 1, 0], [1, 1, 0], [1, 3, 0], [0, 3, 0]]
    body = create_obstacle(client, "prism", [2.0, ell])
    assert_hit(client, body, [3, 0.5, 10], [3, 0.5, 0], [3, 0.5, 2])
    assert_miss(client, [3, 2, 10], [3, 2, -10])  # inside the L's notch: a convex hull would fill it
    assert_hit(client, body, [10, 2, 1], [0, 2, 1], [1, 2, 1])
    assert_hit(client, body, [0.5, 10, 1], [0.5, 0, 1], [0.5, 3, 1])


def test_prism_vertices_may_come_separately_clockwise_or_closed(client):
    # The spawn service's form: the height in dimensions, the vertices apart; any winding; a closing repeat.
    clockwise_closed = [[0, 0, 0], [0, 2, 0], [2, 2, 0], [2, 0, 0], [0, 0, 0]]
    body = create_obstacle(client, "prism", [1.5], vertices=clockwise_closed, position=[5, 0, 0])
    assert_hit(client, body, [6, 1, 10], [6, 1, 0], [6, 1, 1.5])
    assert_hit(client, body, [0, 1, 0.5], [6, 1, 0.5], [5, 1, 0.5])
    assert parse_shape("prism", [1.5], clockwise_closed) == parse_shape("prism", [1.5, clockwise_closed[:4]])


def test_obstacles_are_static(client):
    p.setGravity(0, 0, -9.81, physicsClientId=client)
    bodies = [create_obstacle(client, "sphere", [1, 1, 1], position=[0, 0, 5]),
              create_obstacle(client, "torus", [2, 3, 1], position=[5, 0, 5]),
              create_obstacle(client, "prism", [1, [[0, 0], [1, 0], [0, 1]]], position=[-5, 0, 5])]
    for _ in range(20):
        p.stepSimulation(physicsClientId=client)
    for body in bodies:
        assert p.getDynamicsInfo(body, -1, physicsClientId=client)[0] == 0.0
        assert p.getBasePositionAndOrientation(body, physicsClientId=client)[0][2] == pytest.approx(5.0)


def test_every_geometry_of_the_original_worlds_spawns(client):
    assert CORPUS_WORLDS.is_dir(), f"no corpus at {CORPUS_WORLDS}; set MAGNA_CORPUS to ros_magna_corpus"
    count = 0
    for path in sorted(CORPUS_WORLDS.glob("*/*.json")):
        for volume in json.loads(path.read_text())["scenario"]["volumes"]:
            for geometry in volume["geometries"]:
                xyz, rpy = geometry["origin"]
                create_obstacle(client, geometry["shape"], geometry["dimensions"], position=xyz,
                                orientation_xyzw=quat_from_euler(*rpy))
                for poses_set in geometry.get("poses_sets", []):
                    for shape in poses_set.get("obstacles_shape", []):
                        create_obstacle(client, shape, poses_set["obstacles_dimensions"])
                count += 1
    assert count > 20


def test_the_central_cylinder_fills_the_torus_hole(client):
    # Gym/1Obs_Central_Cylinder: torus [6, 9, 3] around a cylinder [3, 3, 3], both at z = 2.5.
    torus = create_obstacle(client, "torus", [6.0, 9.0, 3.0], position=[0, 0, 2.5])
    cylinder = create_obstacle(client, "cylinder", [3.0, 3.0, 3.0], position=[0, 0, 2.5])
    body, point = hit(client, [10, 0, 2.5], [0, 0, 2.5])
    assert body == torus and point[0] == pytest.approx(4.5, abs=1e-3)
    p.removeBody(torus, physicsClientId=client)
    assert_hit(client, cylinder, [10, 0, 2.5], [0, 0, 2.5], [1.5, 0, 2.5])


# --- meshes ---------------------------------------------------------------------------------------------------------

def mesh_volume(vertices, triangles):
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)  # positive when faces point outward


def assert_closed_and_consistent(triangles):
    # Every directed edge once, and its reverse once: closed, and all faces wound the same way.
    edges = [(int(t[k]), int(t[(k + 1) % 3])) for t in triangles for k in range(3)]
    unique = set(edges)
    assert len(unique) == len(edges)
    assert all((b, a) in unique for a, b in edges)


def test_torus_mesh_is_closed_with_the_torus_volume():
    vertices, triangles = torus_mesh(3.0, 1.5)
    assert_closed_and_consistent(triangles)
    assert mesh_volume(vertices, triangles) == pytest.approx(2 * math.pi**2 * 3.0 * 1.5**2, rel=0.01)


def test_prism_mesh_is_closed_with_area_times_height():
    star = [(math.cos(k * math.pi / 5) * (2.0 if k % 2 == 0 else 0.8),
             math.sin(k * math.pi / 5) * (2.0 if k % 2 == 0 else 0.8)) for k in range(10)]
    spec = parse_shape("prism", [2.5, star])
    assert not spec.convex
    vertices, triangles = prism_mesh(spec.polygon, 2.5)
    assert_closed_and_consistent(triangles)
    x, y = np.array(spec.polygon).T
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
    assert mesh_volume(vertices, triangles) == pytest.approx(area * 2.5)


def test_convexity_is_detected():
    assert parse_shape("prism", [1, [[0, 0], [2, 0], [2, 2], [1, 2], [0, 2]]]).convex  # collinear corner
    assert not parse_shape("prism", [1, [[0, 0], [2, 0], [2, 2], [1, 1], [0, 2]]]).convex


# --- errors ---------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("shape, dimensions, vertices, field, words", [
    ("box", [1, 1, 1], None, "shape", "cube, sphere, cylinder, torus, prism"),
    ("cube", [1, 1], None, "dimensions", "size_x, size_y, size_z"),
    ("cube", 2.0, None, "dimensions", "expected a list"),
    ("cube", [1, -1, 1], None, r"dimensions\[1\]", "positive"),
    ("cube", [1, 0, 1], None, r"dimensions\[1\]", "positive"),
    ("cube", [1, 1, float("nan")], None, r"dimensions\[2\]", "finite number"),
    ("cube", [1, True, 1], None, r"dimensions\[1\]", "finite number"),
    ("cube", [1, "2", 1], None, r"dimensions\[1\]", "finite number"),
    ("cube", [1, 1, 1], [[0, 0], [1, 0], [0, 1]], "vertices", "only a prism"),
    ("sphere", [1, 1, 2], None, "dimensions", "ellipsoids"),
    ("sphere", [1], None, "dimensions", "diameter, diameter, diameter"),
    ("cylinder", [3, 3], None, "dimensions", r"diameter, diameter, height"),
    ("cylinder", [3, 2, 3], None, "dimensions", "elliptic"),
    ("torus", [6, 8, 3], None, r"dimensions\[1\]", "must be 6.0 \\+ 3.0 = 9.0"),
    ("torus", [2, 6, 4], None, r"dimensions\[2\]", "overlap itself"),
    ("prism", [1, [[0, 0], [1, 0]]], None, r"dimensions\[1\]", "3 or more base vertices"),
    ("prism", [1], [[0, 0], [1, 0]], "vertices", "3 or more base vertices"),
    ("prism", [1], None, "vertices", "missing"),
    ("prism", [1, [[0, 0], [1, 0], [0, 1]]], [[0, 0], [1, 0], [0, 1]], "vertices", "given twice"),
    ("prism", [-1, [[0, 0], [1, 0], [0, 1]]], None, r"dimensions\[0\]", "positive"),
    ("prism", [1, [[0, 0], [1, 0], [2, 0]]], None, r"dimensions\[1\]", "no area"),
    ("prism", [1, [[0, 0], [2, 2], [2, 0], [0, 2]]], None, r"dimensions\[1\]", "cross"),
    ("prism", [1, [[0, 0], [1, 0], [1, 0], [0, 1]]], None, r"dimensions\[1\]\[2\]", "repeats vertex 1"),
    ("prism", [1, [[0, 0], [1], [0, 1]]], None, r"dimensions\[1\]\[1\]", r"\[x, y\] or \[x, y, z\]"),
    ("prism", [1, [[0, 0], [1, float("inf")], [0, 1]]], None, r"dimensions\[1\]\[1\]\[1\]", "finite"),
    ("prism", [1, 2, 3], None, "dimensions", "got 3 values"),
])
def test_bad_input_names_the_field(client, shape, dimensions, vertices, field, words):
    with pytest.raises(ShapeError, match=rf"^{field}: .*{words}"):
        create_obstacle(client, shape, dimensions, vertices)
    assert p.getNumBodies(physicsClientId=client) == 0


@pytest.mark.parametrize("kwargs, field", [
    ({"position": [0, 0]}, "position"),
    ({"position": [0, 0, float("nan")]}, r"position\[2\]"),
    ({"orientation_xyzw": [0, 0, 0, 0]}, "orientation_xyzw"),
    ({"orientation_xyzw": [0, 0, 1]}, "orientation_xyzw"),
    ({"rgba": [255, 0, 0, 1]}, "rgba"),
])
def test_bad_pose_or_colour_names_the_field(client, kwargs, field):
    with pytest.raises(ShapeError, match=rf"^{field}: "):
        create_obstacle(client, "cube", [1, 1, 1], **kwargs)


def test_shape_error_is_a_value_error_and_every_shape_is_known():
    assert issubclass(ShapeError, ValueError)
    assert SHAPES == ("cube", "sphere", "cylinder", "torus", "prism")
