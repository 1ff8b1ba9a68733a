"""Frame helpers of the UAL server (no master needed)."""
import math

import numpy as np
import pytest

from magna_sim.ros_ual import rotate_into_body


def rotation_matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_a_heading_velocity_is_forward_in_the_body_frame():
    yaw = 0.7
    q = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    assert rotate_into_body(q, (math.cos(yaw), math.sin(yaw), 0.3)) == pytest.approx((1.0, 0.0, 0.3))


def test_matches_the_transposed_rotation_matrix():
    rng = np.random.default_rng(4)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        v = rng.normal(size=3)
        assert rotate_into_body(q, v) == pytest.approx(rotation_matrix(q).T @ v)
