"""magna_worlds.shapes: inside tests, uniform sampling, volumes and bounds of the five solids, and prism checks."""
import math

import numpy as np
import pytest

from magna_worlds.shapes import (
    SHAPES,
    ShapeError,
    contains,
    half_extents,
    parse_shape,
    sample_uniform,
    solid_volume,
    triangulate,
)

# A non-convex L: the 4 x 1 foot along x and the 1 x 3 leg along y; the notch is x > 1, y > 1.
L_POLYGON = [[0, 0, 0], [4, 0, 0], [4, 1, 0], [1, 1, 0], [1, 3, 0], [0, 3, 0]]
L_AREA = 4.0 + 2.0
# A convex pentagon (the house): square 2 x 2 and a roof up to (1, 3).
HOUSE_POLYGON = [[0, 0], [2, 0], [2, 2], [1, 3], [0, 2]]
HOUSE_AREA = 4.0 + 1.0

SPECS = {
    "cube": parse_shape("cube", [2.0, 3.0, 4.0]),
    "sphere": parse_shape("sphere", [3.0, 3.0, 3.0]),
    "cylinder": parse_shape("cylinder", [2.0, 2.0, 5.0]),
    "torus": parse_shape("torus", [6.0, 9.0, 3.0]),  # R = 3, r = 1.5, as Gym/1Obs_Central_Cylinder.json
    "prism": parse_shape("prism", [2.0, L_POLYGON]),
}
N = 40000  # samples for the statistical checks


def within_binomial(hits: int, n: int, p: float, sigmas: float = 5.0) -> None:
    """The observed share of `hits` in `n` draws matches probability `p` within `sigmas` binomial deviations."""
    sd = math.sqrt(p * (1.0 - p) / n)
    share = hits / n
    assert abs(share - p) <= sigmas * sd, f"share {share:.5f}, expected {p:.5f} +- {sigmas * sd:.5f}"


def inside(spec, point) -> bool:
    return bool(contains(spec, [point])[0])


# --- contains ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("point, expected", [
    ([0, 0, 0], True), ([0.99, 1.49, 1.99], True), ([-0.99, -1.49, -1.99], True),
    ([1.0, 1.5, 2.0], True),  # corner: boundary counts as inside
    ([1.0, 0, 0], True), ([0, 0, -2.0], True),
    ([1.01, 0, 0], False), ([0, 1.51, 0], False), ([0, 0, 2.01], False), ([0, 0, -2.01], False),
])
def test_cube_contains(point, expected):
    assert inside(SPECS["cube"], point) is expected


@pytest.mark.parametrize("point, expected", [
    ([0, 0, 0], True), ([1.5, 0, 0], True), ([0, 0, -1.5], True),
    ([1.5 / math.sqrt(3)] * 3, True),  # on the surface along the diagonal
    ([1.0, 1.0, 0.5], True),  # |p| = 1.5
    ([1.0, 1.0, 1.0], False),  # inside the bounding box, outside the ball
    ([1.51, 0, 0], False), ([0, 0, 1.51], False),
])
def test_sphere_contains(point, expected):
    assert inside(SPECS["sphere"], point) is expected


@pytest.mark.parametrize("point, expected", [
    ([0, 0, 0], True), ([1.0, 0, 0], True), ([0, 0, 2.5], True), ([0, 0, -2.5], True),
    ([math.sqrt(0.5), math.sqrt(0.5), 2.5], True),  # rim
    ([0.8, 0.8, 0], False),  # inside the bounding box's corner, outside the disc
    ([1.01, 0, 0], False), ([0, 0, 2.51], False), ([0.5, 0.5, -2.6], False),
])
def test_cylinder_contains(point, expected):
    assert inside(SPECS["cylinder"], point) is expected


@pytest.mark.parametrize("point, expected", [
    ([0, 0, 0], False),  # the hole
    ([1.0, 0, 0], False), ([0, -1.4, 0], False),  # still in the hole
    ([1.5, 0, 0], True), ([0, -1.5, 0], True),  # inner equator
    ([3.0, 0, 0], True), ([0, 3.0, 0], True), ([-3 / math.sqrt(2), -3 / math.sqrt(2), 1.0], True),  # centre line
    ([4.5, 0, 0], True), ([4.6, 0, 0], False),  # outer equator, then outside
    ([3.0, 0, 1.5], True), ([3.0, 0, 1.51], False),  # top of the tube
    ([4.4, 0, 1.0], False),  # inside the bounding box, outside the tube
    ([3.0 * math.cos(1.0), 3.0 * math.sin(1.0), -1.49], True),
    ([0, 0, 1.5], False),
])
def test_torus_contains(point, expected):
    assert inside(SPECS["torus"], point) is expected


@pytest.mark.parametrize("point, expected", [
    ([0.5, 0.5, 1.0], True), ([3.5, 0.5, 1.0], True), ([0.5, 2.5, 1.0], True),
    ([2.0, 2.0, 1.0], False), ([3.5, 2.5, 1.0], False),  # the notch of the L
    ([1.0, 2.0, 1.0], True), ([2.0, 1.0, 1.0], True),  # on the notch's edges
    ([1.0, 1.0, 0.0], True), ([0, 0, 0], True), ([4, 1, 2], True),  # reflex corner, base corner, top corner
    ([0.5, 0.5, 2.01], False),  # above the height
    ([0.5, 0.5, -0.01], False),  # below the base (the base lies at z = 0, the prism is not centred)
    ([-0.01, 0.5, 1.0], False), ([4.01, 0.5, 1.0], False), ([0.5, 3.01, 1.0], False),
])
def test_prism_contains(point, expected):
    assert inside(SPECS["prism"], point) is expected


def test_contains_is_vectorised_and_tolerance_widens_the_boundary():
    cube = SPECS["cube"]
    points = np.array([[0, 0, 0], [1.0 + 1e-6, 0, 0], [5, 5, 5]])
    assert contains(cube, points).tolist() == [True, False, False]
    assert contains(cube, points, tolerance=1e-5).tolist() == [True, True, False]


# --- sampling ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("shape", SHAPES)
def test_every_sample_lies_inside(shape):
    spec = SPECS[shape]
    points = sample_uniform(spec, 5000, np.random.default_rng(11))
    assert points.shape == (5000, 3)
    assert contains(spec, points).all()
    low, high = half_extents(spec)
    assert (points >= low - 1e-12).all() and (points <= high + 1e-12).all()


@pytest.mark.parametrize("shape", SHAPES)
def test_no_samples_is_an_empty_array(shape):
    assert sample_uniform(SPECS[shape], 0, np.random.default_rng(0)).shape == (0, 3)


@pytest.mark.parametrize("shape", SHAPES)
def test_sampling_repeats_for_a_seed(shape):
    spec = SPECS[shape]
    a = sample_uniform(spec, 100, np.random.default_rng(5))
    b = sample_uniform(spec, 100, np.random.default_rng(5))
    c = sample_uniform(spec, 100, np.random.default_rng(6))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_cube_samples_are_uniform():
    points = sample_uniform(SPECS["cube"], N, np.random.default_rng(1))
    # the box [-1, 0] x [-1.5, 1.5] x [1, 2] holds 1/2 * 1 * 1/4 of the cube
    hits = np.sum((points[:, 0] < 0) & (points[:, 2] > 1.0))
    within_binomial(int(hits), N, 1 / 8)


def test_sphere_samples_are_uniform():
    radius = 1.5
    points = sample_uniform(SPECS["sphere"], N, np.random.default_rng(2))
    r = np.linalg.norm(points, axis=1)
    within_binomial(int(np.sum(r < radius / 2)), N, 1 / 8)  # (1/2)^3
    within_binomial(int(np.sum(points[:, 2] > 0)), N, 1 / 2)
    # the polar cap z > R/2 holds pi h^2 (3R - h) / 3 with h = R/2, over 4/3 pi R^3: 5/32
    within_binomial(int(np.sum(points[:, 2] > radius / 2)), N, 5 / 32)


def test_cylinder_samples_are_uniform():
    points = sample_uniform(SPECS["cylinder"], N, np.random.default_rng(3))
    rho = np.hypot(points[:, 0], points[:, 1])
    within_binomial(int(np.sum(rho < 0.5)), N, 1 / 4)  # (1/2)^2
    within_binomial(int(np.sum(points[:, 2] > 1.5)), N, 1 / 5)  # z in (1.5, 2.5] of [-2.5, 2.5]
    within_binomial(int(np.sum(points[:, 0] > 0)), N, 1 / 2)


def test_torus_samples_are_uniform():
    # Pappus: a part of the tube's cross-section with area A and centroid at distance c from the axis sweeps
    # 2 pi c A. The inner half disc (distance from the axis < R) has A = pi r^2 / 2 and c = R - 4r/(3 pi),
    # the whole disc pi r^2 at R: share = (R - 4r/(3 pi)) / (2R) = 1/2 - 2r/(3 pi R).
    big, small = 3.0, 1.5
    inner_share = 0.5 - 2 * small / (3 * math.pi * big)
    assert inner_share == pytest.approx(0.5 - 1 / (3 * math.pi))
    points = sample_uniform(SPECS["torus"], N, np.random.default_rng(4))
    rho = np.hypot(points[:, 0], points[:, 1])
    within_binomial(int(np.sum(rho < big)), N, inner_share)
    # the upper half of the tube holds half of the torus, and any quarter of the ring a quarter
    within_binomial(int(np.sum(points[:, 2] > 0)), N, 1 / 2)
    within_binomial(int(np.sum((points[:, 0] > 0) & (points[:, 1] > 0))), N, 1 / 4)


def test_torus_inner_share_by_numerical_integration():
    # The same share by integrating the swept area directly (the Pappus formula above, checked independently).
    big, small = 3.0, 1.5
    s = np.linspace(big - small, big + small, 200001)
    chord = 2.0 * np.sqrt(np.clip(small ** 2 - (s - big) ** 2, 0.0, None))  # tube height at distance s
    ring = 2.0 * math.pi * s * chord
    inner = np.trapezoid(np.where(s < big, ring, 0.0), s)
    assert inner / np.trapezoid(ring, s) == pytest.approx(0.5 - 2 * small / (3 * math.pi * big), abs=1e-4)


def test_non_convex_prism_samples_are_uniform():
    points = sample_uniform(SPECS["prism"], N, np.random.default_rng(5))
    within_binomial(int(np.sum(points[:, 0] < 1.0)), N, 3.0 / L_AREA)  # the leg's column x < 1: 1 x 3
    within_binomial(int(np.sum(points[:, 1] > 1.0)), N, 2.0 / L_AREA)  # the leg above the foot: 1 x 2
    within_binomial(int(np.sum(points[:, 2] < 0.5)), N, 0.5 / 2.0)  # height 2
    notch = (points[:, 0] > 1.0) & (points[:, 1] > 1.0)
    assert not notch.any()


def test_convex_prism_samples_fill_a_triangle_by_its_area_share():
    spec = parse_shape("prism", [1.0], vertices=HOUSE_POLYGON)
    points = sample_uniform(spec, N, np.random.default_rng(6))
    # the roof triangle (0, 2), (2, 2), (1, 3) has area 1
    roof = points[:, 1] > 2.0
    within_binomial(int(np.sum(roof)), N, 1.0 / HOUSE_AREA)
    # the triangle (0, 0), (2, 0), (2, 2) (below the diagonal y = x) has area 2
    within_binomial(int(np.sum(points[:, 1] < points[:, 0])), N, 2.0 / HOUSE_AREA)


# --- volume and bounds ------------------------------------------------------------------------------------------

def test_solid_volume_formulas():
    assert solid_volume(SPECS["cube"]) == pytest.approx(24.0)
    assert solid_volume(SPECS["sphere"]) == pytest.approx(4 / 3 * math.pi * 1.5 ** 3)
    assert solid_volume(SPECS["cylinder"]) == pytest.approx(math.pi * 1.0 ** 2 * 5.0)
    assert solid_volume(SPECS["torus"]) == pytest.approx(2 * math.pi ** 2 * 3.0 * 1.5 ** 2)
    assert solid_volume(SPECS["prism"]) == pytest.approx(L_AREA * 2.0)


@pytest.mark.parametrize("shape", SHAPES)
def test_solid_volume_matches_monte_carlo(shape):
    spec = SPECS[shape]
    low, high = half_extents(spec)
    rng = np.random.default_rng(7)
    points = low + rng.random((N, 3)) * (high - low)
    box = float(np.prod(high - low))
    share = solid_volume(spec) / box
    within_binomial(int(contains(spec, points).sum()), N, share)


def test_half_extents():
    def bounds(spec):
        low, high = half_extents(spec)
        return low.tolist(), high.tolist()

    assert bounds(SPECS["cube"]) == ([-1.0, -1.5, -2.0], [1.0, 1.5, 2.0])
    assert bounds(SPECS["sphere"]) == ([-1.5, -1.5, -1.5], [1.5, 1.5, 1.5])
    assert bounds(SPECS["cylinder"]) == ([-1.0, -1.0, -2.5], [1.0, 1.0, 2.5])
    assert bounds(SPECS["torus"]) == ([-4.5, -4.5, -1.5], [4.5, 4.5, 1.5])
    assert bounds(SPECS["prism"]) == ([0.0, 0.0, 0.0], [4.0, 3.0, 2.0])
    shifted = parse_shape("prism", [3.0, [[-2, 1], [5, 1], [5, 4]]])
    assert bounds(shifted) == ([-2.0, 1.0, 0.0], [5.0, 4.0, 3.0])


# --- parse_shape ----------------------------------------------------------------------------------------------

def test_prism_polygon_is_stored_counter_clockwise_and_ignores_z():
    clockwise = parse_shape("prism", [1.0, [[0, 0, 7], [0, 1, 7], [1, 1, 7], [1, 0, 7]]])
    assert clockwise.polygon == ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0))
    assert not SPECS["prism"].convex and parse_shape("prism", [1.0], vertices=HOUSE_POLYGON).convex
    assert not SPECS["torus"].convex and SPECS["cube"].convex


def test_prism_closed_by_repeating_its_first_vertex():
    spec = parse_shape("prism", [1.0, [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]]])
    assert len(spec.polygon) == 4


@pytest.mark.parametrize("vertices", [[], [[0, 0, 0]], [[0, 0, 0], [1, 0, 0]]])
def test_prism_needs_three_vertices(vertices):
    with pytest.raises(ShapeError, match=r"^dimensions\[1\]: .*3 or more base vertices"):
        parse_shape("prism", [1.0, vertices])
    with pytest.raises(ShapeError, match=r"^vertices: .*3 or more base vertices"):
        parse_shape("prism", [1.0], vertices=vertices)


def test_two_vertices_closed_are_not_a_triangle():
    with pytest.raises(ShapeError, match=r"^dimensions\[1\]\[2\]: repeats vertex 0"):
        parse_shape("prism", [1.0, [[0, 0], [1, 0], [0, 0]]])
    closed_triangle = parse_shape("prism", [1.0, [[0, 0], [1, 0], [0, 1], [0, 0]]])
    assert len(closed_triangle.polygon) == 3


def test_prism_with_crossing_edges_is_refused():
    bow_tie = [[0, 0], [1, 1], [1, 0], [0, 1]]
    with pytest.raises(ShapeError, match=r"^dimensions\[1\]: the polygon's edges 0 and 2 cross"):
        parse_shape("prism", [1.0, bow_tie])
    with pytest.raises(ShapeError, match=r"^vertices: the polygon's edges"):
        parse_shape("prism", [1.0], vertices=bow_tie)


@pytest.mark.parametrize("shape, dimensions, vertices, message", [
    ("prism", [1.0, [[0, 0], [1, 0], [2, 0]]], None, r"^dimensions\[1\]: the base polygon has no area"),
    ("prism", [1.0, [[0, 0], [1, 0], [1, 1], [1, 0]]], None, r"^dimensions\[1\]\[3\]: repeats vertex 1"),
    ("prism", [1.0], None, r"^vertices: missing"),
    ("prism", [1.0, [[0, 0], [1, 0], [1, 1]]], [[0, 0], [1, 0], [1, 1]], r"^vertices: given twice"),
    ("prism", [-1.0, [[0, 0], [1, 0], [1, 1]]], None, r"^dimensions\[0\]: must be positive"),
    ("prism", [1.0, [[0, 0], [1, 0], [1]]], None, r"^dimensions\[1\]\[2\]: a vertex is \[x, y\]"),
    ("ellipsoid", [1, 1, 1], None, r"^shape: unknown shape 'ellipsoid'"),
    ("cube", [1, 1], None, r"^dimensions: a cube needs"),
    ("cube", [1, 0, 1], None, r"^dimensions\[1\]: must be positive"),
    ("cube", [1, "2", 1], None, r"^dimensions\[1\]: expected a finite number"),
    ("cube", "1 1 1", None, r"^dimensions: expected a list"),
    ("sphere", [1, 2, 1], None, r"^dimensions: .*ellipsoids are not supported"),
    ("cylinder", [1, 2, 1], None, r"^dimensions: .*elliptic cylinders are not supported"),
    ("torus", [6, 8, 3], None, r"^dimensions\[1\]: .*outer diameter must be 6.0 \+ 3.0 = 9.0"),
    ("torus", [2, 5, 3], None, r"^dimensions\[2\]: .*must not exceed"),
    ("cube", [1, 1, 1], [[0, 0], [1, 0], [1, 1]], r"^vertices: only a prism has vertices"),
])
def test_parse_shape_errors_name_the_field(shape, dimensions, vertices, message):
    with pytest.raises(ShapeError, match=message):
        parse_shape(shape, dimensions, vertices)


def test_triangulation_of_a_non_convex_polygon_covers_its_area():
    spec = SPECS["prism"]
    poly = np.array(spec.polygon)
    triangles = poly[triangulate(poly)]
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    assert len(triangles) == len(poly) - 2
    assert (cross > 0).all()  # counter-clockwise, none degenerate
    assert 0.5 * cross.sum() == pytest.approx(L_AREA)
    centroids = np.column_stack([triangles.mean(axis=1), np.full(len(triangles), 1.0)])
    assert contains(spec, centroids).all()  # no triangle covers the notch
