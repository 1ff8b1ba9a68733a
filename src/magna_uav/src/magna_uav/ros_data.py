"""The ROS side of a UAV manager's data (UAV-D): keeps a WorldView filled from topics.

Per UAV id it listens to the UAL API and the autopilot's battery:

    own UAV:
    /uav_{id}/ual/pose                PoseStamped      position, orientation, stamp
    /uav_{id}/ual/velocity            TwistStamped     linear velocity, yaw rate (map frame)
    /uav_{id}/ual/state               uav_abstraction_layer/State
    /uav_{id}/mavros/battery          sensor_msgs/BatteryState   percentage, 0..1 (NaN: unknown)
    /uav_{id}/camera/depth/image_raw  sensor_msgs/Image 32FC1 (metres) or 16UC1 (mm), when asked
    every other UAV:
    /uav_{id}/ual/odom                nav_msgs/Odometry  pose and twist (the twist in the body
                                      frame, as UAL publishes it; turned into map here)

Why odom for the others: with N UAVs every manager deserialises every message it subscribes
to, N * (N - 1) per publishing period across the fleet for each topic per other UAV. One
message that carries pose and velocity halves that; nothing reads another UAV's UAL state
or battery (the evaluator, roles and recorder look at the own UAV's).

In simulation every UAV, the own one included, comes instead from magna_sim's one message per
period, /magna/sim/swarm_state (magna_msgs/SwarmState: every simulated UAV's odom values and
UAL state, stamped with the odom's stamp), through a `SwarmFeed`: one subscription that feeds
every manager of a process (a host's N managers deserialise it once, not 4N times). Only the
UAVs flown by MAVLink (hil, real), which magna_sim does not fly, are still heard on their topics.

and to the world node's latched /magna/world/markers, whose namespace "obstacles" becomes
the view's obstacles (their real shape and their bounding sphere). A UAV enters the view at its first pose: what is
heard of it before (velocity, state, battery) is kept and shows up with that pose, so the
view never holds a UAV at a made-up position.

Threads: rospy runs each subscription's callbacks in a thread of its own; every update
takes `lock` and replaces whole AgentState objects, and the control loop holds the same
lock while it reads the view (`with data.lock: evaluator.step(view)`). The swarm's state alone never
waits for that lock: one thread hands it to every manager of a host, so a manager busy in its step gets it
when its next step takes the lock (ViewLock).

The message handling (`WorldUpdater`, `ObstacleMarkers`) needs no ROS master, only the
message classes; `RosWorldData` adds the subscriptions.
"""
from __future__ import annotations

import dataclasses
import math
import threading
from collections.abc import Callable, Iterable

import numpy as np
from geometry_msgs.msg import PoseStamped, TwistStamped
from magna_msgs.msg import SwarmState
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState, Image
from uav_abstraction_layer.msg import State
from visualization_msgs.msg import Marker, MarkerArray

from magna_common import ros_names as names
from magna_uav.shapes import Box, Capsule, Cylinder, Mesh, Sphere
from magna_uav.world_view import AgentState, Obstacle, WorldView

OBSTACLE_NS = "obstacles"
MAP_FRAMES = ("map", "/map", "")  # markers without a frame are taken to be in map

_MARKER_TYPES = {getattr(Marker, n): n for n in (
    "ARROW", "CUBE", "SPHERE", "CYLINDER", "LINE_STRIP", "LINE_LIST", "CUBE_LIST", "SPHERE_LIST", "POINTS",
    "TEXT_VIEW_FACING", "MESH_RESOURCE", "TRIANGLE_LIST")}


def topics(agent_id: int) -> dict[str, str]:
    """The topics heard for one UAV."""
    return {**{name: names.ual(agent_id, name) for name in ("pose", "velocity", "odom", "state")},
            "battery": names.battery(agent_id), "depth": names.depth_camera(agent_id, "image_raw")}


# --- obstacle markers -------------------------------------------------------------------------------------------

def obstacles_from_markers(markers: MarkerArray) -> list[Obstacle]:
    """The obstacles one MarkerArray leaves behind when applied to an empty set (see ObstacleMarkers)."""
    table = ObstacleMarkers()
    table.apply(markers)
    return table.obstacles()


class ObstacleMarkers:
    """The obstacle markers heard so far, keyed by (ns, id) as rviz keys them.

    Only namespace "obstacles" counts. ADD (= MODIFY) puts or replaces a marker, DELETE
    removes it, DELETEALL (ns "" or "obstacles") empties the set. Each marker becomes an
    Obstacle whose parts are the solid rviz would draw (a CUBE a box, a SPHERE a sphere, a
    CYLINDER a cylinder, all with the marker's pose; a TRIANGLE_LIST its triangles, as the
    world node draws a torus or a prism; LINE_LIST/LINE_STRIP capsules of half the line width;
    POINTS and SPHERE_LIST spheres, CUBE_LIST boxes; an ellipsoid SPHERE its box and an elliptic
    CYLINDER the circular one of its larger axis, both holding it), and whose bounding sphere is:

    - CUBE: half the diagonal of the scale (full edge lengths); SPHERE: half the largest
      scale; CYLINDER: half the diagonal of (diameter, height) -- each the smallest sphere
      about the pose origin that holds the solid;
    - TRIANGLE_LIST (points scaled by `scale`, as rviz does), LINE_LIST/LINE_STRIP (plus
      half the line width scale.x), POINTS, SPHERE_LIST, CUBE_LIST (plus half an item):
      the points are in the marker's frame; the centre is the pose origin or the centre of
      the points' bounding box, whichever needs the smaller radius, moved by the pose;
    - ARROW, TEXT_VIEW_FACING, MESH_RESOURCE have no size of their own here: skipped, and
      `apply` says so.

    The bounding sphere is what ORCA-3D and the networks are given; gaps, nearest-first order
    and collisions use the parts (magna_uav.world_view). The name is the marker's `text` when it
    has one, else "obstacle_{id}". Markers in a frame other than map are skipped (there is no
    tf lookup here).
    """

    def __init__(self, namespace: str = OBSTACLE_NS):
        self.namespace = namespace
        self._by_key: dict[tuple[str, int], Obstacle] = {}

    def apply(self, markers: MarkerArray | Iterable[Marker]) -> list[str]:
        """Apply the markers in order; return what was skipped and why (empty when all were used)."""
        problems = []
        for marker in getattr(markers, "markers", markers):
            if marker.action == Marker.DELETEALL:
                if marker.ns in ("", self.namespace):
                    self._by_key.clear()
                continue
            if marker.ns != self.namespace:
                continue
            key = (marker.ns, marker.id)
            if marker.action == Marker.DELETE:
                self._by_key.pop(key, None)
                continue
            if marker.action != Marker.ADD:
                problems.append(f"marker {marker.ns}/{marker.id}: unknown action {marker.action}; skipped")
                continue
            try:
                obstacle = marker_obstacle(marker)
            except ValueError as err:
                problems.append(f"marker {marker.ns}/{marker.id}: {err}; skipped")
                self._by_key.pop(key, None)  # a replaced marker that we cannot use is gone all the same
                continue
            if obstacle is None:
                self._by_key.pop(key, None)
            else:
                self._by_key[key] = obstacle
        return problems

    def obstacles(self) -> list[Obstacle]:
        return [self._by_key[k] for k in sorted(self._by_key)]


def marker_obstacle(marker: Marker) -> Obstacle | None:
    """One marker in map as an Obstacle: its real shape and bounding sphere (None for a point marker without
    points); ValueError if unusable."""
    if marker.header.frame_id not in MAP_FRAMES:
        raise ValueError(f"in frame {marker.header.frame_id!r}, not map (no tf lookup here)")
    kind = _MARKER_TYPES.get(marker.type, f"type {marker.type}")
    scale = np.array([marker.scale.x, marker.scale.y, marker.scale.z], dtype=float)
    if not np.all(np.isfinite(scale)):
        raise ValueError(f"{kind} with a non-finite scale {scale.tolist()}")
    scale = np.abs(scale)
    position = np.array([marker.pose.position.x, marker.pose.position.y, marker.pose.position.z], dtype=float)
    q = marker.pose.orientation
    rotation = _rotation(q.x, q.y, q.z, q.w)
    name = marker.text.strip() or f"obstacle_{marker.id}"

    if marker.type == Marker.CUBE:
        return Obstacle(name, position, float(np.linalg.norm(scale)) / 2.0, (Box(position, rotation, scale / 2.0),))
    if marker.type == Marker.SPHERE:
        if np.ptp(scale) == 0.0:
            return Obstacle(name, position, float(scale[0]) / 2.0)  # the bounding sphere is the shape
        # an ellipsoid (the worlds have none): its box in its own frame, which holds it
        return Obstacle(name, position, float(scale.max()) / 2.0, (Box(position, rotation, scale / 2.0),))
    if marker.type == Marker.CYLINDER:
        radius = max(scale[0], scale[1]) / 2.0  # an elliptic section is held by the circle of its larger axis
        return Obstacle(name, position, float(math.hypot(2.0 * radius, scale[2])) / 2.0,
                        (Cylinder(position, rotation, radius, scale[2] / 2.0),))

    item = {  # half the size of what is drawn at each point
        Marker.TRIANGLE_LIST: 0.0,
        Marker.LINE_LIST: scale[0] / 2.0,
        Marker.LINE_STRIP: scale[0] / 2.0,
        Marker.POINTS: max(scale[0], scale[1]) / 2.0,
        Marker.SPHERE_LIST: scale.max() / 2.0,
        Marker.CUBE_LIST: float(np.linalg.norm(scale)) / 2.0,
    }.get(marker.type)
    if item is None:
        raise ValueError(f"a {kind} marker has no size MAGNA can bound (use CUBE, SPHERE, CYLINDER or TRIANGLE_LIST)")
    if not marker.points:
        return None
    points = np.array([[p.x, p.y, p.z] for p in marker.points], dtype=float)
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{kind} with non-finite points")
    if marker.type == Marker.TRIANGLE_LIST:
        points = points * scale
    mid = (points.min(axis=0) + points.max(axis=0)) / 2.0
    radius, centre = min((float(np.linalg.norm(points - c, axis=1).max()), i) for i, c in enumerate((np.zeros(3), mid)))
    local = mid if centre == 1 else np.zeros(3)
    in_map = points @ rotation.T + position
    return Obstacle(name, position + rotation @ local, radius + float(item),
                    _point_parts(marker.type, in_map, rotation, scale, float(item)))


def _point_parts(kind: int, points: np.ndarray, rotation: np.ndarray, scale: np.ndarray, item: float) -> tuple:
    """The solids of a marker drawn at points (already in map): what the gaps are measured to."""
    if kind == Marker.TRIANGLE_LIST:
        whole = len(points) // 3 * 3  # rviz draws whole triangles only
        if whole == 0:
            return tuple(Sphere(p, 0.0) for p in points)
        return (Mesh(points[:whole].reshape(-1, 3, 3)),)
    if kind in (Marker.LINE_LIST, Marker.LINE_STRIP):
        if len(points) < 2:
            return (Sphere(points[0], item),)
        pairs = (points[0:len(points) // 2 * 2:2], points[1:len(points) // 2 * 2:2]) if kind == Marker.LINE_LIST \
            else (points[:-1], points[1:])
        return tuple(Capsule(a, b, item) for a, b in zip(*pairs, strict=True))
    if kind == Marker.CUBE_LIST:
        return tuple(Box(p, rotation, scale / 2.0) for p in points)
    return tuple(Sphere(p, item) for p in points)  # POINTS (squares facing the camera), SPHERE_LIST


def _rotate_out_of_body(orientation_xyzw, vector) -> tuple[float, float, float]:
    """A body-frame vector in map (R v, R from the unit quaternion), in plain floats: numpy is slower at this size."""
    x, y, z, w = (float(c) for c in orientation_xyzw)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or norm < 1e-9:
        x, y, z, w = 0.0, 0.0, 0.0, 1.0
    else:
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
    vx, vy, vz = (float(c) for c in vector)
    # R v = v + 2 q x (q x v + w v), q = (x, y, z)
    tx, ty, tz = y * vz - z * vy + w * vx, z * vx - x * vz + w * vy, x * vy - y * vx + w * vz
    return (vx + 2.0 * (y * tz - z * ty), vy + 2.0 * (z * tx - x * tz), vz + 2.0 * (x * ty - y * tx))


def _rotation(x: float, y: float, z: float, w: float) -> np.ndarray:
    q = np.array([x, y, z, w], dtype=float)
    norm = float(np.linalg.norm(q))
    if not math.isfinite(norm) or norm < 1e-9:  # rviz draws an all-zero quaternion as identity
        return np.eye(3)
    x, y, z, w = q / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


# --- depth images -----------------------------------------------------------------------------------------------

def depth_image(msg: Image) -> np.ndarray:
    """A depth image as a (height, width) float array in metres; NaN where there is no reading."""
    encodings = {"32FC1": ("f4", 4), "16UC1": ("u2", 2)}  # 16UC1: millimetres, 0 = no reading
    if msg.encoding not in encodings:
        raise ValueError(f"depth image encoding {msg.encoding!r} is not supported; publish 32FC1 (m) or 16UC1 (mm)")
    code, size = encodings[msg.encoding]
    if msg.step < msg.width * size or len(msg.data) < msg.step * msg.height:
        raise ValueError(f"depth image of {msg.width}x{msg.height} has step {msg.step} and {len(msg.data)} "
                         f"bytes; expected step >= {msg.width * size} and {msg.step * msg.height} bytes")
    dtype = np.dtype(code).newbyteorder(">" if msg.is_bigendian else "<")
    rows = np.frombuffer(bytes(msg.data), dtype=np.uint8, count=msg.step * msg.height).reshape(msg.height, msg.step)
    image = rows[:, :msg.width * size].copy().view(dtype).reshape(msg.height, msg.width).astype(float)
    if msg.encoding == "16UC1":
        image[image == 0] = np.nan
        image /= 1000.0
    return image


# --- the updater ------------------------------------------------------------------------------------------------

def _stamp_ns(msg, now: float) -> int:
    """The message's header stamp in ns, or `now` (when it came) if it has none; never 0 (0 means none heard)."""
    stamp = msg.header.stamp
    return int(stamp.secs) * 10**9 + int(stamp.nsecs) or max(1, round(now * 1e9))


class ViewLock:
    """The lock of one view, with a one-message mailbox for whoever must not wait for it.

    `with lock:` as a threading.Lock. A control step holds it for the whole step, UAL service calls
    included, which can take a while. The swarm's state comes on one subscription for every manager
    of a host, one member after the other: waiting for one busy manager would hold back the others'
    views (stale poses, ORCA-3D flying on them). `apply_or_leave(apply)` therefore runs `apply` under
    the lock only when it is free; else it leaves `apply` for the next holder, which runs it on
    taking the lock, before reading anything. A newer message replaces one left waiting, and one
    applied at once drops it: the messages come in order, so only the newest counts.
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._mailbox = threading.Lock()  # taken briefly, never while waiting for `_lock`
        self._waiting: Callable[[], None] | None = None

    def __enter__(self) -> ViewLock:
        self._lock.acquire()
        with self._mailbox:
            waiting, self._waiting = self._waiting, None
        if waiting is not None:
            try:
                waiting()
            except BaseException:
                self._lock.release()
                raise
        return self

    def __exit__(self, *exc) -> None:
        self._lock.release()

    def apply_or_leave(self, apply: Callable[[], None]) -> bool:
        """True when `apply` ran now; False when it was left for the lock's next holder."""
        if not self._lock.acquire(blocking=False):
            with self._mailbox:
                self._waiting = apply
            return False
        try:
            with self._mailbox:
                self._waiting = None  # older than `apply`
            apply()
        finally:
            self._lock.release()
        return True


class WorldUpdater:
    """Turns UAL, battery, depth and marker messages into WorldView updates, under `lock`."""

    def __init__(self, view: WorldView, agent_ids: Iterable[int], safety_radii: dict[int, float]):
        self.view = view
        ids = sorted({int(i) for i in agent_ids} | {view.own_id})
        missing = [i for i in ids if i not in safety_radii]
        if missing:
            raise ValueError(f"safety_radii: no safety radius for UAV {', '.join(map(str, missing))}; give one per "
                             f"agent id (the airframe's safety_radius, e.g. UavConfig.safety_radius)")
        self.agent_ids = ids
        self.lock = ViewLock()
        self._records = {i: AgentState(id=i, safety_radius=float(safety_radii[i])) for i in ids}
        self._posed: set[int] = set()
        self.markers = ObstacleMarkers()
        self.marker_problems: list[str] = []  # what the last marker message had that was skipped

    def heard(self, agent_id: int) -> AgentState:
        """The latest state heard of one UAV, whether or not its pose has come (it is in the view only then)."""
        with self.lock:
            return self._records[agent_id]

    def on_pose(self, agent_id: int, msg: PoseStamped, now: float = 0.0) -> None:
        p, q = msg.pose.position, msg.pose.orientation
        stamp = msg.header.stamp.to_sec() or now
        self._update(agent_id, position=(p.x, p.y, p.z), orientation=(q.x, q.y, q.z, q.w), stamp=stamp,
                     pose_stamp_ns=_stamp_ns(msg, now), pose=True)

    def on_velocity(self, agent_id: int, msg: TwistStamped, now: float = 0.0) -> None:
        v = msg.twist.linear
        self._update(agent_id, velocity=(v.x, v.y, v.z), yaw_rate=float(msg.twist.angular.z),
                     velocity_stamp_ns=_stamp_ns(msg, now))

    def on_odom(self, agent_id: int, msg: Odometry, now: float = 0.0) -> None:
        """Pose and velocity at once; the twist is in the body frame (child_frame_id), turned into map."""
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        orientation = (q.x, q.y, q.z, q.w)
        linear, angular = msg.twist.twist.linear, msg.twist.twist.angular
        velocity = _rotate_out_of_body(orientation, (linear.x, linear.y, linear.z))
        spin = _rotate_out_of_body(orientation, (angular.x, angular.y, angular.z))
        stamp = msg.header.stamp.to_sec() or now
        stamp_ns = _stamp_ns(msg, now)
        self._update(agent_id, position=(p.x, p.y, p.z), orientation=orientation, velocity=velocity,
                     yaw_rate=spin[2], stamp=stamp, pose_stamp_ns=stamp_ns, velocity_stamp_ns=stamp_ns, pose=True)

    def on_swarm(self, msg: SwarmState, now: float = 0.0, only: Iterable[int] | None = None) -> None:
        """Pose, velocity and UAL state of every UAV of the message that this view holds (of `only`, when given),
        exactly as its UAL topics give them: the same position, orientation and stamp, the velocity already in map,
        the yaw rate the map z of the angular velocity. A message without states (an older publisher) leaves the
        UAL states as they were. ValueError if the arrays do not match the ids."""
        count = len(msg.ids)
        if not (len(msg.poses) == len(msg.velocities) == len(msg.angular_velocities) == count
                and len(msg.states) in (0, count)):
            raise ValueError(f"swarm state with {count} ids, {len(msg.poses)} poses, {len(msg.velocities)} "
                             f"velocities, {len(msg.angular_velocities)} angular velocities and {len(msg.states)} "
                             f"states; each array needs one entry per id (states may be empty)")
        states = msg.states
        wanted = self._records.keys() if only is None else set(only) & self._records.keys()
        stamp = msg.header.stamp.to_sec() or now
        stamp_ns = _stamp_ns(msg, now)

        def apply() -> None:  # the whole swarm at once: a control step never sees half of one instant
            for index, agent_id in enumerate(msg.ids):
                if agent_id not in wanted:
                    continue
                pose, linear = msg.poses[index], msg.velocities[index]
                p, q = pose.position, pose.orientation
                ual_state = {"ual_state": int(states[index])} if states else {}
                self._update_held(agent_id, position=(p.x, p.y, p.z), orientation=(q.x, q.y, q.z, q.w),
                                  velocity=(linear.x, linear.y, linear.z),
                                  yaw_rate=float(msg.angular_velocities[index].z), stamp=stamp,
                                  pose_stamp_ns=stamp_ns, velocity_stamp_ns=stamp_ns, pose=True, **ual_state)

        self.lock.apply_or_leave(apply)  # a manager busy in its step takes it when its next step begins

    def on_state(self, agent_id: int, msg: State) -> None:
        self._update(agent_id, ual_state=int(msg.state))

    def on_battery(self, agent_id: int, msg: BatteryState) -> None:
        self._update(agent_id, battery=float(msg.percentage))

    def on_depth(self, agent_id: int, msg: Image) -> None:
        image = depth_image(msg)  # decoded outside the lock
        self._update(agent_id, depth=image)

    def on_markers(self, msg: MarkerArray) -> list[str]:
        with self.lock:
            self.marker_problems = self.markers.apply(msg)
            self.view.set_obstacles(self.markers.obstacles())
            return self.marker_problems

    def _update(self, agent_id: int, pose: bool = False, **values) -> None:
        with self.lock:
            self._update_held(agent_id, pose, **values)

    def _update_held(self, agent_id: int, pose: bool = False, **values) -> None:
        """_update with `lock` already held."""
        state = dataclasses.replace(self._records[agent_id], **values)
        self._records[agent_id] = state
        if pose:
            self._posed.add(agent_id)
        if agent_id in self._posed:
            self.view.update_agent(state)


class SwarmFeed:
    """One subscription to the swarm's state, handed to every view of the process that joined it.

    `join(updater, ids)` makes `updater.on_swarm` take the UAVs `ids` from each message; `leave(updater)`
    stops it. The subscription is made at the first join (`subscribe(topic, callback)` returns a handle
    with `unregister()`; rospy.Subscriber when not given), and ends with `close()`.
    """

    def __init__(self, topic: str = names.SIM_SWARM_STATE, subscribe: Callable | None = None,
                 clock: Callable[[], float] | None = None):
        self.topic = topic
        self._subscribe = subscribe
        self._clock = clock
        self._lock = threading.Lock()
        self._members: dict[int, tuple[WorldUpdater, frozenset[int]]] = {}  # by id(updater)
        self._subscription = None

    def join(self, updater: WorldUpdater, ids: Iterable[int]) -> None:
        with self._lock:
            self._members[id(updater)] = (updater, frozenset(int(i) for i in ids))
            if self._subscription is None:
                self._subscription = self._make_subscription()

    def leave(self, updater: WorldUpdater) -> None:
        with self._lock:
            self._members.pop(id(updater), None)

    @property
    def members(self) -> int:
        with self._lock:
            return len(self._members)

    def deliver(self, msg: SwarmState, now: float | None = None) -> list[str]:
        """Hand one message to every member; returns what a member refused (one line each)."""
        if now is None:
            now = self._clock() if self._clock is not None else 0.0
        with self._lock:
            members = list(self._members.values())
        problems = []
        for updater, ids in members:
            try:
                updater.on_swarm(msg, now, ids)
            except ValueError as error:  # a bad message: every member would refuse it alike
                problems.append(f"{self.topic}: {error}")
                break
        return problems

    def close(self) -> None:
        with self._lock:
            subscription, self._subscription = self._subscription, None
            self._members.clear()
        if subscription is not None:
            subscription.unregister()

    def _make_subscription(self):
        if self._subscribe is not None:
            return self._subscribe(self.topic, self.deliver)
        import rospy

        if self._clock is None:
            self._clock = rospy.get_time

        def callback(msg: SwarmState) -> None:
            for problem in self.deliver(msg):
                rospy.logerr_throttle(5.0, problem)

        return rospy.Subscriber(self.topic, SwarmState, callback, queue_size=1, tcp_nodelay=True)


class RosWorldData(WorldUpdater):
    """WorldUpdater wired to the topics; `close()` (or leaving a `with` block) unsubscribes.

    With `swarm`, the UAVs come from that feed, the own one too, except those in `odom_ids` (the hil and real
    ones, which magna_sim does not fly): such an own UAV is heard on its pose, velocity and state topics; the
    others, and without a feed every other UAV, on their odom. An own UAV from the feed saves a host three
    30 Hz subscriptions per manager, its largest share of messages; the battery (1 Hz) stays a topic.
    """

    def __init__(self, view: WorldView, agent_ids: list[int], safety_radii: dict[int, float], depth: bool = False,
                 markers_topic: str = names.WORLD_MARKERS, swarm: SwarmFeed | None = None,
                 odom_ids: Iterable[int] = ()):
        import rospy  # here, so that the rest of the module loads without a ROS environment being up

        super().__init__(view, agent_ids, safety_radii)
        self._rospy = rospy
        self._subscribers: list[rospy.Subscriber] = []
        others = [i for i in self.agent_ids if i != view.own_id]
        not_simulated = {int(i) for i in odom_ids}
        odom = set(others) if swarm is None else not_simulated & set(others)
        own_from_swarm = swarm is not None and view.own_id not in not_simulated
        self._swarm = swarm
        view.own_pose_topic = topics(view.own_id)["pose"]
        if swarm is not None:
            swarm.join(self, [i for i in self.agent_ids if i not in odom and (i != view.own_id or own_from_swarm)])
            if own_from_swarm:
                view.own_pose_topic = swarm.topic

        def sub(topic, msg_type, handler, *args):
            self._subscribers.append(rospy.Subscriber(topic, msg_type, self._guard(handler, topic), callback_args=args,
                                                      queue_size=1, tcp_nodelay=True))

        own = topics(view.own_id)
        if not own_from_swarm:
            sub(own["pose"], PoseStamped, self._pose, view.own_id)
            sub(own["velocity"], TwistStamped, self._velocity, view.own_id)
            sub(own["state"], State, self.on_state, view.own_id)
        for i in sorted(odom):
            sub(topics(i)["odom"], Odometry, self._odom, i)
        sub(own["battery"], BatteryState, self.on_battery, view.own_id)
        if depth:
            sub(own["depth"], Image, self.on_depth, view.own_id)
        sub(markers_topic, MarkerArray, self._markers)

    @property
    def topics_heard(self) -> list[str]:
        """The topics this view subscribes to itself (the swarm's feed aside)."""
        return [subscriber.name for subscriber in self._subscribers]

    def _pose(self, agent_id: int, msg: PoseStamped) -> None:
        self.on_pose(agent_id, msg, now=self._rospy.get_time())

    def _velocity(self, agent_id: int, msg: TwistStamped) -> None:
        self.on_velocity(agent_id, msg, now=self._rospy.get_time())

    def _odom(self, agent_id: int, msg: Odometry) -> None:
        self.on_odom(agent_id, msg, now=self._rospy.get_time())

    def _markers(self, msg: MarkerArray) -> None:
        for problem in self.on_markers(msg):
            self._rospy.logwarn("world markers: %s", problem)

    def _guard(self, handler, topic: str):
        def callback(msg, args):
            try:
                handler(*args, msg)
            except ValueError as err:  # a bad message must not kill the subscriber thread silently
                self._rospy.logerr_throttle(5.0, f"{topic}: {err}")
        return callback

    def close(self) -> None:
        if self._swarm is not None:
            self._swarm.leave(self)
            self._swarm = None
        for subscriber in self._subscribers:
            subscriber.unregister()
        self._subscribers = []

    def __enter__(self) -> RosWorldData:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
