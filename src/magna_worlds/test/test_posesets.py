"""magna_worlds.posesets and .generate: where every pose and obstacle goes, how many, their names, and the seeds."""
import copy
import json
import math
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from magna_worlds.errors import WorldError
from magna_worlds.generate import resolve_world, world_record
from magna_worlds.loader import load_world, world_from_data
from magna_worlds.model import PoseSetSpec
from magna_worlds.posesets import LayoutError, matrix_layout, zigzag_layout
from magna_worlds.shapes import contains, parse_shape
from magna_worlds.transforms import quaternions_from_rpy
from tests.rotations import rpy_matrix, ry, rz
from tests.support import CORPUS

CORPUS_WORLDS = CORPUS / "Worlds"
TOL = 1e-9


def corpus_worlds():
    """The corpus files; without the corpus, one path that does not exist, so the tests using it fail (not skip)."""
    return sorted(CORPUS_WORLDS.glob("*/*.json")) or [CORPUS_WORLDS / "missing" / "corpus.json"]


# --- a synthetic world: five shapes x every kind of set, rotated volume, rotated geometries --------------------

L_SHAPE = [[0, 0, 0], [4, 0, 0], [4, 1, 0], [1, 1, 0], [1, 3, 0], [0, 3, 0]]  # non-convex
U_SHAPE = [[0, 0], [6, 0], [6, 4], [4, 4], [4, 1], [2, 1], [2, 4], [0, 4]]  # non-convex, lines cut it twice
HEXAGON = [[2, 0], [1, 1.7], [-1, 1.7], [-2, 0], [-1, -1.7], [1, -1.7]]
OBSTACLE_RANGES = [[0.5, 1.0], [0.6, 0.9], [0.2, 0.4]]
OBSTACLE_SHAPES = ["cube", "sphere", "cylinder", "torus"]

# geometry name -> (shape, dimensions, origin, a few coordinates inside the solid)
GEOMETRIES = {
    "Box": ("cube", [3.0, 2.0, 1.5], [[1, 2, 0.5], [0.4, 0.1, -0.7]], [[0, 0, 0], [1.4, -0.9, 0.7]]),
    "Ball": ("sphere", [2.0, 2.0, 2.0], [[-2, 0, 1], [0, 0, 0]], [[0, 0, 0], [0.5, -0.5, 0.5]]),
    "Can": ("cylinder", [2.0, 2.0, 3.0], [[0, -3, 1], [1.2, 0, 0.3]], [[0, 0, 1.4], [0.7, 0.7, -1.4]]),
    "Ring": ("torus", [4.0, 6.0, 2.0], [[4, 4, 0], [0, 0.5, 2.0]], [[2, 0, 0], [0, -2.9, 0.2]]),
    "Roof": ("prism", [2.0, HEXAGON], [[-4, -4, 0], [0, 0, 0.8]], [[0, 0, 1], [1.9, 0, 0]]),
    "Ell": ("prism", [1.5, L_SHAPE], [[0, 6, 0], [0.3, -0.2, 2.5]], [[0.5, 2.5, 1], [3.5, 0.5, 0.1]]),
}


def synthetic_geometry(name, shape, dimensions, origin, coordinates):
    sets = [
        {"type": "matrix", "matrix_type": "dimension", "use": "poses", "dimensions": [3, 4, 2],
         "poses_orientation": [0.1, -0.2, 0.3]},
        {"type": "matrix", "matrix_type": "distance", "use": "poses", "dimensions": [0.5, 0.6, 0.4], "density": 0.7},
        {"type": "random", "use": "poses", "quantity": 25, "poses_orientation": "random"},
        {"type": "coordinates", "use": "poses",
         "coordinates": [[c, [0, 0, 0.5 * k]] for k, c in enumerate(coordinates)]},
        {"type": "random", "use": "obstacles", "quantity": 12, "obstacles_shape": OBSTACLE_SHAPES,
         "obstacles_dimensions": OBSTACLE_RANGES, "poses_orientation": [[0, 0.3], [-0.2, 0.2], [-1, 1]]},
        {"type": "matrix", "matrix_type": "dimension", "use": "obstacles", "dimensions": [2, 2, 2],
         "density": 0.8, "obstacles_shape": "sphere", "obstacles_dimensions": [0.3, 0.3, 0.3]},
    ]
    if shape == "prism":
        sets += [
            {"type": "matrix", "matrix_type": "dimension", "use": "poses", "dimensions": [5, 4, 2],
             "set_orientation": [0, 0, 0.6]},
            {"type": "matrix", "matrix_type": "distance", "use": "poses", "dimensions": [0.4, 0.5, 0.5],
             "set_orientation": [0, 0, -0.9]},
            {"type": "zigzag", "use": "poses", "height": 0.75, "spacing": [0.3, 0.4], "sweep_angle": 0.35,
             "margins": [0.1, 0.2], "initial_sense": "left"},
            {"type": "random", "use": "obstacles", "quantity": 4, "obstacles_shape": ["prism"],
             "obstacles_dimensions": [0.5, [[0, 0], [0.3, 0], [0, 0.2]]]},
        ]
    return {"name": name, "prefix": name.lower()[:3], "shape": shape, "id": 0, "origin": origin,
            "dimensions": dimensions if shape != "prism" else [dimensions[0], dimensions[1]],
            "color": [1, 2, 3], "alpha": 0.5, "poses_sets": sets}


def synthetic_data():
    geometries = [synthetic_geometry(name, *spec) for name, spec in GEOMETRIES.items()]
    return {"scenario": {
        "world_boundaries": [[-50, 50], [-50, 50], [-50, 50]],
        "volumes": [
            {"name": "Turned", "prefix": "T", "origin": [[5, -3, 2], [0.2, -0.3, 1.0]], "permits": "geofence",
             "geometries": geometries},
            {"name": "Plain", "prefix": "P", "origin": [[0, 0, 0], [0, 0, 0]], "permits": "geofence",
             "geometries": copy.deepcopy(geometries)},
        ],
    }}


def synthetic(seed=0, data=None):
    loaded = world_from_data(synthetic_data() if data is None else data, "synthetic.json")
    assert loaded.warnings == ()
    return resolve_world(loaded, seed)


def local_of(placed, map_positions):
    """Map positions brought back into the geometry frame."""
    return placed.frame.inverse().apply(map_positions)


def assert_all_inside(resolved):
    checked = 0
    for placed in resolved.geometries:
        spec = placed.geometry.spec
        for pose_set in placed.pose_sets:
            local = local_of(placed, pose_set.positions)
            np.testing.assert_allclose(local, pose_set.local_positions, atol=1e-9)
            outside = ~contains(spec, local, tolerance=TOL)
            assert not outside.any(), (f"{placed.frame_name} set {pose_set.index}: "
                                       f"{local[outside].tolist()} outside the {spec.shape}")
            checked += len(local)
        if placed.obstacles:
            local = local_of(placed, np.array([o.position for o in placed.obstacles]))
            np.testing.assert_allclose(local, np.array([o.local_position for o in placed.obstacles]), atol=1e-9)
            assert contains(spec, local, tolerance=TOL).all(), f"{placed.frame_name}: an obstacle centre is outside"
            checked += len(local)
    return checked


# --- every pose inside its geometry ---------------------------------------------------------------------------

@pytest.mark.parametrize("path", corpus_worlds(), ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_corpus_pose_and_obstacle_lies_inside_its_geometry(path):
    loaded = load_world(path, search_path=[])
    for seed in range(4):
        resolved = resolve_world(loaded, seed)
        checked = assert_all_inside(resolved)
        assert checked == resolved.pose_count() + len(resolved.obstacles())
    assert checked > 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_synthetic_pose_and_obstacle_lies_inside_its_geometry(seed):
    resolved = synthetic(seed)
    checked = assert_all_inside(resolved)
    assert checked > 1000
    # all five shapes and all four set types (and both uses) took part
    assert {g.geometry.spec.shape for g in resolved.geometries} == {"cube", "sphere", "cylinder", "torus", "prism"}
    assert {s.spec.type for g in resolved.geometries for s in g.pose_sets} == {"matrix", "random", "coordinates",
                                                                               "zigzag"}
    for placed in resolved.geometries:
        assert all(len(s) > 0 for s in placed.pose_sets)
        assert placed.obstacles


def test_geometry_frames_compose_volume_and_geometry_origins_by_hand():
    resolved = synthetic()
    volume_rpy, volume_xyz = [0.2, -0.3, 1.0], np.array([5, -3, 2])
    for name, (_, _, (xyz, rpy), _) in GEOMETRIES.items():
        placed = resolved.geometry("Turned", name)
        local = np.array([[0.1, 0.2, 0.3], [0, 0, 0]])
        by_hand = (rpy_matrix(volume_rpy) @ (rpy_matrix(rpy) @ local.T + np.array(xyz)[:, None])).T + volume_xyz
        np.testing.assert_allclose(placed.frame.apply(local), by_hand, atol=1e-12)
        plain = resolved.geometry("Plain", name)
        np.testing.assert_allclose(plain.frame.apply(local), (rpy_matrix(rpy) @ local.T).T + xyz, atol=1e-12)
        # the same sets give the same local poses whichever volume holds them (only the seed streams differ)
        first_matrix = placed.pose_sets[0]
        np.testing.assert_allclose(first_matrix.local_positions, plain.pose_sets[0].local_positions)


def test_map_orientations_are_the_local_ones_turned_by_the_geometry_frame():
    resolved = synthetic()
    for placed in resolved.geometries:
        for pose_set in placed.pose_sets:
            for q_local, q_map in zip(pose_set.local_quaternions, pose_set.quaternions, strict=True):
                expected = placed.frame.rotation @ Rotation.from_quat(q_local).as_matrix()
                np.testing.assert_allclose(Rotation.from_quat(q_map).as_matrix(), expected, atol=1e-9)


# --- counts ---------------------------------------------------------------------------------------------------

def geometry_of(resolved, name, volume="Plain"):
    return resolved.geometry(volume, name)


def set_at(placed, index):
    """The pose set written at `index` in the geometry's poses_sets (obstacle sets are not pose sets)."""
    return next(s for s in placed.pose_sets if s.index == index)


@pytest.mark.parametrize("name", ["Box", "Ball", "Can", "Ring"])
def test_matrix_by_dimension_keeps_every_cell(name):
    pose_set = geometry_of(synthetic(), name).pose_sets[0]
    assert len(pose_set) == 3 * 4 * 2
    assert sorted(pose_set.cells) == [(i, j, k) for i in range(3) for j in range(4) for k in range(2)]


def test_matrix_by_dimension_of_a_cube_sits_at_cell_centres():
    spec = parse_shape("cube", [3.0, 2.0, 1.5])
    positions, cells = matrix_layout(spec, PoseSetSpec("matrix", "poses", "x", matrix_dimensions=(3, 4, 2)))
    for (i, j, k), p in zip(cells, positions, strict=True):
        np.testing.assert_allclose(p, [-1.0 + i, -0.75 + 0.5 * j, -0.375 + 0.75 * k], atol=1e-12)
    one, _ = matrix_layout(spec, PoseSetSpec("matrix", "poses", "x", matrix_dimensions=(1, 1, 1)))
    np.testing.assert_allclose(one, [[0, 0, 0]])


def test_matrix_by_dimension_of_round_shapes_follows_their_axes():
    cylinder = parse_shape("cylinder", [2.0, 2.0, 3.0])
    positions, cells = matrix_layout(cylinder, PoseSetSpec("matrix", "poses", "x", matrix_dimensions=(4, 2, 3)))
    for (i, j, k), p in zip(cells, positions, strict=True):  # angle, radius, height
        angle, radius = (i + 0.5) / 4 * 2 * math.pi, (j + 0.5) / 2 * 1.0
        np.testing.assert_allclose(p, [radius * math.cos(angle), radius * math.sin(angle), (k + 0.5) - 1.5],
                                   atol=1e-12)
    torus = parse_shape("torus", [4.0, 6.0, 2.0])
    positions, cells = matrix_layout(torus, PoseSetSpec("matrix", "poses", "x", matrix_dimensions=(4, 4, 2)))
    for (i, j, k), p in zip(cells, positions, strict=True):  # ring angle, tube angle, tube radius
        ring, tube, rho = (i + 0.5) / 4 * 2 * math.pi, (j + 0.5) / 4 * 2 * math.pi, (k + 0.5) / 2 * 1.0
        np.testing.assert_allclose(math.atan2(p[1], p[0]) % (2 * math.pi), ring, atol=1e-12)
        np.testing.assert_allclose(math.hypot(math.hypot(p[0], p[1]) - 2.0, p[2]), rho, atol=1e-12)
        np.testing.assert_allclose(math.atan2(p[2], math.hypot(p[0], p[1]) - 2.0) % (2 * math.pi), tube, atol=1e-12)
    sphere = parse_shape("sphere", [2.0, 2.0, 2.0])
    positions, cells = matrix_layout(sphere, PoseSetSpec("matrix", "poses", "x", matrix_dimensions=(3, 3, 2)))
    for (_, j, k), p in zip(cells, positions, strict=True):  # azimuth, polar angle, radius
        np.testing.assert_allclose(np.linalg.norm(p), (k + 0.5) / 2, atol=1e-12)
        np.testing.assert_allclose(math.acos(p[2] / np.linalg.norm(p)), (j + 0.5) / 3 * math.pi, atol=1e-9)


@pytest.mark.parametrize("size, spacing", [
    ([3.0, 2.0, 1.5], [0.5, 0.7, 0.4]),
    ([4.0, 4.0, 4.0], [1.0, 1.0, 1.0]),
    ([0.3, 0.3, 0.3], [0.1, 0.1, 0.1]),  # 0.3 / 0.1 is 2.9999999999999996 in floating point: still 3 cells
    ([2.0, 1.0, 1.0], [2.0, 0.3, 1.0]),  # a spacing equal to the extent gives one cell, in the middle
])
def test_matrix_by_distance_in_a_cube_counts_floor_of_extent_over_spacing(size, spacing):
    spec = parse_shape("cube", size)
    positions, cells = matrix_layout(spec, PoseSetSpec("matrix", "poses", "x", matrix_type="distance",
                                                       matrix_dimensions=tuple(spacing)))
    counts = [math.floor(round(e / s, 9)) for e, s in zip(size, spacing, strict=True)]
    assert len(positions) == math.prod(counts)
    assert (cells.max(axis=0) + 1).tolist() == counts
    for axis in range(3):  # spaced as asked, centred in the cube
        values = np.unique(positions[:, axis].round(9))
        np.testing.assert_allclose(np.diff(values), spacing[axis], atol=1e-9)
        assert values.mean() == pytest.approx(0.0, abs=1e-9)


def test_matrix_by_distance_in_a_sphere_keeps_the_cells_inside():
    spec = parse_shape("sphere", [2.0, 2.0, 2.0])
    positions, cells = matrix_layout(spec, PoseSetSpec("matrix", "poses", "x", matrix_type="distance",
                                                       matrix_dimensions=(0.5, 0.5, 0.5)))
    grid = np.stack(np.meshgrid(*[np.arange(4) * 0.5 - 0.75] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = grid[np.linalg.norm(grid, axis=1) <= 1.0]
    assert len(positions) == len(inside) == 32
    assert sorted(map(tuple, positions.round(9))) == sorted(map(tuple, inside.round(9)))


def test_distance_spacing_too_wide_is_a_layout_error():
    spec = parse_shape("cylinder", [2.0, 2.0, 3.0])
    with pytest.raises(LayoutError, match=r"^dimensions\[2\]: a spacing of 4 m does not fit .* 3 m along z"):
        matrix_layout(spec, PoseSetSpec("matrix", "poses", "x", matrix_type="distance", matrix_dimensions=(1, 1, 4)))


def test_density_keeps_a_share_of_the_cells():
    data = synthetic_data()
    box = data["scenario"]["volumes"][1]["geometries"][0]
    box["poses_sets"] = [{"type": "matrix", "use": "poses", "dimensions": [10, 10, 10], "density": 0.3},
                         {"type": "matrix", "use": "poses", "dimensions": [10, 10, 10]}]
    placed = geometry_of(synthetic(data=data), "Box")
    kept, full = placed.pose_sets
    n, p = 1000, 0.3
    assert abs(len(kept) - n * p) <= 5 * math.sqrt(n * p * (1 - p))
    full_rows = {cell: full.local_positions[row] for cell, row in full.cells.items()}
    for cell, row in kept.cells.items():  # a kept cell sits where it would without the density
        np.testing.assert_allclose(kept.local_positions[row], full_rows[cell])


def test_random_and_coordinates_counts_and_values():
    resolved = synthetic()
    for name, (_, _, _, coordinates) in GEOMETRIES.items():
        placed = geometry_of(resolved, name)
        assert len(placed.pose_sets[2]) == 25
        listed = placed.pose_sets[3]
        np.testing.assert_allclose(listed.local_positions, coordinates)
        np.testing.assert_allclose(listed.local_quaternions,
                                   quaternions_from_rpy([[0, 0, 0.5 * k] for k in range(len(coordinates))]))
        # obstacles: 12 random ones, then the kept cells of the 2 x 2 x 2 matrix (density 0.8), then 4 prisms
        obstacles = placed.obstacles
        prisms = 4 if placed.geometry.spec.shape == "prism" else 0
        in_matrix = obstacles[12:len(obstacles) - prisms]
        assert 0 < len(in_matrix) <= 8
        assert [o.shape for o in obstacles[len(obstacles) - prisms:]] == ["prism"] * prisms
        cells, _ = matrix_layout(placed.geometry.spec, PoseSetSpec("matrix", "obstacles", "x",
                                                                   matrix_dimensions=(2, 2, 2)))
        for obstacle in in_matrix:
            assert np.isclose(cells, obstacle.local_position, atol=1e-12).all(axis=1).any()


def test_matrix_orientation_fixed_and_random_rotations():
    placed = geometry_of(synthetic(), "Box")
    fixed = placed.pose_sets[0]
    np.testing.assert_allclose(fixed.local_quaternions, np.tile(quaternions_from_rpy([0.1, -0.2, 0.3]), (24, 1)))
    drawn = placed.pose_sets[2]
    assert len(np.unique(drawn.local_quaternions.round(9), axis=0)) == 25
    np.testing.assert_allclose(np.linalg.norm(drawn.local_quaternions, axis=1), 1.0)


def test_obstacles_draw_shapes_and_dimensions_as_asked():
    resolved = synthetic(seed=3)
    (x_low, x_high), _, (z_low, z_high) = OBSTACLE_RANGES
    seen = set()
    for placed in resolved.geometries:
        drawn = placed.obstacles[:12]
        for obstacle in drawn:
            assert obstacle.shape in OBSTACLE_SHAPES
            seen.add(obstacle.shape)
            d = obstacle.dimensions
            assert x_low <= d[0] <= x_high
            if obstacle.shape == "cube":
                assert OBSTACLE_RANGES[1][0] <= d[1] <= OBSTACLE_RANGES[1][1] and z_low <= d[2] <= z_high
            elif obstacle.shape == "sphere":
                assert d[0] == d[1] == d[2]
            elif obstacle.shape == "cylinder":
                assert d[0] == d[1] and z_low <= d[2] <= z_high
            else:  # torus [2R, 2R + 2r, 2r]
                assert z_low <= d[2] <= z_high and d[1] == pytest.approx(d[0] + d[2])
            parse_shape(obstacle.shape, list(d))  # a valid obstacle
            rpy = Rotation.from_quat(obstacle.local_quaternion).as_euler("xyz")
            assert 0 <= rpy[0] <= 0.3 + 1e-9 and -0.2 - 1e-9 <= rpy[1] <= 0.2 + 1e-9 and -1 - 1e-9 <= rpy[2] <= 1 + 1e-9
        fixed = placed.obstacles[12:]
        for obstacle in fixed:
            if obstacle.shape == "prism":
                assert obstacle.dimensions == (0.5,) and obstacle.polygon == ((0, 0), (0.3, 0), (0, 0.2))
            else:
                assert (obstacle.shape, obstacle.dimensions) == ("sphere", (0.3, 0.3, 0.3))
                np.testing.assert_allclose(obstacle.local_quaternion, [0, 0, 0, 1])
        assert len(drawn) == 12
    assert seen == set(OBSTACLE_SHAPES)
    # the sizes really are drawn, not fixed at one end
    sizes = [o.dimensions[0] for o in resolved.obstacles() if o.shape == "cube"]
    assert len(set(sizes)) == len(sizes) > 3


def test_mixed_obstacle_shapes_share_one_fixed_size():
    data = synthetic_data()
    box = data["scenario"]["volumes"][1]["geometries"][0]
    box["poses_sets"] = [{"type": "random", "use": "obstacles", "quantity": 30,
                          "obstacles_shape": ["cube", "sphere", "cylinder"], "obstacles_dimensions": [0.3, 0.4, 0.5]}]
    obstacles = geometry_of(synthetic(data=data), "Box").obstacles
    sizes = {o.shape: o.dimensions for o in obstacles}
    assert sizes == {"cube": (0.3, 0.4, 0.5), "sphere": (0.3, 0.3, 0.3), "cylinder": (0.3, 0.3, 0.5)}
    assert len(obstacles) == 30


def test_prism_matrix_turned_by_set_orientation_yaw():
    resolved = synthetic()
    placed = geometry_of(resolved, "Ell")
    spec = placed.geometry.spec
    for pose_set, yaw, step in ((set_at(placed, 6), 0.6, None), (set_at(placed, 7), -0.9, (0.4, 0.5, 0.5))):
        assert pose_set.spec.set_yaw == yaw
        turned = pose_set.local_positions @ rz(yaw)  # into the grid's own axes
        poly = np.array(spec.polygon) @ rz(yaw)[:2, :2]
        low, high = np.append(poly.min(axis=0), 0.0), np.append(poly.max(axis=0), 1.5)
        for (i, j, k), row in pose_set.cells.items():
            if step is None:  # by dimension [5, 4, 2]: cell centres of the turned bounding box
                expected = low + (np.array([i, j, k]) + 0.5) / np.array([5, 4, 2]) * (high - low)
                np.testing.assert_allclose(turned[row], expected, atol=1e-9)
        if step is not None:  # by distance: the grid lines run along the turned axes, `step` apart
            for axis in range(3):
                values = np.unique(turned[:, axis].round(9))
                gaps = np.diff(values) / step[axis]
                np.testing.assert_allclose(gaps, gaps.round(), atol=1e-6)
        assert contains(spec, pose_set.local_positions).all()
        assert len(pose_set) < (40 if step is None else 10 ** 4)


def test_a_prism_matrix_with_no_cell_over_the_polygon_is_an_error():
    thin = parse_shape("prism", [1.0, [[0, 0], [10, 0], [10, 0.1], [1, 0.1], [1, 10], [0, 10]]])
    with pytest.raises(LayoutError, match=r"^dimensions: no cell centre"):
        matrix_layout(thin, PoseSetSpec("matrix", "poses", "x", matrix_dimensions=(2, 2, 1)))


# --- zigzag ---------------------------------------------------------------------------------------------------

def zigzag(polygon, height=2.0, spacing=(0.0, 1.5), sweep=0.0, margins=(0.5, 1.0), sense="right", tall=5.0):
    spec = parse_shape("prism", [tall, polygon])
    return spec, zigzag_layout(spec, PoseSetSpec("zigzag", "poses", "x", height=height, spacing=spacing,
                                                 sweep_angle=sweep, margins=margins, initial_sense=sense))


def lines_of(points, sweep=0.0):
    """Waypoints in the sweep frame, grouped by line (constant sweep-y), in flying order."""
    local = points[:, :2] @ rz(sweep)[:2, :2]
    lines, current = [], [local[0]]
    for p in local[1:]:
        if abs(p[1] - current[-1][1]) < 1e-9:
            current.append(p)
        else:
            lines.append(np.array(current))
            current = [p]
    lines.append(np.array(current))
    return lines


RECTANGLE = [[0, 0], [10, 0], [10, 6], [0, 6]]


def test_zigzag_over_a_rectangle_by_hand():
    # 10 x 6 m, margins [0.5, 1.0]: lines from x 0.5 to 9.5, within y 1 .. 5; 1.5 m apart that is 3 lines
    # (3 m), centred: y = 1.5, 3, 4.5
    _, points = zigzag(RECTANGLE)
    np.testing.assert_allclose(points, [[0.5, 1.5, 2], [9.5, 1.5, 2], [9.5, 3, 2], [0.5, 3, 2], [0.5, 4.5, 2],
                                        [9.5, 4.5, 2]], atol=1e-12)
    _, left = zigzag(RECTANGLE, sense="left")
    np.testing.assert_allclose(left, [[9.5, 1.5, 2], [0.5, 1.5, 2], [0.5, 3, 2], [9.5, 3, 2], [9.5, 4.5, 2],
                                      [0.5, 4.5, 2]], atol=1e-12)
    # no margins and a spacing that fits exactly: the outer lines run along the edges, still whole
    _, edges = zigzag([[0, 0], [6, 0], [6, 6], [0, 6]], height=1.0, spacing=(0.0, 2.0), margins=(0.0, 0.0))
    np.testing.assert_allclose(edges, [[0, 0, 1], [6, 0, 1], [6, 2, 1], [0, 2, 1], [0, 4, 1], [6, 4, 1], [6, 6, 1],
                                       [0, 6, 1]], atol=1e-9)
    # room for one line only: in the middle
    _, one = zigzag(RECTANGLE, spacing=(0.0, 5.0), margins=(0.5, 2.0))
    np.testing.assert_allclose(one, [[0.5, 3, 2], [9.5, 3, 2]], atol=1e-12)


@pytest.mark.parametrize("sense", ["right", "left"])
@pytest.mark.parametrize("along", [0.0, 2.0, 0.7])
def test_zigzag_lines_alternate_are_spaced_and_keep_the_margins(sense, along):
    margins, between, height = (0.5, 1.0), 1.2, 3.0
    spec, points = zigzag(RECTANGLE, height=height, spacing=(along, between), margins=margins, sense=sense)
    assert (points[:, 2] == height).all()
    assert contains(spec, points).all()
    lines = lines_of(points)
    assert len(lines) == math.floor((6 - 2 * margins[1]) / between) + 1
    ys = [line[0, 1] for line in lines]
    np.testing.assert_allclose(np.diff(ys), between)
    assert ys[0] >= margins[1] - 1e-12 and ys[-1] <= 6 - margins[1] + 1e-12  # the side margins
    assert ys[0] == pytest.approx(6 - ys[-1])  # centred across the rectangle
    for n, line in enumerate(lines):
        direction = np.sign(line[-1, 0] - line[0, 0])
        assert direction == (1 if (n % 2 == 0) == (sense == "right") else -1)
        steps = np.diff(line[:, 0]) * direction
        assert (steps > 0).all()  # monotone along the line
        if along > 0:  # every `along` m from the line's low end (in sweep x); the last gap takes the rest
            gaps = np.diff(np.sort(line[:, 0]))
            np.testing.assert_allclose(gaps[:-1], along)
            assert 0 < gaps[-1] <= along + 1e-9
        else:
            assert len(line) == 2
        # the end margins
        assert line[:, 0].min() == pytest.approx(margins[0]) and line[:, 0].max() == pytest.approx(10 - margins[0])


@pytest.mark.parametrize("sweep", [0.0, 0.35, math.pi / 2, 2.5, -1.0])
def test_sweep_angle_turns_the_lines_with_the_polygon(sweep):
    # turning the polygon and the sweep together turns the waypoints the same way
    base_spec, base = zigzag(HEXAGON, spacing=(0.5, 0.6), margins=(0.2, 0.3), sense="left")
    turned_polygon = (np.array(HEXAGON) @ rz(sweep)[:2, :2].T).tolist()
    spec, turned = zigzag(turned_polygon, spacing=(0.5, 0.6), margins=(0.2, 0.3), sweep=sweep, sense="left")
    np.testing.assert_allclose(turned, base @ rz(sweep).T, atol=1e-9)
    assert contains(spec, turned).all()
    # each line runs along the sweep direction (cos, sin), the lines 0.6 m apart across it
    lines = lines_of(turned, sweep)
    assert len(lines) == len(lines_of(base)) > 3
    np.testing.assert_allclose(np.diff([line[0, 1] for line in lines]), 0.6, atol=1e-9)


def test_sweep_angle_on_a_fixed_polygon():
    square = [[0, 0], [6, 0], [6, 6], [0, 6]]
    _, along_x = zigzag(square, spacing=(0.0, 2.0), margins=(0.0, 1.0))
    _, along_y = zigzag(square, spacing=(0.0, 2.0), margins=(0.0, 1.0), sweep=math.pi / 2)
    np.testing.assert_allclose(along_x[:2, :2], [[0, 1], [6, 1]], atol=1e-12)
    # a quarter turn: lines along +y, stacked towards -x (the sweep frame's +y), the first flown towards +y
    np.testing.assert_allclose(along_y[:2, :2], [[5, 0], [5, 6]], atol=1e-12)
    assert np.allclose(np.diff(along_y[::2, 0]), -2.0)


def test_zigzag_over_a_non_convex_polygon_stays_inside():
    spec, points = zigzag(U_SHAPE, spacing=(0.4, 0.5), margins=(0.2, 0.25), sweep=0.0)
    assert contains(spec, points).all()
    upper = points[points[:, 1] > 1.0 + 1e-9]
    assert len(upper) and not ((upper[:, 0] > 2.0) & (upper[:, 0] < 4.0)).any()  # nothing over the U's gap
    for line in lines_of(points):
        steps = np.diff(line[:, 0])
        assert (steps > 0).all() or (steps < 0).all()


def test_a_line_touching_a_vertex_stays_one_stretch():
    notch = [[0, 0], [4, 0], [4, 2], [2, 1], [0, 2]]  # the top's V reaches down to (2, 1)
    _, points = zigzag(notch, height=0.5, spacing=(0.0, 5.0), margins=(0.1, 0.9))  # one line, at y = 1
    np.testing.assert_allclose(points, [[0.1, 1, 0.5], [3.9, 1, 0.5]], atol=1e-12)


@pytest.mark.parametrize("kwargs, message", [
    ({"height": 6.0}, r"^height: the sweep plane must lie within the prism"),
    ({"margins": (0.0, 3.5)}, r"^margins\[1\]: "),
    ({"margins": (5.5, 1.0)}, r"^margins\[0\]: "),
])
def test_zigzag_errors(kwargs, message):
    with pytest.raises(LayoutError, match=message):
        zigzag(RECTANGLE, **kwargs)


def test_zigzag_in_a_world_is_a_named_path():
    resolved = synthetic()
    for volume in ("Plain", "Turned"):
        for name in ("Roof", "Ell"):
            placed = resolved.geometry(volume, name)
            paths = [s for s in placed.pose_sets if s.spec.type == "zigzag"]
            assert [s.path_name for s in paths] == ["Zigzag"]
            local = paths[0].local_positions
            assert (local[:, 2] == 0.75).all()
            lines = lines_of(local, 0.35)
            assert np.sign(lines[0][-1, 0] - lines[0][0, 0]) == -1  # initial_sense "left"
            np.testing.assert_allclose(np.diff([line[0, 1] for line in lines]), 0.4, atol=1e-9)


# --- seeds ----------------------------------------------------------------------------------------------------

def all_positions(resolved):
    return {(g.frame_name, s.index): s.positions for g in resolved.geometries for s in g.pose_sets} | {
        o.name: np.append(o.position, o.dimensions[0]) for o in resolved.obstacles()}


def test_the_same_seed_repeats_exactly_and_another_differs():
    a, b, c = all_positions(synthetic(7)), all_positions(synthetic(7)), all_positions(synthetic(8))
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    # the random sets: 25 poses each, and the first 12 obstacles of each geometry
    random_keys = [k for k in a if (isinstance(k, str) and int(k.rsplit("_", 1)[1]) < 12)
                   or (not isinstance(k, str) and len(a[k]) == 25)]
    assert random_keys
    differ = [k for k in random_keys if k in c and (a[k].shape != c[k].shape or not np.allclose(a[k], c[k]))]
    assert len(differ) == len(random_keys)
    assert json.dumps(world_record(synthetic(7))) == json.dumps(world_record(synthetic(7)))


def test_editing_one_geometry_does_not_move_the_random_poses_of_another():
    before = synthetic(5)
    data = synthetic_data()
    plain = data["scenario"]["volumes"][1]["geometries"]
    plain[0]["dimensions"] = [5.0, 5.0, 5.0]  # Box: other size
    plain[0]["poses_sets"][2]["quantity"] = 40  # and more random poses
    plain.insert(1, synthetic_geometry("Extra", "sphere", [1.0, 1.0, 1.0], [[0, 0, 0], [0, 0, 0]], [[0, 0, 0]]))
    after = synthetic(5, data)
    assert len(after.geometry("Plain", "Box").pose_sets[2]) == 40
    for name in GEOMETRIES:
        if name == "Box":
            continue
        for volume in ("Plain", "Turned"):
            old, new = before.geometry(volume, name), after.geometry(volume, name)
            for s_old, s_new in zip(old.pose_sets, new.pose_sets, strict=True):
                np.testing.assert_array_equal(s_old.positions, s_new.positions)
                np.testing.assert_array_equal(s_old.quaternions, s_new.quaternions)
            assert [(o.name, o.shape, o.dimensions) for o in old.obstacles] == [
                (o.name, o.shape, o.dimensions) for o in new.obstacles]


# --- names and frames -----------------------------------------------------------------------------------------

def test_frame_names():
    resolved = synthetic()
    for placed in resolved.geometries:
        vol, geo = placed.volume, placed.geometry
        assert placed.frame_name == f"{vol.prefix}_{geo.name}"
        base = f"{vol.prefix}_{geo.prefix}"
        assert placed.base_name == base
        matrices = 0
        listed = 0
        for pose_set in placed.pose_sets:
            if pose_set.cells is not None:
                tag = "" if matrices == 0 else f"_set{pose_set.index}"
                for (i, j, k), row in pose_set.cells.items():
                    assert pose_set.frames[row] == f"{base}{tag}_pos_{i}_{j}_{k}"
                matrices += 1
            else:
                assert pose_set.frames == [f"{base}_pos_{listed + n}" for n in range(len(pose_set))]
                listed += len(pose_set)
        assert [o.name for o in placed.obstacles] == [f"{base}_obs_{n}" for n in range(len(placed.obstacles))]


def test_static_transforms_are_unique_parents_first_and_compose_to_the_map_poses():
    resolved = synthetic()
    transforms = resolved.static_transforms()
    children = [child for _, child, _ in transforms]
    assert len(children) == len(set(children))
    known = {"map"}
    for parent, child, _ in transforms:
        assert parent in known, f"{child} listed before its parent {parent}"
        known.add(child)
    frames = {child: (parent, frame) for parent, child, frame in transforms}

    def to_map(name):
        parent, frame = frames[name]
        return frame if parent == "map" else to_map(parent).compose(frame)

    for placed in resolved.geometries:
        for pose_set in placed.pose_sets:
            for name, position, quaternion in zip(pose_set.frames, pose_set.positions, pose_set.quaternions,
                                                  strict=True):
                chained = to_map(name)
                np.testing.assert_allclose(chained.translation, position, atol=1e-9)
                np.testing.assert_allclose(chained.rotation, Rotation.from_quat(quaternion).as_matrix(), atol=1e-9)
        for obstacle in placed.obstacles:
            np.testing.assert_allclose(to_map(obstacle.name).translation, obstacle.position, atol=1e-9)
    expected = len(resolved.world.volumes) + len(resolved.geometries) + resolved.pose_count() + len(
        resolved.obstacles())
    assert len(transforms) == expected


def test_colliding_frame_names_are_refused():
    data = synthetic_data()
    data["scenario"]["volumes"][1]["prefix"] = "T"  # both volumes now publish T_Box, ...
    with pytest.raises(WorldError) as err:
        synthetic(data=data)
    assert str(err.value).startswith("synthetic.json: scenario.volumes[1].geometries[0].name: frame 'T_Box' would be "
                                     "published twice (under Turned and Plain)")


def small_world(*volumes):
    def geometry(name, prefix, poses=False):
        sets = [{"type": "random", "quantity": 2}] if poses else []
        return {"name": name, "prefix": prefix, "shape": "cube", "origin": [[0, 0, 0], [0, 0, 0]],
                "dimensions": [1, 1, 1], "poses_sets": sets}

    return world_from_data({"scenario": {"world_boundaries": [[0, 1], [0, 1], [0, 1]], "volumes": [
        {"name": name, "prefix": prefix, "origin": [[0, 0, 0], [0, 0, 0]],
         "geometries": [geometry(*g) for g in geometries]} for name, prefix, geometries in volumes]}}, "small.json")


@pytest.mark.parametrize("volumes, path, frame", [
    # the second geometry of the second volume publishes A_B_C again: its name is at fault, not its neighbour's
    ([("A", "A", [("B_C", "p")]), ("Q", "A_B", [("K", "k"), ("C", "c")])],
     "scenario.volumes[1].geometries[1].name", "A_B_C"),
    ([("A", "A", [("G", "g"), ("H", "h")]), ("Q", "A", [("K", "k"), ("H", "q")])],
     "scenario.volumes[1].geometries[1].name", "A_H"),
    # pose frames {volPrefix}_{geomPrefix}_pos_{n}: the prefix of the geometry holding the second copy
    ([("A", "A", [("G", "x", True)]), ("Q", "A", [("K", "k"), ("L", "x", True)])],
     "scenario.volumes[1].geometries[1].prefix", "A_x_pos_0"),
])
def test_a_frame_collision_names_the_geometry_at_fault(volumes, path, frame):
    with pytest.raises(WorldError) as err:
        resolve_world(small_world(*volumes))
    assert str(err.value).startswith(f"small.json: {path}: frame {frame!r} would be published twice"), str(err.value)


def test_corpus_frame_names_follow_the_original():
    resolved = resolve_world(load_world(CORPUS_WORLDS / "Delivery" / "Delivery.json", search_path=[]), seed=0)
    children = [child for _, child, _ in resolved.static_transforms()]
    assert children[:5] == ["Ground_Station", "Obstacles_1", "Delivery_1", "Obstacles_2", "Delivery_2"]
    assert {"GS_Limits", "GS_Agents_take_off", "GS_takeoff_pos_0_0_0", "GS_takeoff_pos_1_0_0", "GS_aTO_pos_1_0_0",
            "O1_Obstacles", "O1_del_obs_0", "D1_Recipient", "D1_rec_obs_0", "D2_del_pos_0_0_0"} <= set(children)
    recipient = resolved.obstacles()[1]
    assert (recipient.name, recipient.shape, recipient.dimensions) == ("D1_rec_obs_0", "cube", (1.0, 1.0, 1.5))
    np.testing.assert_allclose(recipient.position, [0, 15, 0.75])


# --- corpus poses by hand -------------------------------------------------------------------------------------

def test_take_off_poses_of_gym_empty_by_hand():
    # Gym/Empty.json: Ground_Station/Agents_take_off, a 4 x 0.1 x 0.1 m cube at z 0.05, matrix [2, 1, 1]:
    # cell centres at x = (0.5 / 2 - 1/2) * 4 = -1 and +1; orientation rpy [0, 1.25, 1.5]
    resolved = resolve_world(load_world(CORPUS_WORLDS / "Gym" / "Empty.json", search_path=[]), seed=0)
    pose_set = resolved.geometry("Ground_Station", "Agents_take_off").pose_sets[0]
    assert pose_set.frames == ["GS4_takeoff_pos_0_0_0", "GS4_takeoff_pos_1_0_0"]
    np.testing.assert_allclose(pose_set.positions, [[-1.0, 0.0, 0.05], [1.0, 0.0, 0.05]], atol=1e-12)
    for q in pose_set.quaternions:
        np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), rz(1.5) @ ry(1.25), atol=1e-12)


def test_take_off_poses_of_empty_4_cylinders_by_hand():
    # Gym/Empty_4_Cylinders.json has matrix [3, 1, 1] over the same 4 m cube: x = -4/3, 0, +4/3
    resolved = resolve_world(load_world(CORPUS_WORLDS / "Gym" / "Empty_4_Cylinders.json", search_path=[]), seed=0)
    pose_set = resolved.geometry("Ground_Station", "Agents_take_off").pose_sets[0]
    rows = [pose_set.cells[(i, 0, 0)] for i in range(3)]
    np.testing.assert_allclose(pose_set.positions[rows], [[-4 / 3, 0, 0.05], [0, 0, 0.05], [4 / 3, 0, 0.05]],
                               atol=1e-12)
    # and Empty/Empty.json shifts the same cube to x = -400
    empty = resolve_world(load_world(CORPUS_WORLDS / "Empty" / "Empty.json", search_path=[]), seed=0)
    np.testing.assert_allclose(empty.geometry("Ground_Station", "Agents_take_off").pose_sets[0].positions[:, 0],
                               [-400 - 4 / 3, -400, -400 + 4 / 3], atol=1e-9)


def test_delivery_random_obstacle_density_and_names():
    resolved = resolve_world(load_world(CORPUS_WORLDS / "Delivery" / "Delivery.json", search_path=[]), seed=0)
    dense = resolved.geometry("Obstacles_2", "Obstacles").obstacles
    names = [o.name for o in dense]
    assert names == [f"O2_del_obs_{n}" for n in range(len(dense))]
    assert all(re.fullmatch(r"O2_del_obs_\d+", n) for n in names)
    counts = [len(resolve_world(resolved.world, seed).geometry("Obstacles_2", "Obstacles").obstacles)
              for seed in range(40)]
    assert all(0 <= c <= 12 for c in counts)
    assert 40 * 12 * 0.3 - 5 * math.sqrt(40 * 12 * 0.21) <= sum(counts) <= 40 * 12 * 0.3 + 5 * math.sqrt(40 * 12 * 0.21)


def boundary_world(z_of_geometry):
    return {"scenario": {"world_boundaries": [[-5, 5], [-5, 5], [0, 10]], "volumes": [
        {"name": "V", "prefix": "v", "origin": [[0, 0, 0], [0, 0, 0]], "geometries": [
            {"name": "G", "prefix": "g", "shape": "cube", "origin": [[0, 0, z_of_geometry], [0, 0, 0]],
             "dimensions": [2, 2, 2], "poses_sets": [{"type": "matrix", "dimensions": [2, 1, 1]}]}]}]}}


def test_poses_outside_the_world_boundaries_are_kept_with_a_warning_and_refused_when_strict():
    inside = resolve_world(world_from_data(boundary_world(5.0), "inside.json"))
    assert inside.pose_count() == 2 and inside.warnings == []
    outside = resolve_world(world_from_data(boundary_world(12.0), "outside.json"))
    assert outside.pose_count() == 2 and len(outside.warnings) == 1
    assert outside.warnings[0].startswith("outside.json: scenario.volumes[0].geometries[0].poses_sets[0]: puts 2 of "
                                          "its 2 poses outside scenario.world_boundaries [[-5, 5], [-5, 5], [0, 10]]")
    assert "they are kept (the original did not check)" in outside.warnings[0]
    with pytest.raises(WorldError) as err:
        resolve_world(world_from_data(boundary_world(12.0), "outside.json"), strict=True)
    assert err.value.path == "scenario.volumes[0].geometries[0].poses_sets[0]"
    assert str(err.value).endswith("(refused with --strict)")
