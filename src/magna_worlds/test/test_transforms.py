"""magna_worlds.transforms: frames compose and invert, roll-pitch-yaw about fixed x-y-z, quaternions [x, y, z, w]."""
import math

import numpy as np
import pytest

from magna_worlds.transforms import Frame, quaternions_from_rpy, rotate_quaternions, rotation_from_rpy
from tests.rotations import rx, ry, rz


def quat_to_matrix(q):
    """[x, y, z, w] -> rotation matrix, written out (Hamilton convention)."""
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


RPYS = [(0.0, 0.0, 0.0), (0.3, 0.0, 0.0), (0.0, -0.7, 0.0), (0.0, 0.0, 2.0), (0.1, 0.2, 0.3), (-1.2, 0.9, -2.8),
        (0.0, 1.25, 1.5)]


@pytest.mark.parametrize("rpy", RPYS)
def test_rpy_is_fixed_axes_xyz(rpy):
    r, p, y = rpy
    expected = rz(y) @ ry(p) @ rx(r)
    np.testing.assert_allclose(rotation_from_rpy(rpy), expected, atol=1e-12)
    np.testing.assert_allclose(Frame.from_xyz_rpy([0, 0, 0], rpy).rotation, expected, atol=1e-12)


def test_single_axis_turns_by_hand():
    # yaw 90 deg sends x to y; pitch 90 deg sends x to -z; roll 90 deg sends y to z
    np.testing.assert_allclose(Frame.from_xyz_rpy([0, 0, 0], [0, 0, math.pi / 2]).apply([[1, 0, 0]]), [[0, 1, 0]],
                               atol=1e-12)
    np.testing.assert_allclose(Frame.from_xyz_rpy([0, 0, 0], [0, math.pi / 2, 0]).apply([[1, 0, 0]]), [[0, 0, -1]],
                               atol=1e-12)
    np.testing.assert_allclose(Frame.from_xyz_rpy([0, 0, 0], [math.pi / 2, 0, 0]).apply([[0, 1, 0]]), [[0, 0, 1]],
                               atol=1e-12)
    # roll first, then yaw, about the fixed axes: y -roll-> z -yaw-> z
    np.testing.assert_allclose(Frame.from_xyz_rpy([0, 0, 0], [math.pi / 2, 0, math.pi / 2]).apply([[0, 1, 0]]),
                               [[0, 0, 1]], atol=1e-12)


@pytest.mark.parametrize("rpy", RPYS)
def test_quaternion_order_is_xyzw(rpy):
    q = quaternions_from_rpy(rpy)
    assert q.shape == (1, 4)
    np.testing.assert_allclose(np.linalg.norm(q[0]), 1.0)
    r, p, y = rpy
    np.testing.assert_allclose(quat_to_matrix(q[0]), rz(y) @ ry(p) @ rx(r), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(Frame.from_xyz_rpy([1, 2, 3], rpy).quaternion()), rz(y) @ ry(p) @ rx(r),
                               atol=1e-12)


def test_known_quaternions():
    half = math.sqrt(0.5)
    np.testing.assert_allclose(quaternions_from_rpy([0, 0, 0])[0], [0, 0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(quaternions_from_rpy([0, 0, math.pi / 2])[0], [0, 0, half, half], atol=1e-12)
    np.testing.assert_allclose(quaternions_from_rpy([math.pi / 2, 0, 0])[0], [half, 0, 0, half], atol=1e-12)
    np.testing.assert_allclose(quaternions_from_rpy([0, math.pi / 2, 0])[0], [0, half, 0, half], atol=1e-12)
    frame = Frame.from_xyz_quaternion([1, 2, 3], [0, 0, half, half])
    np.testing.assert_allclose(frame.rotation, rz(math.pi / 2), atol=1e-12)
    np.testing.assert_allclose(frame.rpy(), [0, 0, math.pi / 2], atol=1e-12)


def test_many_rpy_rows_at_once():
    rows = np.array(RPYS)
    q = quaternions_from_rpy(rows)
    assert q.shape == (len(RPYS), 4)
    for row, quat in zip(rows, q, strict=True):
        np.testing.assert_allclose(quat_to_matrix(quat), rz(row[2]) @ ry(row[1]) @ rx(row[0]), atol=1e-12)


@pytest.mark.parametrize("rpy", [(0.1, 0.2, 0.3), (-1.2, 0.9, -2.8), (0.0, -0.4, 3.0)])
def test_rpy_round_trip(rpy):
    np.testing.assert_allclose(Frame.from_xyz_rpy([0, 0, 0], rpy).rpy(), rpy, atol=1e-12)


def test_apply_is_rotation_then_translation():
    frame = Frame.from_xyz_rpy([1.0, -2.0, 0.5], [0.0, 0.0, math.pi / 2])
    np.testing.assert_allclose(frame.apply([[1, 0, 0], [0, 0, 0], [0, 1, 2]]),
                               [[1.0, -1.0, 0.5], [1.0, -2.0, 0.5], [0.0, -2.0, 2.5]], atol=1e-12)
    assert frame.apply([2, 0, 0]).shape == (3,)


def random_frame(rng):
    return Frame.from_xyz_rpy(rng.uniform(-5, 5, 3), rng.uniform(-math.pi, math.pi, 3))


def test_compose_inverse_apply_round_trips():
    rng = np.random.default_rng(3)
    points = rng.uniform(-3, 3, (20, 3))
    for _ in range(20):
        a, b, c = random_frame(rng), random_frame(rng), random_frame(rng)
        # composing is applying one after the other
        np.testing.assert_allclose(a.compose(b).apply(points), a.apply(b.apply(points)), atol=1e-12)
        # associativity
        left, right = a.compose(b).compose(c), a.compose(b.compose(c))
        np.testing.assert_allclose(left.rotation, right.rotation, atol=1e-12)
        np.testing.assert_allclose(left.translation, right.translation, atol=1e-12)
        # the inverse undoes the frame, on either side
        np.testing.assert_allclose(a.inverse().apply(a.apply(points)), points, atol=1e-12)
        np.testing.assert_allclose(a.apply(a.inverse().apply(points)), points, atol=1e-12)
        for identity in (a.compose(a.inverse()), a.inverse().compose(a)):
            np.testing.assert_allclose(identity.rotation, np.eye(3), atol=1e-12)
            np.testing.assert_allclose(identity.translation, np.zeros(3), atol=1e-12)
        # (ab)^-1 = b^-1 a^-1
        np.testing.assert_allclose(a.compose(b).inverse().apply(points), b.inverse().compose(a.inverse()).apply(points),
                                   atol=1e-12)
        # the rotation stays orthonormal and proper
        np.testing.assert_allclose(left.rotation @ left.rotation.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(left.rotation) == pytest.approx(1.0)


def test_compose_by_hand():
    parent = Frame.from_xyz_rpy([10, 0, 0], [0, 0, math.pi / 2])
    child = Frame.from_xyz_rpy([1, 0, 0], [0, 0, math.pi / 2])
    both = parent.compose(child)
    np.testing.assert_allclose(both.translation, [10, 1, 0], atol=1e-12)
    np.testing.assert_allclose(both.rotation, rz(math.pi), atol=1e-12)
    np.testing.assert_allclose(Frame.identity().compose(child).translation, child.translation)
    np.testing.assert_allclose(parent.inverse().translation, [0, 10, 0], atol=1e-12)


def test_rotate_quaternions_expresses_orientations_in_the_parent():
    rng = np.random.default_rng(4)
    frame = random_frame(rng)
    local = quaternions_from_rpy(rng.uniform(-math.pi, math.pi, (5, 3)))
    turned = rotate_quaternions(frame.rotation, local)
    assert turned.shape == (5, 4)
    for q_local, q_map in zip(local, turned, strict=True):
        np.testing.assert_allclose(quat_to_matrix(q_map), frame.rotation @ quat_to_matrix(q_local), atol=1e-12)
        # the same as composing frames
        composed = frame.compose(Frame.from_xyz_quaternion([0, 0, 0], q_local))
        np.testing.assert_allclose(composed.rotation, quat_to_matrix(q_map), atol=1e-12)
