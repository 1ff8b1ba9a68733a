"""The depth camera: metric z-depth, axes and image orientation, empty space, near clipping."""
import math

import numpy as np
import pybullet as p
import pytest

from magna_common.airframes import load_airframe
from magna_sim.bodies import create_uav_body
from magna_sim.depth_camera import DepthCamera

LEVEL = (0.0, 0.0, 0.0, 1.0)


@pytest.fixture
def client():
    cid = p.connect(p.DIRECT)
    yield cid
    p.disconnect(cid)


def box(client, size, position, orientation=LEVEL):
    """A static box with a visual shape: what the renderer draws."""
    half = [s / 2.0 for s in size]
    collision = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
    visual = p.createVisualShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
    return p.createMultiBody(0.0, collision, visual, basePosition=position, baseOrientation=orientation,
                             physicsClientId=client)


def yaw(angle):
    return p.getQuaternionFromEuler([0.0, 0.0, angle])


def centre(image):
    h, w = image.shape
    return image[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1]


def test_image_shape_and_type(client):
    for width, height in ((64, 48), (160, 120), (7, 3)):
        image = DepthCamera(client, width=width, height=height).render([0, 0, 1], LEVEL)
        assert image.shape == (height, width) and image.dtype == np.float32


def test_wall_ahead_reads_its_distance_as_z_depth(client):
    box(client, [1.0, 40.0, 40.0], [5.5, 0.0, 0.0])  # near face at x = 5
    camera = DepthCamera(client, mount_offset=(0.2, 0.0, 0.05))
    image = camera.render([0.0, 0.0, 1.0], LEVEL)
    np.testing.assert_allclose(centre(image), 5.0 - 0.2, atol=0.02)
    # A flat wall square to the axis is at one z-depth in every pixel; the range would grow to the corners.
    np.testing.assert_allclose(image, 4.8, atol=0.02)


def test_yawing_sees_another_wall_and_nothing_behind(client):
    # Each wall spans less than the 90 degree view from the other direction.
    box(client, [1.0, 6.0, 40.0], [5.5, 0.0, 0.0])  # ahead along +x, face at 5 m
    box(client, [6.0, 1.0, 40.0], [0.0, 8.5, 0.0])  # to the left (+y), face at 8 m
    camera = DepthCamera(client, mount_offset=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(centre(camera.render([0, 0, 0], yaw(0.0))), 5.0, atol=0.02)
    np.testing.assert_allclose(centre(camera.render([0, 0, 0], yaw(math.pi / 2))), 8.0, atol=0.02)
    assert np.all(np.isposinf(camera.render([0, 0, 0], yaw(-math.pi / 2))))  # +y behind, nothing to the right
    # The mount offset turns with the body: 1 m forward is 1 m closer to whichever wall is ahead.
    forward = DepthCamera(client, mount_offset=(1.0, 0.0, 0.0))
    np.testing.assert_allclose(centre(forward.render([0, 0, 0], yaw(math.pi / 2))), 7.0, atol=0.02)


def test_empty_world_is_all_infinite(client):
    image = DepthCamera(client).render([0, 0, 10], LEVEL)
    assert np.all(np.isposinf(image))


def test_beyond_far_is_infinite(client):
    box(client, [1.0, 100.0, 100.0], [25.5, 0.0, 0.0])
    assert np.all(np.isposinf(DepthCamera(client, far=20.0).render([0, 0, 0], LEVEL)))
    np.testing.assert_allclose(DepthCamera(client, far=30.0).render([0, 0, 0], LEVEL), 25.0, atol=0.05)


def test_row_zero_is_up_and_column_zero_is_left(client):
    box(client, [20.0, 20.0, 1.0], [0.0, 0.0, -1.5])  # a floor, top face 1.5 m below the camera
    box(client, [0.2, 0.6, 40.0], [5.1, 1.0, 0.0])  # a pole 5 m ahead, 1 m to the left (+y), ~4 px wide
    camera = DepthCamera(client, width=64, height=48, mount_offset=(0.0, 0.0, 0.0))
    image = camera.render([0, 0, 0], LEVEL)
    assert np.all(np.isfinite(image[-1]))  # the floor along the bottom row
    # Above the horizon only the pole, in the column where the pinhole model puts y = +1 at z = 5.
    columns = np.flatnonzero(np.isfinite(image[0]))
    np.testing.assert_allclose(image[0, columns], 5.0, atol=0.02)
    expected = camera.cx - camera.fx * 1.0 / 5.0
    assert abs(columns.mean() - expected) <= 0.6 and 3 <= columns.size <= 5
    # Upside down, the floor fills the top row and the pole moves to the right of centre.
    flipped = camera.render([0, 0, 0], p.getQuaternionFromEuler([math.pi, 0.0, 0.0]))
    assert np.all(np.isfinite(flipped[0]))
    columns = np.flatnonzero(np.isfinite(flipped[-1]))
    assert abs(columns.mean() - (camera.cx + camera.fx * 1.0 / 5.0)) <= 0.6


def test_floor_depth_follows_pitch(client):
    box(client, [100.0, 100.0, 1.0], [0.0, 0.0, -0.5])  # ground top at z = 0
    camera = DepthCamera(client, mount_offset=(0.0, 0.0, 0.0))
    # Nose down 30 degrees from 2 m up: the axis meets the ground 2 / sin(30) = 4 m away.
    image = camera.render([0, 0, 2.0], p.getQuaternionFromEuler([0.0, math.radians(30.0), 0.0]))
    # The four centre pixels straddle the axis by half a pixel (1/64 rad) up and down.
    half = math.atan(0.5 / camera.fy)
    above, below = (2.0 / math.sin(math.radians(30.0) + s * half) * math.cos(half) for s in (-1, 1))
    np.testing.assert_allclose(centre(image), [[above, above], [below, below]], atol=0.02)


def test_nothing_reads_closer_than_near(client):
    box(client, [1.0, 1.0, 1.0], [0.55, 0.0, 0.0])  # near face 5 cm ahead, inside the near distance
    box(client, [1.0, 40.0, 40.0], [3.5, 0.0, 0.0])
    box(client, [0.2, 0.2, 0.2], [0.25, -0.2, 0.0])  # just beyond near, down and to the right
    camera = DepthCamera(client, near=0.1, mount_offset=(0.0, 0.0, 0.0))
    image = camera.render([0, 0, 0], LEVEL)
    finite = image[np.isfinite(image)]
    assert finite.size == image.size
    assert finite.min() >= camera.near
    assert finite.min() == pytest.approx(0.15, abs=0.01)  # the small box's face


def test_own_uav_body_does_not_block_the_view(client):
    box(client, [1.0, 40.0, 40.0], [5.5, 0.0, 0.0])
    airframe = load_airframe("iris")
    create_uav_body(client, airframe, [0.0, 0.0, 1.0], LEVEL)  # the camera sits inside this cylinder
    image = DepthCamera(client).render([0.0, 0.0, 1.0], LEVEL)
    np.testing.assert_allclose(image, 5.0, atol=0.02)


def test_intrinsics_match_the_field_of_view(client):
    camera = DepthCamera(client, width=160, height=120, fov_deg=90.0)
    assert camera.fx == camera.fy == pytest.approx(80.0)
    assert (camera.cx, camera.cy) == (79.5, 59.5)
    assert camera.vertical_fov_deg == pytest.approx(math.degrees(2 * math.atan(0.75)))


@pytest.mark.parametrize("kwargs", [{"width": 0}, {"fov_deg": 180.0}, {"near": 0.0}, {"near": 5.0, "far": 5.0}])
def test_bad_settings_are_refused(client, kwargs):
    with pytest.raises(ValueError):
        DepthCamera(client, **kwargs)
