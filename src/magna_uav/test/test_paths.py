"""Waypoint paths: smoothing by smooth_path_mode, the waypoint tracker, nav_msgs/Path."""
import json
import math

import numpy as np
import pytest

from magna_uav.paths import Path, WaypointTracker, as_waypoints, path_msg, smooth_path
from tests.support import CORPUS

ZIGZAG = np.array([[0, 0, 1], [2, 3, 1], [4, -1, 2], [6, 2, 2.5], [8, 0, 1]], dtype=float)


def _contains(points, point, tol=1e-9):
    return bool(np.any(np.linalg.norm(points - point, axis=1) <= tol))


@pytest.mark.parametrize("order", [0, None])
def test_order_zero_or_none_returns_the_waypoints_as_they_are(order):
    out = smooth_path(ZIGZAG.tolist(), order)
    assert out.shape == ZIGZAG.shape and np.array_equal(out, ZIGZAG)


@pytest.mark.parametrize("order", [1, 2, 3, 5])
def test_smoothing_starts_and_ends_exactly_at_the_end_waypoints_and_passes_through_every_waypoint(order):
    out = smooth_path(ZIGZAG, order, samples_per_metre=10)
    assert np.array_equal(out[0], ZIGZAG[0]) and np.array_equal(out[-1], ZIGZAG[-1])
    for waypoint in ZIGZAG:
        assert _contains(out, waypoint), (order, waypoint)
    # the waypoints come in their order along the samples
    hits = [int(np.argmin(np.linalg.norm(out - w, axis=1))) for w in ZIGZAG]
    assert hits == sorted(hits)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_smoothing_samples_evenly_along_the_curve_at_the_asked_density(order):
    chord = float(np.linalg.norm(np.diff(ZIGZAG, axis=0), axis=1).sum())
    out = smooth_path(ZIGZAG, order, samples_per_metre=10)
    steps = np.linalg.norm(np.diff(out, axis=0), axis=1)
    assert len(out) >= chord * 10
    assert steps.max() <= 0.1 + 1e-3  # no longer jump than asked, even where the spline bulges
    assert steps.min() > 1e-6  # and no repeated sample
    coarse = smooth_path(ZIGZAG, order, samples_per_metre=1)
    assert len(coarse) < len(out) and np.linalg.norm(np.diff(coarse, axis=0), axis=1).max() <= 1.0 + 1e-2


def test_order_one_is_the_polyline_itself_densely_sampled():
    out = smooth_path(ZIGZAG, 1, samples_per_metre=5)
    # every sample lies on one of the straight segments
    for point in out:
        distances = []
        for a, b in zip(ZIGZAG[:-1], ZIGZAG[1:], strict=True):
            t = np.clip(np.dot(point - a, b - a) / np.dot(b - a, b - a), 0, 1)
            distances.append(np.linalg.norm(a + t * (b - a) - point))
        assert min(distances) < 1e-9


def test_higher_orders_curve_away_from_the_polyline():
    linear = smooth_path(ZIGZAG, 1, samples_per_metre=20)
    cubic = smooth_path(ZIGZAG, 3, samples_per_metre=20)
    # the cubic is not the polyline: some sample is well off every segment
    off = max(min(np.linalg.norm(linear - p, axis=1)) for p in cubic)
    assert off > 0.05


def test_order_is_clipped_to_the_number_of_waypoints():
    two = np.array([[0, 0, 1], [4, 0, 1]], dtype=float)
    out = smooth_path(two, 3, samples_per_metre=2)  # degree min(3, 1) = 1: the straight line
    assert np.array_equal(out[0], two[0]) and np.array_equal(out[-1], two[-1])
    assert np.allclose(out[:, 1:], [0, 1]) and np.all(np.diff(out[:, 0]) > 0)
    three = np.array([[0, 0, 1], [2, 2, 1], [4, 0, 1]], dtype=float)
    parabola = smooth_path(three, 5)  # degree 2 through three points
    assert all(_contains(parabola, w) for w in three)
    # a parabola in the chord parameter: smooth, no kink at the middle waypoint
    middle = int(np.argmin(np.linalg.norm(parabola - three[1], axis=1)))
    before = parabola[middle] - parabola[middle - 1]
    after = parabola[middle + 1] - parabola[middle]
    cos = np.dot(before, after) / np.linalg.norm(before) / np.linalg.norm(after)
    assert cos > 0.99


def test_one_waypoint_and_repeated_waypoints():
    assert np.array_equal(smooth_path([[1, 2, 3]], 3), [[1.0, 2.0, 3.0]])
    repeated = np.array([[0, 0, 1], [0, 0, 1], [3, 0, 1], [3, 3, 1], [3, 3, 1]], dtype=float)
    out = smooth_path(repeated, 3)
    assert np.all(np.isfinite(out))
    assert np.array_equal(out[0], repeated[0]) and np.array_equal(out[-1], repeated[-1])
    assert smooth_path([[2, 2, 2], [2, 2, 2]], 2).tolist() == [[2.0, 2.0, 2.0]]


@pytest.mark.parametrize("order", [-1, 1.5, "2", True])
def test_bad_orders_are_refused(order):
    with pytest.raises(ValueError, match="smooth_path_mode"):
        smooth_path(ZIGZAG, order)


@pytest.mark.parametrize("waypoints", [[], [[0, 0]], [[0, 0, math.nan]], "abc"])
def test_bad_waypoints_are_refused(waypoints):
    with pytest.raises(ValueError, match="path: waypoints"):
        as_waypoints(waypoints)


def _corpus_modes():
    modes = []
    for path in sorted((CORPUS / "Missions").rglob("*.json")):
        _collect(json.loads(path.read_text()), modes)
    return modes


def _collect(node, modes):
    if isinstance(node, dict):
        for key, value in node.items():
            if key == "smooth_path_mode":
                modes.append(value)
            else:
                _collect(value, modes)
    elif isinstance(node, list):
        for value in node:
            _collect(value, modes)


def test_every_smooth_path_mode_of_the_corpus_missions_is_accepted():
    modes = _corpus_modes()
    assert len(modes) >= 20, f"the corpus missions are missing from {CORPUS}"
    assert set(modes) == {0, 1, 2}
    for mode in set(modes):
        out = smooth_path(ZIGZAG, mode)
        assert np.array_equal(out[0], ZIGZAG[0]) and np.array_equal(out[-1], ZIGZAG[-1])
        assert (len(out) == len(ZIGZAG)) == (mode == 0)


def test_path_smoothed_interpolates_the_yaw_along_the_chord():
    path = Path([[0, 0, 1], [1, 0, 1], [2, 0, 1]], yaw=[3.0, -3.0, -2.5])  # wraps through pi
    assert path.length == pytest.approx(2.0)
    smooth = path.smoothed(1, samples_per_metre=4)
    assert len(smooth) == 9 and smooth.yaw.shape == (9,)
    assert smooth.yaw[0] == pytest.approx(3.0) and smooth.yaw[-1] == pytest.approx(-2.5)
    # between 3.0 and -3.0 the short way is through pi, not through 0
    assert np.all(np.abs(smooth.yaw[:5]) > 2.9)
    assert path.smoothed(0).yaw.tolist() == [3.0, -3.0, -2.5]
    with pytest.raises(ValueError, match="2 yaw values for 3 waypoints"):
        Path([[0, 0, 1], [1, 0, 1], [2, 0, 1]], yaw=[0, 1])


def test_tracker_advances_only_within_the_accepted_radius_of_the_own_position():
    tracker = WaypointTracker([[0, 0, 1], [5, 0, 1], [5, 5, 1]], accepted_radius=0.5)
    assert tracker.index == 0 and tracker.remaining == 3 and not tracker.done
    assert tracker.target.tolist() == [0.0, 0.0, 1.0]
    assert tracker.update([0.6, 0, 1]) is False and tracker.index == 0  # just outside
    assert tracker.update([0.5, 0, 1]) is True and tracker.index == 1  # on the radius counts
    assert tracker.update([0.1, 0, 1]) is False and tracker.index == 1  # back at the old one: no change
    assert tracker.update([5, 0.4, 1.2]) is True and tracker.remaining == 1
    assert tracker.target.tolist() == [5.0, 5.0, 1.0]
    assert tracker.update([5, 5.3, 1.3]) is True
    assert tracker.done and tracker.remaining == 0 and tracker.target is None and tracker.index == 3
    assert tracker.update([5, 5, 1]) is False


def test_tracker_passes_every_waypoint_inside_the_radius_at_once_but_not_beyond():
    dense = smooth_path([[0, 0, 1], [2, 0, 1]], 1, samples_per_metre=10)  # 0.1 m apart
    tracker = WaypointTracker(dense, accepted_radius=0.35)
    tracker.update([0, 0, 1])
    assert tracker.index == 4  # samples at 0, 0.1, 0.2, 0.3 passed; 0.4 is next
    tracker.update([5, 0, 1])  # far ahead of the target: nothing passed
    assert tracker.index == 4


def test_tracker_target_is_a_copy_and_bad_radius_is_refused():
    tracker = WaypointTracker([[1, 1, 1]], accepted_radius=1)
    tracker.target[0] = 99
    assert tracker.target.tolist() == [1.0, 1.0, 1.0]
    for radius in (0, -1, math.nan):
        with pytest.raises(ValueError, match="accepted_radius"):
            WaypointTracker([[1, 1, 1]], accepted_radius=radius)


def test_path_msg_holds_every_point_in_the_frame_with_the_yaw():
    import rospy

    msg = path_msg([[0, 0, 1], [1, 2, 3]], frame="map", stamp=rospy.Time(12, 5))
    assert msg._type == "nav_msgs/Path" and msg.header.frame_id == "map"
    assert msg.header.stamp == rospy.Time(12, 5)
    assert [(p.pose.position.x, p.pose.position.y, p.pose.position.z) for p in msg.poses] == [(0, 0, 1), (1, 2, 3)]
    assert all(p.header.frame_id == "map" and p.header.stamp == rospy.Time(12, 5) for p in msg.poses)
    assert all(p.pose.orientation.w == 1.0 and p.pose.orientation.z == 0.0 for p in msg.poses)

    turned = path_msg(Path([[0, 0, 1]], yaw=[math.pi / 2]), frame="uav_1/base_link")
    q = turned.poses[0].pose.orientation
    assert turned.header.frame_id == "uav_1/base_link" and turned.header.stamp.is_zero()
    assert (q.x, q.y) == (0, 0) and q.z == pytest.approx(math.sqrt(0.5)) and q.w == pytest.approx(math.sqrt(0.5))


def test_the_module_imports_without_ros():
    import subprocess
    import sys

    code = ("import sys; sys.modules['rospy'] = sys.modules['nav_msgs'] = sys.modules['geometry_msgs'] = None; "
            "import magna_uav.paths as p; print(len(p.smooth_path([[0, 0, 0], [1, 0, 0]], 1)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) == 11
