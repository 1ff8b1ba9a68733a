"""Waypoint paths for the path-follower role: the path, its optional smoothing, and a tracker
that walks the waypoints as the UAV reaches them.

`smooth_path_mode` of the mission's follow_path state is the smoothing order: 0 (or absent)
flies the waypoints as given; k >= 1 flies a B-spline of degree min(k, n-1) that passes
through every waypoint, parametrised by cumulative chord length and sampled densely.
No ROS import at module level: `path_msg` imports nav_msgs when called.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

DEFAULT_SAMPLES_PER_METRE = 10.0
_SAME_POINT = 1e-9  # m: consecutive waypoints closer than this are one waypoint for the spline


@dataclass(frozen=True)
class Path:
    """Waypoints (n, 3) in metres in the map frame, with an optional yaw (n,) in radians."""

    waypoints: np.ndarray
    yaw: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "waypoints", as_waypoints(self.waypoints))
        if self.yaw is not None:
            yaw = np.asarray(self.yaw, dtype=float).reshape(-1)
            if len(yaw) != len(self.waypoints):
                raise ValueError(f"path: {len(yaw)} yaw values for {len(self.waypoints)} waypoints")
            if not np.all(np.isfinite(yaw)):
                raise ValueError("path: yaw values must be finite")
            object.__setattr__(self, "yaw", yaw)

    def __len__(self) -> int:
        return len(self.waypoints)

    @property
    def length(self) -> float:
        """Sum of the straight segments between consecutive waypoints (m)."""
        return float(np.linalg.norm(np.diff(self.waypoints, axis=0), axis=1).sum())

    def smoothed(self, order: int | None, samples_per_metre: float = DEFAULT_SAMPLES_PER_METRE) -> Path:
        """This path through `smooth_path`; a yaw, if any, is interpolated (unwrapped) along the chord length."""
        points, params, knots = _smooth(self.waypoints, order, samples_per_metre)
        if self.yaw is None:
            return Path(points)
        if params is None:  # not smoothed: the waypoints as they are
            return Path(points, self.yaw)
        keep = _distinct(self.waypoints)
        yaw = np.interp(params, knots, np.unwrap(self.yaw[keep]))
        return Path(points, np.angle(np.exp(1j * yaw)))


def as_waypoints(waypoints) -> np.ndarray:
    """Waypoints as a float (n, 3) array; ValueError unless n >= 1 and every value is finite."""
    if isinstance(waypoints, Path):
        return waypoints.waypoints.copy()
    try:
        array = np.array(waypoints, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"path: waypoints must be numbers, shape (n, 3): {error}") from None
    if array.ndim != 2 or array.shape[1] != 3 or array.shape[0] < 1:
        raise ValueError(f"path: waypoints must have shape (n, 3) with n >= 1, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError("path: waypoints must be finite")
    return array


def smooth_path(waypoints, order: int | None, samples_per_metre: float = DEFAULT_SAMPLES_PER_METRE) -> np.ndarray:
    """The points to fly for `waypoints` (n, 3) and a `smooth_path_mode` `order`.

    order 0 or None: the waypoints as they are. order k >= 1: an interpolating B-spline of degree
    min(k, n-1) over the cumulative chord length, sampled evenly along the curve at about
    `samples_per_metre` points per metre plus every waypoint itself, so the result contains each
    waypoint and starts and ends exactly at the first and last one. Repeated consecutive waypoints
    are merged.
    """
    return _smooth(waypoints, order, samples_per_metre)[0]


def _smooth(waypoints, order, samples_per_metre):
    """(points, sample parameters or None when not smoothed, knot parameters of the distinct waypoints)."""
    points = as_waypoints(waypoints)
    order = _order(order)
    if order == 0:
        return points, None, None
    if not _positive_number(samples_per_metre):
        raise ValueError(f"path: samples_per_metre must be a positive number, got {samples_per_metre!r}")
    distinct = points[_distinct(points)]
    if len(distinct) == 1:
        return distinct, np.zeros(1), np.zeros(1)
    knots = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(distinct, axis=0), axis=1))))
    degree = min(order, len(distinct) - 1)
    from scipy.interpolate import make_interp_spline

    spline = make_interp_spline(knots, distinct, k=degree)
    # samples evenly spaced along the curve's own length (a spline is longer than its chords)
    fine = np.union1d(np.linspace(0.0, knots[-1], int(math.ceil(knots[-1] * samples_per_metre * 8)) + 2), knots)
    arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(spline(fine), axis=0), axis=1))))
    count = max(2, int(math.ceil(arc[-1] * samples_per_metre)) + 1)
    params = np.interp(np.linspace(0.0, arc[-1], count), arc, fine)
    near_knot = np.abs(params[:, None] - knots[None, :]).min(axis=1) <= _SAME_POINT
    params = np.union1d(params[~near_knot], knots)
    sampled = spline(params)
    sampled[np.searchsorted(params, knots)] = distinct  # exact at the waypoints, not within 1e-15
    return sampled, params, knots


def _order(order) -> int:
    if order is None:
        return 0
    if isinstance(order, bool) or not isinstance(order, numbers.Integral) or order < 0:
        raise ValueError(f"path: smooth_path_mode must be an integer >= 0 (0 = no smoothing), got {order!r}")
    return int(order)


def _distinct(points: np.ndarray) -> np.ndarray:
    """Indices of the waypoints that differ from the one before (the first always kept)."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate(([0], np.nonzero(steps > _SAME_POINT)[0] + 1))


def _positive_number(value: object) -> bool:
    # `object`: mypy does not count float as a numbers.Real, so checking a float-typed value inline would make
    # the code after the check unreachable to it
    return isinstance(value, numbers.Real) and math.isfinite(value) and float(value) > 0


class WaypointTracker:
    """Walks the waypoints in order: the current target advances once the UAV's own position is
    within `accepted_radius` of it (inclusive). One update may pass several waypoints when they
    all lie within the radius, as the samples of a smoothed path do.
    """

    def __init__(self, waypoints, accepted_radius: float):
        if not _positive_number(accepted_radius):
            raise ValueError(f"accepted_radius must be a positive number of metres, got {accepted_radius!r}")
        self.waypoints = as_waypoints(waypoints)
        self.accepted_radius = float(accepted_radius)
        self._index = 0

    @property
    def index(self) -> int:
        """Index of the current target; len(waypoints) once done."""
        return self._index

    @property
    def done(self) -> bool:
        return self._index >= len(self.waypoints)

    @property
    def remaining(self) -> int:
        """Waypoints not reached yet, the current target included."""
        return len(self.waypoints) - self._index

    @property
    def target(self) -> np.ndarray | None:
        """The waypoint to fly to now (a copy), or None when every waypoint is reached."""
        return None if self.done else self.waypoints[self._index].copy()

    def update(self, position: Sequence[float]) -> bool:
        """Advance past every consecutive waypoint within the radius of `position`; True if it moved."""
        here = np.asarray(position, dtype=float).reshape(3)
        start = self._index
        while not self.done and np.linalg.norm(self.waypoints[self._index] - here) <= self.accepted_radius:
            self._index += 1
        return self._index != start


def path_msg(points, frame: str = "map", stamp=None, yaw=None):
    """A nav_msgs/Path of `points` ((n, 3) or a Path) in `frame`.

    `stamp` (rospy.Time) goes to the header and every pose; None leaves time zero ("latest").
    Orientation is the yaw about z (from `yaw`, or the Path's own) or the identity.
    """
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path as PathMsg

    if isinstance(points, Path) and yaw is None:
        yaw = points.yaw
    array = as_waypoints(points)
    if yaw is not None:
        yaw = np.asarray(yaw, dtype=float).reshape(-1)
        if len(yaw) != len(array):
            raise ValueError(f"path_msg: {len(yaw)} yaw values for {len(array)} points")
    msg = PathMsg()
    msg.header.frame_id = frame
    if stamp is not None:
        msg.header.stamp = stamp
    for n, point in enumerate(array):
        pose = PoseStamped()
        pose.header.frame_id = frame
        if stamp is not None:
            pose.header.stamp = stamp
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = (float(v) for v in point)
        half = 0.0 if yaw is None else float(yaw[n]) / 2.0
        pose.pose.orientation.z = math.sin(half)
        pose.pose.orientation.w = math.cos(half)
        msg.poses.append(pose)
    return msg
