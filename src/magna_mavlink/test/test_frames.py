"""ROS (ENU/FLU) and MAVLink (NED/FRD) frames, table-driven, and every conversion undone by its inverse."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from magna_mavlink import frames

D = math.radians


@pytest.mark.parametrize(("enu", "ned"), [
    ((1, 0, 0), (0, 1, 0)),   # east
    ((0, 1, 0), (1, 0, 0)),   # north
    ((0, 0, 1), (0, 0, -1)),  # up
    ((1, 2, 3), (2, 1, -3)),
])
def test_world_vectors(enu, ned):
    assert np.allclose(frames.enu_to_ned(enu), ned)
    assert np.allclose(frames.ned_to_enu(ned), enu)


@pytest.mark.parametrize(("flu", "frd"), [
    ((1, 0, 0), (1, 0, 0)),   # forward
    ((0, 1, 0), (0, -1, 0)),  # left is minus right
    ((0, 0, 1), (0, 0, -1)),  # up is minus down
])
def test_body_vectors(flu, frd):
    assert np.allclose(frames.flu_to_frd(flu), frd)
    assert np.allclose(frames.frd_to_flu(frd), flu)


@pytest.mark.parametrize(("enu_deg", "ned_deg"), [
    (0, 90),      # facing east
    (90, 0),      # facing north
    (180, -90),   # facing west
    (-90, 180),   # facing south: (-pi, pi] keeps +180
    (45, 45),     # north-east
])
def test_yaw(enu_deg, ned_deg):
    assert frames.yaw_enu_to_ned(D(enu_deg)) == pytest.approx(D(ned_deg))
    assert frames.yaw_ned_to_enu(D(ned_deg)) == pytest.approx(frames.wrap_angle(D(enu_deg)))


@pytest.mark.parametrize(("enu_euler_deg", "ned_euler_deg"), [
    # (yaw, pitch, roll) about z, y, x of each convention
    ((0, 0, 0), (90, 0, 0)),        # level, facing east
    ((90, 0, 0), (0, 0, 0)),        # level, facing north
    ((0, -10, 0), (90, 10, 0)),     # facing east, nose up 10 deg (FLU pitches up about -y, FRD about +y)
    ((90, 0, 20), (0, 0, 20)),      # facing north, left wing up (FLU +x roll) is right wing down (FRD +x roll)
])
def test_attitude(enu_euler_deg, ned_euler_deg):
    enu = Rotation.from_euler("ZYX", enu_euler_deg, degrees=True).as_quat()
    ned = frames.attitude_enu_flu_to_ned_frd(enu)
    assert np.allclose(Rotation.from_quat(ned).as_euler("ZYX", degrees=True), ned_euler_deg, atol=1e-9)
    back = frames.attitude_ned_frd_to_enu_flu(ned)
    assert Rotation.from_quat(back).approx_equal(Rotation.from_quat(enu), atol=1e-12)


def test_the_attitudes_heading_is_the_yaw_conversion():
    rng = np.random.default_rng(7)
    for yaw in rng.uniform(-math.pi, math.pi, 50):
        enu = Rotation.from_euler("z", yaw).as_quat()
        ned_yaw = Rotation.from_quat(frames.attitude_enu_flu_to_ned_frd(enu)).as_euler("ZYX")[0]
        assert frames.wrap_angle(ned_yaw - frames.yaw_enu_to_ned(yaw)) == pytest.approx(0.0, abs=1e-9)


def test_wrap_angle_is_half_open():
    assert frames.wrap_angle(math.pi) == math.pi and frames.wrap_angle(-math.pi) == math.pi
    assert frames.wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
