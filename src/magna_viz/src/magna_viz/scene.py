"""The UAV scene: what rviz draws of each UAV, built from its poses, paths and goals and the mission file.

No rospy here: `Scene` takes plain numbers (positions, quaternions, stamps) and returns a
visualization_msgs/MarkerArray, so a unit test reaches it without a master. The scene node
(magna_viz.scene_node) feeds it from the topics and publishes what it returns.

Per UAV, in the UAV's mission colour (marker_color [r, g, b, a], r, g, b 0-255), all in `map`:

    ns body       the airframe as a flat cylinder (opaque), id = UAV id
    ns heading    an arrow along the UAV's yaw
    ns safety     a translucent sphere of the airframe's safety radius (true size, mission alpha)
    ns label      the UAV's name above it
    ns trail      where it has flown, a LINE_STRIP (opaque)
    ns path_raw   the raw path: thin translucent line and its waypoints
    ns path_smoothed  the smoothed path it follows
    ns goal       the current goal: a sphere, and a thin line from the UAV to it

`scale` multiplies the drawn sizes (not the safety sphere) so UAVs stay visible in big worlds.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from geometry_msgs.msg import Point, Quaternion, Vector3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

MAP_FRAME = "map"
NAMESPACES = ("body", "heading", "safety", "label", "trail", "path_raw", "path_smoothed", "goal")
TRAIL_STEP = 0.05  # m: a new trail point once the UAV is this far from the last one
TIME_JUMP_BACK = 1.0  # s: a pose older than the last by more than this restarts the trails (bag looped)


@dataclass(frozen=True)
class UavStyle:
    """How one UAV is drawn: its id, colour (0..1 per channel, as rviz wants it) and sizes in metres."""

    id: int
    rgba: tuple[float, float, float, float]
    body_radius: float = 0.3
    body_height: float = 0.12
    safety_radius: float = 0.3

    @property
    def name(self) -> str:
        return f"uav_{self.id}"

    @property
    def rgb(self) -> tuple[float, float, float]:
        return self.rgba[:3]


def rgba_from_marker_color(color: Sequence[float]) -> tuple[float, float, float, float]:
    """A mission's marker_color [r, g, b, a] (r, g, b 0-255, a 0-1) as rviz's 0..1 channels."""
    if len(color) != 4:
        raise ValueError(f"marker_color: expected [r, g, b, a], got {list(color)!r}")
    r, g, b, a = (float(c) for c in color)
    return (_clamp(r / 255.0), _clamp(g / 255.0), _clamp(b / 255.0), _clamp(a))


def styles_from_mission(mission_file: str | Path) -> list[UavStyle]:
    """One style per agent of a mission file (Agents_Config or legacy UAVs_Config), sizes from its airframe.

    Raises magna_uav.config.ConfigError (a ValueError) naming the file and field of a bad entry.
    """
    from magna_uav.config import configs_from_mission_file

    styles = []
    for config in configs_from_mission_file(mission_file):
        body = config.airframe.body
        styles.append(UavStyle(
            id=config.id, rgba=rgba_from_marker_color(config.marker_color),
            body_radius=body.radius if body is not None else config.safety_radius,
            body_height=body.height if body is not None else 0.12,
            safety_radius=config.safety_radius))
    return styles


@dataclass
class UavTrack:
    """What is known of one UAV so far."""

    style: UavStyle
    position: tuple[float, float, float] | None = None
    orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    stamp: float | None = None
    trail: list[tuple[float, float, float]] = field(default_factory=list)
    raw_path: list[tuple[float, float, float]] = field(default_factory=list)
    smoothed_path: list[tuple[float, float, float]] = field(default_factory=list)
    goal: tuple[float, float, float] | None = None


class Scene:
    """The UAVs' state, updated message by message; `markers()` draws it.

    `changed` is set by every update that alters the drawing and cleared by `markers()`, so a
    node republishes only when there is something new.
    """

    def __init__(self, styles: Iterable[UavStyle], scale: float = 1.0, trail_step: float = TRAIL_STEP,
                 max_trail: int = 0, frame: str = MAP_FRAME):
        self.tracks: dict[int, UavTrack] = {s.id: UavTrack(s) for s in styles}
        if scale <= 0:
            raise ValueError(f"scale must be > 0, got {scale}")
        self.scale, self.trail_step, self.max_trail, self.frame = scale, trail_step, max_trail, frame
        self.changed = True
        self._cleared = False  # the next drawing starts with a DELETEALL (after a restart)

    @property
    def ids(self) -> list[int]:
        return sorted(self.tracks)

    def update_pose(self, uav_id: int, position: Sequence[float], orientation: Sequence[float] = (0, 0, 0, 1),
                    stamp: float | None = None) -> None:
        """A new pose of a UAV: moves its body and grows its trail."""
        track = self.tracks.get(uav_id)
        if track is None:
            return
        if stamp is not None and track.stamp is not None and stamp < track.stamp - TIME_JUMP_BACK:
            self.restart()
        here = _xyz(position)
        if not all(math.isfinite(v) for v in here):
            return
        track.position, track.orientation, track.stamp = here, _xyzw(orientation), stamp
        if not track.trail or _distance(track.trail[-1], here) >= self.trail_step:
            track.trail.append(here)
            if self.max_trail and len(track.trail) > self.max_trail:
                del track.trail[: len(track.trail) - self.max_trail]
        self.changed = True

    def update_path(self, uav_id: int, points: Iterable[Sequence[float]], smoothed: bool) -> None:
        track = self.tracks.get(uav_id)
        if track is None:
            return
        path = [_xyz(p) for p in points]
        if smoothed:
            track.smoothed_path = path
        else:
            track.raw_path = path
        self.changed = True

    def update_goal(self, uav_id: int, position: Sequence[float] | None) -> None:
        track = self.tracks.get(uav_id)
        if track is None:
            return
        track.goal = None if position is None else _xyz(position)
        self.changed = True

    def restart(self) -> None:
        """Forget trails, paths and goals (time went back: a bag played again)."""
        for uav_id, track in self.tracks.items():
            self.tracks[uav_id] = UavTrack(track.style)
        self._cleared = True
        self.changed = True

    def markers(self) -> MarkerArray:
        """Every marker of every UAV known so far; markers of things not known (yet) are deleted."""
        out = MarkerArray()
        if self._cleared:
            clear = Marker(action=Marker.DELETEALL)
            clear.header.frame_id = self.frame
            out.markers.append(clear)
            self._cleared = False
        for uav_id in self.ids:
            out.markers.extend(self._uav_markers(self.tracks[uav_id]))
        self.changed = False
        return out

    # --- one UAV -------------------------------------------------------------------------------------------

    def _uav_markers(self, track: UavTrack) -> list[Marker]:
        style, s = track.style, self.scale
        rgb = style.rgb
        solid = (*rgb, 1.0)
        markers = []
        here = track.position
        if here is not None:
            body = self._marker(style, "body", Marker.CYLINDER, solid)
            body.pose.position = Point(*here)
            body.pose.orientation = Quaternion(*track.orientation)
            body.scale = Vector3(2 * style.body_radius * s, 2 * style.body_radius * s,
                                 max(style.body_height * s, 0.05))
            markers.append(body)

            heading = self._marker(style, "heading", Marker.ARROW, _lighter(rgb, 0.5, 1.0))
            heading.pose.position = Point(*here)
            heading.pose.orientation = Quaternion(*track.orientation)
            heading.scale = Vector3(2.2 * style.body_radius * s, 0.12 * s, 0.12 * s)
            markers.append(heading)

            safety = self._marker(style, "safety", Marker.SPHERE, (*rgb, min(style.rgba[3], 1.0) * 0.5))
            safety.pose.position = Point(*here)
            safety.scale = Vector3(*(2 * style.safety_radius,) * 3)
            markers.append(safety)

            label = self._marker(style, "label", Marker.TEXT_VIEW_FACING, _lighter(rgb, 0.35, 1.0))
            label.pose.position = Point(here[0], here[1], here[2] + max(style.body_radius, 0.3) * s + 0.4 * s)
            label.scale.z = 0.45 * s
            label.text = style.name
            markers.append(label)
        else:
            markers += [self._delete(style, ns) for ns in ("body", "heading", "safety", "label")]

        markers.append(self._line(style, "trail", track.trail, 0.08 * s, solid))
        raw = self._line(style, "path_raw", track.raw_path, 0.03 * s, (*rgb, 0.45))
        markers.append(raw)
        if track.raw_path:
            waypoints = self._marker(style, "path_raw", Marker.SPHERE_LIST, (*rgb, 0.6))
            waypoints.id = 100000 + style.id  # a second marker of the namespace
            waypoints.scale = Vector3(*(0.18 * s,) * 3)
            waypoints.points = [Point(*p) for p in track.raw_path]
            markers.append(waypoints)
        else:
            gone = self._delete(style, "path_raw")
            gone.id = 100000 + style.id
            markers.append(gone)
        markers.append(self._line(style, "path_smoothed", track.smoothed_path, 0.05 * s, (*rgb, 0.8)))

        if track.goal is not None:
            goal = self._marker(style, "goal", Marker.SPHERE, (*_lighter(rgb, 0.25, 1.0)[:3], 0.9))
            goal.pose.position = Point(*track.goal)
            goal.scale = Vector3(*(0.3 * s,) * 3)
            markers.append(goal)
            if here is not None:
                markers.append(self._line(style, "goal", [here, track.goal], 0.02 * s, (*rgb, 0.6),
                                          marker_id=100000 + style.id))
        else:
            markers.append(self._delete(style, "goal"))
            gone = self._delete(style, "goal")
            gone.id = 100000 + style.id
            markers.append(gone)
        return markers

    def _marker(self, style: UavStyle, ns: str, kind: int, rgba) -> Marker:
        marker = Marker(type=kind, action=Marker.ADD, ns=ns, id=style.id, color=ColorRGBA(*rgba))
        marker.header.frame_id = self.frame
        marker.pose.orientation.w = 1.0
        marker.frame_locked = False
        return marker

    def _delete(self, style: UavStyle, ns: str) -> Marker:
        marker = Marker(action=Marker.DELETE, ns=ns, id=style.id)
        marker.header.frame_id = self.frame
        return marker

    def _line(self, style: UavStyle, ns: str, points, width: float, rgba, marker_id: int | None = None) -> Marker:
        """A LINE_STRIP through the points, or a DELETE when there are fewer than two."""
        if len(points) < 2:
            marker = self._delete(style, ns)
        else:
            marker = self._marker(style, ns, Marker.LINE_STRIP, rgba)
            marker.scale.x = width
            marker.points = [Point(*p) for p in points]
        if marker_id is not None:
            marker.id = marker_id
        return marker


def is_clear_only(markers: MarkerArray) -> bool:
    """True when a MarkerArray only deletes (what the world node sends when the last world part goes)."""
    return all(m.action in (Marker.DELETE, Marker.DELETEALL) for m in markers.markers)


def _xyz(values: Sequence[float]) -> tuple[float, float, float]:
    x, y, z = values
    return float(x), float(y), float(z)


def _xyzw(values: Sequence[float]) -> tuple[float, float, float, float]:
    x, y, z, w = values
    return float(x), float(y), float(z), float(w)


def _distance(a: Sequence[float], b: Sequence[float]) -> float:
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b, strict=True)))


def _clamp(value: float) -> float:
    return min(max(value, 0.0), 1.0)


def _lighter(rgb: Sequence[float], amount: float, alpha: float) -> tuple[float, float, float, float]:
    """The colour mixed with white by `amount` (0: unchanged, 1: white)."""
    r, g, b = (c + (1.0 - c) * amount for c in rgb)
    return (r, g, b, alpha)
