"""The set-point stream: the latest command wins, and a velocity not renewed in time becomes a hold."""
import numpy as np

from magna_mavlink.setpoints import VELOCITY_TIMEOUT, SetPointStream


def test_nothing_is_streamed_before_a_command_or_after_clear():
    stream = SetPointStream()
    assert stream.at(0.0, (0, 0, 0)) is None
    stream.hold((1, 2, 3))
    stream.clear()
    assert stream.at(1.0, (0, 0, 0)) is None


def test_a_position_is_held_until_replaced():
    stream = SetPointStream()
    stream.hold((1, 2, 3), yaw=0.5)
    for now in (0.0, 10.0, 1000.0):
        point = stream.at(now, (9, 9, 9))
        assert point.kind == "position" and np.allclose(point.vector, (1, 2, 3)) and point.yaw == 0.5


def test_a_renewed_velocity_keeps_flying():
    stream = SetPointStream()
    for tick in range(10):  # renewed every 0.4 s, inside the timeout
        now = tick * 0.4
        stream.velocity((1, 0, 0), now)
        assert stream.at(now + 0.39, (tick, 0, 2)).kind == "velocity"


def test_an_expired_velocity_holds_where_the_vehicle_is_then():
    stream = SetPointStream()
    stream.velocity((1, 0, 0), now=10.0)
    assert stream.at(10.0 + VELOCITY_TIMEOUT, (3, 0, 2)).kind == "velocity"  # exactly at the timeout: still on
    held = stream.at(10.0 + VELOCITY_TIMEOUT + 0.01, (3.5, 0, 2))
    assert held.kind == "position" and np.allclose(held.vector, (3.5, 0, 2))
    # the hold stays where it began, wherever the vehicle drifts afterwards
    assert np.allclose(stream.at(20.0, (3.9, 0.1, 2)).vector, (3.5, 0, 2))


def test_a_new_command_replaces_the_hold():
    stream = SetPointStream()
    stream.velocity((0, 1, 0), now=0.0)
    stream.at(5.0, (0, 2, 2))  # expired: holding
    stream.velocity((0, -1, 0), now=5.0)
    assert stream.at(5.1, (0, 2, 2)).kind == "velocity"
