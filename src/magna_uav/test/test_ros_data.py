"""World data from ROS messages: obstacle markers, depth images and agent updates without a master; one live test."""
import json
import math
import struct
import threading

import numpy as np
import pytest
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, TwistStamped, Vector3
from magna_msgs.msg import SwarmState
from nav_msgs.msg import Odometry
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import BatteryState, Image
from uav_abstraction_layer.msg import State
from visualization_msgs.msg import Marker, MarkerArray

from magna_common import ros_names as names
from magna_uav.ros_data import (
    ObstacleMarkers,
    SwarmFeed,
    ViewLock,
    WorldUpdater,
    depth_image,
    marker_obstacle,
    obstacles_from_markers,
)
from magna_uav.world_view import AgentState, WorldView
from tests.support import CORPUS, wait_until

YAW_90 = Quaternion(0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5))


def marker(kind, marker_id=0, ns="obstacles", scale=(1, 1, 1), position=(0, 0, 0), orientation=None, points=(),
           action=Marker.ADD, frame="map", text=""):
    m = Marker(type=kind, id=marker_id, ns=ns, action=action, text=text, scale=Vector3(*scale),
               pose=Pose(position=Point(*position), orientation=orientation or Quaternion(0, 0, 0, 1)))
    m.header.frame_id = frame
    m.points = [Point(*p) for p in points]
    return m


# --- markers ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind, scale, radius", [
    (Marker.CUBE, (2, 3, 6), 3.5),  # half the diagonal: sqrt(4 + 9 + 36) / 2
    (Marker.SPHERE, (3, 3, 3), 1.5),
    (Marker.CYLINDER, (6, 6, 8), 5.0),  # corner of the (radius 3, half-height 4) section
])
def test_primitive_markers_are_bounded_by_their_scale(kind, scale, radius):
    (obstacle,) = obstacles_from_markers(MarkerArray([marker(kind, 7, scale=scale, position=(1, 2, 3))]))
    assert obstacle.name == "obstacle_7"
    assert obstacle.radius == pytest.approx(radius)
    np.testing.assert_allclose(obstacle.position, [1, 2, 3])


def test_a_triangle_list_is_bounded_by_its_points_moved_by_the_pose():
    # a prism-like mesh whose points lie from x=4..6 in its own frame: the box centre (5, 0, 1) beats the origin
    points = [(4, -1, 0), (6, -1, 0), (6, 1, 2), (4, 1, 2), (5, 0, 0), (5, 0, 2)]
    o = marker_obstacle(marker(Marker.TRIANGLE_LIST, points=points, position=(10, 0, 0), orientation=YAW_90))
    np.testing.assert_allclose(o.position, [10, 5, 1], atol=1e-12)  # (5, 0, 1) turned 90 degrees about z
    assert o.radius == pytest.approx(math.sqrt(3))
    # rviz scales a triangle list's points by `scale`
    scaled = marker_obstacle(marker(Marker.TRIANGLE_LIST, points=points, scale=(2, 2, 2)))
    assert scaled.radius == pytest.approx(2 * math.sqrt(3))


def test_points_about_the_origin_keep_the_origin_as_centre():
    # the box centre would be (0, 0, 0.45), needing a radius of 1.097; the origin needs only 1.0
    points = [(-1, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 0.9)]
    o = marker_obstacle(marker(Marker.LINE_LIST, points=points, scale=(0.2, 0, 0), position=(0, 0, 5)))
    np.testing.assert_allclose(o.position, [0, 0, 5])
    assert o.radius == pytest.approx(1.0 + 0.1)  # plus half the line width


def test_only_the_obstacle_namespace_counts_and_actions_apply_in_order():
    table = ObstacleMarkers()
    problems = table.apply(MarkerArray([
        marker(Marker.CUBE, 0, ns="geometries", scale=(9, 9, 9)),
        marker(Marker.SPHERE, 0, scale=(1, 1, 1), text="rock"),
        marker(Marker.SPHERE, 1, scale=(2, 2, 2)),
        marker(Marker.SPHERE, 2, scale=(4, 4, 4)),
        marker(Marker.SPHERE, 2, action=Marker.DELETE),
        marker(Marker.SPHERE, 1, scale=(6, 6, 6)),  # ADD on an existing (ns, id) replaces it
    ]))
    assert problems == []
    assert [(o.name, o.radius) for o in table.obstacles()] == [("rock", 0.5), ("obstacle_1", 3.0)]
    table.apply(MarkerArray([marker(Marker.SPHERE, 0, action=Marker.DELETEALL, ns="geometries")]))
    assert len(table.obstacles()) == 2  # another namespace's DELETEALL leaves ours alone
    table.apply(MarkerArray([Marker(action=Marker.DELETEALL), marker(Marker.CUBE, 5, scale=(2, 2, 2))]))
    assert [o.name for o in table.obstacles()] == ["obstacle_5"]


def test_unusable_markers_are_skipped_and_said():
    table = ObstacleMarkers()
    table.apply(MarkerArray([marker(Marker.SPHERE, 3, scale=(1, 1, 1))]))
    problems = table.apply(MarkerArray([
        marker(Marker.MESH_RESOURCE, 3),  # replaces the sphere 3 with something we cannot bound
        marker(Marker.CUBE, 4, frame="uav_1/base_link"),
        marker(Marker.TRIANGLE_LIST, 5),  # no points: nothing to avoid
    ]))
    assert problems == [
        "marker obstacles/3: a MESH_RESOURCE marker has no size MAGNA can bound "
        "(use CUBE, SPHERE, CYLINDER or TRIANGLE_LIST); skipped",
        "marker obstacles/4: in frame 'uav_1/base_link', not map (no tf lookup here); skipped",
    ]
    assert table.obstacles() == []


def test_markers_of_the_world_node_become_obstacles():
    from magna_worlds.markers import world_markers
    from magna_worlds.registry import WorldRegistry

    # Delivery has sphere and cube obstacles (matrix pose sets) and many geofence geometries
    world = WorldRegistry(seed=1).add_file("main", CORPUS / "Worlds" / "Delivery" / "Delivery.json")
    expected = world.obstacles()
    assert {o.shape for o in expected} == {"sphere", "cube"}
    obstacles = obstacles_from_markers(world_markers([world]))
    assert len(obstacles) == len(expected)
    for got, want in zip(obstacles, expected, strict=True):
        assert got.name == want.name  # the world's obstacle names ({volPrefix}_{geomPrefix}_obs_{n})
        np.testing.assert_allclose(got.position, want.position, atol=1e-9)
        bound = want.dimensions[0] / 2 if want.shape == "sphere" else np.linalg.norm(want.dimensions) / 2
        assert got.radius == pytest.approx(bound)


def test_markers_keep_their_real_shape_for_the_gaps():
    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 0], safety_radius=0.0))

    def distance(m, point):
        view.set_obstacles([marker_obstacle(m)])
        view.update_agent(AgentState(1, point, safety_radius=0.0))
        return view.nearest_obstacles()[0][1]

    cube = marker(Marker.CUBE, scale=(10, 2, 2), position=(0, 0, 5), orientation=YAW_90)  # long side along y
    assert distance(cube, (0, 8, 5)) == pytest.approx(3.0) and distance(cube, (4, 0, 5)) == pytest.approx(3.0)
    assert distance(cube, (0, 0, 5.5)) == pytest.approx(-0.5)
    cylinder = marker(Marker.CYLINDER, scale=(2, 2, 10), position=(0, 0, 5))
    assert distance(cylinder, (4, 0, 5)) == pytest.approx(3.0) and distance(cylinder, (0, 0, 12)) == pytest.approx(2.0)
    sphere = marker(Marker.SPHERE, scale=(2, 2, 2))
    assert marker_obstacle(sphere).parts == () and distance(sphere, (0, 3, 0)) == pytest.approx(2.0)
    # a triangle list is measured to its triangles: one triangle in the plane z = 0, moved up 1 m
    triangle = marker(Marker.TRIANGLE_LIST, points=[(0, 0, 0), (4, 0, 0), (0, 4, 0)], position=(0, 0, 1))
    assert distance(triangle, (1, 1, 3)) == pytest.approx(2.0) and distance(triangle, (-3, 0, 1)) == pytest.approx(3)
    line = marker(Marker.LINE_STRIP, points=[(0, 0, 0), (10, 0, 0), (10, 10, 0)], scale=(0.2, 0, 0))
    assert distance(line, (5, 2, 0)) == pytest.approx(1.9) and distance(line, (12, 5, 0)) == pytest.approx(1.9)


def test_the_power_lines_of_a_world_are_measured_as_wires():
    """A world like the original GAUSSUseCase1 power line: two 400 m x 0.3 m wires 25 m up, along x."""
    from magna_worlds.markers import world_markers
    from magna_worlds.registry import WorldRegistry

    wires = {"name": "Wires", "prefix": "w", "shape": "cylinder", "dimensions": [4.0, 4.0, 400.0],
             "origin": [[-600.0, 0.0, 25.0], [0, math.pi / 2, 0]],  # roll, pitch, yaw: the axis lies along x
             "poses_sets": [{"type": "coordinates", "use": "obstacles", "obstacles_shape": ["cylinder"],
                             "obstacles_dimensions": [0.3, 0.3, 400],
                             "coordinates": [[[0, 1.5, 0], [0, 0, 0]], [[0, -1.5, 0], [0, 0, 0]]]}]}
    world = {"scenario": {"world_boundaries": [[-1000, 1000], [-1000, 1000], [-10, 500]], "volumes": [
        {"name": "Line", "prefix": "line", "origin": [[0.0, 100.0, 0.0], [0, 0, 0]], "geometries": [wires]}]}}
    part = WorldRegistry(seed=1).add_inline("line", json.dumps(world))
    obstacles = obstacles_from_markers(world_markers([part]))
    assert [o.name for o in obstacles] == ["line_w_obs_0", "line_w_obs_1"]
    assert all(o.radius > 199.0 for o in obstacles)  # the bounding spheres are useless for gaps
    view = WorldView(1)
    view.set_obstacles(obstacles)
    view.update_agent(AgentState(1, [-500, 100, 25 + 95], safety_radius=1.0))
    gaps = [gap for _, gap in view.nearest_obstacles()]
    assert gaps == pytest.approx([math.hypot(95, 1.5) - 0.15 - 1.0] * 2)
    view.update_agent(AgentState(1, [-790, 101.5, 26.0], safety_radius=1.0))  # 1 m over one wire, near its end
    (first, gap), (_, other) = view.nearest_obstacles()
    assert first.name == "line_w_obs_0" and gap == pytest.approx(1 - 0.15 - 1.0)
    assert other == pytest.approx(math.hypot(3, 1) - 0.15 - 1.0)


# --- depth -----------------------------------------------------------------------------------------------------

def test_depth_images_decode_to_metres_with_row_padding():
    values = [1.5, 2.0, math.inf, 0.25, 3.0, 4.0]
    rows = [struct.pack("<3f", *values[:3]) + b"\0" * 4, struct.pack("<3f", *values[3:]) + b"\0" * 4]
    image = depth_image(Image(height=2, width=3, encoding="32FC1", step=16, data=b"".join(rows)))
    np.testing.assert_array_equal(image, np.array(values).reshape(2, 3))
    big = depth_image(Image(height=1, width=2, encoding="32FC1", is_bigendian=1, step=8, data=struct.pack(">2f", 1, 2)))
    np.testing.assert_array_equal(big, [[1.0, 2.0]])
    mm = depth_image(Image(height=1, width=2, encoding="16UC1", step=4, data=struct.pack("<2H", 1500, 0)))
    np.testing.assert_array_equal(mm, [[1.5, np.nan]])


def test_bad_depth_images_are_refused():
    with pytest.raises(ValueError, match="encoding 'rgb8' is not supported; publish 32FC1"):
        depth_image(Image(height=1, width=1, encoding="rgb8", step=3, data=b"abc"))
    with pytest.raises(ValueError, match="expected step >= 12 and 12 bytes"):
        depth_image(Image(height=1, width=3, encoding="32FC1", step=12, data=b"\0" * 8))


# --- agent updates ---------------------------------------------------------------------------------------------

def pose(x, y, z, stamp=0.0):
    msg = PoseStamped(pose=Pose(position=Point(x, y, z), orientation=YAW_90))
    msg.header.frame_id = "map"
    msg.header.stamp.secs, msg.header.stamp.nsecs = int(stamp), int(round(stamp % 1 * 1e9))
    return msg


def twist(vx, vy, vz, yaw_rate):
    msg = TwistStamped()
    msg.twist.linear, msg.twist.angular.z = Vector3(vx, vy, vz), yaw_rate
    return msg


def test_an_agent_enters_the_view_at_its_first_pose_with_what_was_heard_before():
    view = WorldView(1)
    data = WorldUpdater(view, [2], {1: 0.3, 2: 0.5})
    assert data.agent_ids == [1, 2]  # own id always
    data.on_velocity(2, twist(1, 2, 3, 0.5))
    data.on_state(2, State(state=State.FLYING_AUTO))
    data.on_battery(2, BatteryState(percentage=0.4))
    assert view.agent(2) is None  # no made-up position at the origin
    assert data.heard(2).ual_state == State.FLYING_AUTO
    data.on_pose(2, pose(4, 5, 6, stamp=12.5))
    a = view.agent(2)
    np.testing.assert_allclose(a.position, [4, 5, 6])
    np.testing.assert_allclose(a.velocity, [1, 2, 3])
    assert (a.yaw_rate, a.ual_state, a.battery, a.stamp, a.safety_radius) == (0.5, 4, pytest.approx(0.4), 12.5, 0.5)
    assert a.yaw == pytest.approx(math.pi / 2)
    before = view.agent(2)
    data.on_battery(2, BatteryState(percentage=0.3))
    assert view.agent(2) is not before and before.battery == pytest.approx(0.4)  # replaced, never changed in place
    data.on_pose(1, pose(0, 0, 0), now=7.0)
    assert view.own.stamp == 7.0  # a pose without a stamp takes the receive time
    # the exact stamps of the messages held, in ns, for the recorder to name them; velocity 0: none heard
    assert (a.pose_stamp_ns, a.velocity_stamp_ns) == (12_500_000_000, 1)  # unstamped, heard at now=0
    assert (view.own.pose_stamp_ns, view.own.velocity_stamp_ns) == (7_000_000_000, 0)
    stamped = twist(0, 0, 0, 0.0)
    stamped.header.stamp.secs, stamped.header.stamp.nsecs = 13, 33_333_333
    data.on_velocity(1, stamped, now=99.0)
    assert view.own.velocity_stamp_ns == 13_033_333_333
    assert view.nearest_agents()[0][1] == pytest.approx(math.sqrt(16 + 25 + 36) - 0.8)


def odom(x, y, z, body_velocity, body_spin=(0.0, 0.0, 0.0), orientation=YAW_90, stamp=0.0):
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = "map", "uav/base_link"
    msg.header.stamp.secs, msg.header.stamp.nsecs = int(stamp), int(round(stamp % 1 * 1e9))
    msg.pose.pose = Pose(position=Point(x, y, z), orientation=orientation)
    msg.twist.twist.linear, msg.twist.twist.angular = Vector3(*body_velocity), Vector3(*body_spin)
    return msg


def test_odom_gives_pose_and_the_body_twist_turned_into_map():
    view = WorldView(1)
    data = WorldUpdater(view, [2], {1: 0.3, 2: 0.5})
    data.on_odom(2, odom(4, 5, 6, body_velocity=(1.0, 0.0, 0.5), body_spin=(0.0, 0.0, 0.3), stamp=2.5))
    a = view.agent(2)
    np.testing.assert_allclose(a.position, [4, 5, 6])
    # yawed 90 degrees: the body's x axis is map's y
    np.testing.assert_allclose(a.velocity, [0.0, 1.0, 0.5], atol=1e-12)
    assert (a.yaw, a.yaw_rate, a.stamp) == (pytest.approx(math.pi / 2), pytest.approx(0.3), 2.5)
    assert a.pose_stamp_ns == a.velocity_stamp_ns == 2_500_000_000  # both from the one message


@pytest.mark.parametrize("seed", range(5))
def test_odom_velocity_matches_the_rotation_matrix_for_any_attitude(seed):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    q *= 3.0 / np.linalg.norm(q)  # not unit: the rotation must not scale the velocity
    body = rng.normal(size=3)
    data = WorldUpdater(WorldView(1), [2], {1: 0.3, 2: 0.5})
    data.on_odom(2, odom(0, 0, 0, body_velocity=body, orientation=Quaternion(*q)))
    x, y, z, w = q / np.linalg.norm(q)
    rotation = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    np.testing.assert_allclose(data.view.agent(2).velocity, rotation @ body, atol=1e-12)


def swarm_of(odoms: dict, stamp: float, states: dict | None = None) -> SwarmState:
    """The SwarmState magna_sim publishes with these odom messages (and UAL states, by id, when given): the same
    poses, the velocities in map."""
    msg = SwarmState()
    msg.header.stamp.secs, msg.header.stamp.nsecs = int(stamp), int(round(stamp % 1 * 1e9))
    msg.header.frame_id = "map"
    for uav_id in sorted(odoms):
        o = odoms[uav_id]
        q = o.pose.pose.orientation
        rotation = Rotation.from_quat([q.x, q.y, q.z, q.w])
        linear, angular = o.twist.twist.linear, o.twist.twist.angular
        msg.ids.append(uav_id)
        msg.poses.append(o.pose.pose)
        msg.velocities.append(Vector3(*rotation.apply([linear.x, linear.y, linear.z])))
        msg.angular_velocities.append(Vector3(*rotation.apply([angular.x, angular.y, angular.z])))
    if states is not None:
        msg.states = bytes(states[uav_id] for uav_id in sorted(odoms))
    return msg


@pytest.mark.parametrize("seed", range(3))
def test_the_swarm_gives_each_uav_exactly_what_its_odom_gives(seed):
    rng = np.random.default_rng(seed)
    odoms = {}
    for uav_id in (1, 2, 3, 4):
        q = rng.normal(size=4)
        odoms[uav_id] = odom(*rng.uniform(-20, 20, size=3), body_velocity=rng.normal(size=3),
                             body_spin=rng.normal(size=3), orientation=Quaternion(*(q / np.linalg.norm(q))),
                             stamp=12.345678901)
    radii = {1: 0.3, 2: 0.5, 3: 0.4, 4: 0.6}
    states = {1: State.FLYING_AUTO, 2: State.LANDED_ARMED, 3: State.TAKING_OFF, 4: State.LANDING}
    by_odom, by_swarm = WorldUpdater(WorldView(1), [2, 3, 4], radii), WorldUpdater(WorldView(1), [2, 3, 4], radii)
    for uav_id in (2, 3):
        by_odom.on_odom(uav_id, odoms[uav_id], now=99.0)
        by_odom.on_state(uav_id, State(state=states[uav_id]))
    by_swarm.on_swarm(swarm_of(odoms, 12.345678901, states), now=99.0, only=[2, 3])
    assert by_swarm.view.agent(4) is None and by_swarm.view.agent(1) is None  # only the UAVs asked for
    for uav_id in (2, 3):
        assert by_swarm.view.agent(uav_id).ual_state == by_odom.view.agent(uav_id).ual_state == states[uav_id]
        a, b = by_odom.view.agent(uav_id), by_swarm.view.agent(uav_id)
        np.testing.assert_array_equal(a.position, b.position)
        np.testing.assert_array_equal(a.orientation, b.orientation)
        np.testing.assert_allclose(b.velocity, a.velocity, rtol=0, atol=1e-12)
        assert b.yaw_rate == pytest.approx(a.yaw_rate, rel=0, abs=1e-12)
        assert (b.stamp, b.pose_stamp_ns, b.velocity_stamp_ns) == (a.stamp, a.pose_stamp_ns, a.velocity_stamp_ns)
        assert b.pose_stamp_ns == 12_345_678_901
        assert b.safety_radius == radii[uav_id]


def test_a_swarm_whose_arrays_do_not_match_its_ids_is_refused_whole():
    data = WorldUpdater(WorldView(1), [2, 3], {1: 0.3, 2: 0.5, 3: 0.5})
    msg = swarm_of({2: odom(1, 2, 3, (0, 0, 0)), 3: odom(4, 5, 6, (0, 0, 0))}, 1.0)
    msg.velocities.pop()
    with pytest.raises(ValueError, match="2 ids, 2 poses, 1 velocities, 2 angular velocities and 0 states"):
        data.on_swarm(msg)
    one_state = swarm_of({2: odom(1, 2, 3, (0, 0, 0)), 3: odom(4, 5, 6, (0, 0, 0))}, 1.0)
    one_state.states = bytes([State.FLYING_AUTO])
    with pytest.raises(ValueError, match="and 1 states; each array needs one entry per id"):
        data.on_swarm(one_state)
    assert data.view.agent(2) is None


def test_a_swarm_without_states_leaves_the_ual_states_as_they_were():
    data = WorldUpdater(WorldView(1), [2], {1: 0.3, 2: 0.5})
    data.on_state(2, State(state=State.FLYING_MANUAL))
    data.on_swarm(swarm_of({2: odom(1, 2, 3, (0, 0, 0))}, 1.0))  # an older publisher's message
    assert data.view.agent(2).ual_state == State.FLYING_MANUAL and data.view.agent(2).position[0] == 1
    data.on_swarm(swarm_of({2: odom(1, 2, 3, (0, 0, 0))}, 2.0, {2: State.LANDING}))
    assert data.view.agent(2).ual_state == State.LANDING


def test_one_swarm_feed_subscribes_once_and_feeds_every_view_its_own_uavs():
    made = []

    class Subscription:
        def __init__(self, topic, callback):
            self.topic, self.callback, self.open = topic, callback, True
            made.append(self)

        def unregister(self):
            self.open = False

    feed = SwarmFeed(subscribe=Subscription, clock=lambda: 5.0)
    radii = {1: 0.3, 2: 0.3, 3: 0.3}
    views = {i: WorldUpdater(WorldView(i), [1, 2, 3], radii) for i in (1, 2, 3)}
    for i, updater in views.items():
        feed.join(updater, [j for j in (1, 2, 3) if j != i and j != 3])  # UAV 3 flies by MAVLink: not from here
    assert len(made) == 1 and made[0].topic == names.SIM_SWARM_STATE and feed.members == 3
    made[0].callback(swarm_of({j: odom(j, 0, 0, (0, 0, 0)) for j in (1, 2, 3)}, 2.0))
    assert views[1].view.agent(2).position[0] == 2 and views[2].view.agent(1).position[0] == 1
    assert views[1].view.agent(3) is None and views[3].view.agent(3) is None  # own UAV 3: from its pose topic
    feed.leave(views[1])
    made[0].callback(swarm_of({j: odom(10 * j, 0, 0, (0, 0, 0)) for j in (1, 2, 3)}, 3.0))
    assert views[1].view.agent(2).position[0] == 2 and views[2].view.agent(1).position[0] == 10
    bad = swarm_of({1: odom(0, 0, 0, (0, 0, 0))}, 4.0)
    bad.poses.append(bad.poses[0])
    assert feed.deliver(bad) == [f"{names.SIM_SWARM_STATE}: swarm state with 1 ids, 2 poses, 1 velocities, 1 "
                                 f"angular velocities and 0 states; each array needs one entry per id (states may "
                                 f"be empty)"]
    feed.close()
    assert not made[0].open and feed.members == 0


def test_a_busy_view_does_not_hold_the_swarm_back_from_the_others():
    # Manager 1 is inside a long step (a UAL call) and holds its view's lock; the feed's one thread must
    # still hand the message to manager 2 at once, and manager 1 gets it when its next step takes the lock.
    feed = SwarmFeed(subscribe=lambda topic, callback: None, clock=lambda: 5.0)
    radii = {1: 0.3, 2: 0.3, 3: 0.3}
    views = {i: WorldUpdater(WorldView(i), [1, 2, 3], radii) for i in (1, 2)}
    for i, updater in views.items():
        feed.join(updater, [j for j in (1, 2, 3) if j != i])
    delivered = threading.Event()
    with views[1].lock:  # manager 1's step
        thread = threading.Thread(target=lambda: (feed.deliver(swarm_of({j: odom(j, 0, 0, (0, 0, 0))
                                                                          for j in (1, 2, 3)}, 2.0)),
                                                  delivered.set()))
        thread.start()
        assert delivered.wait(10), "the feed waited for a busy manager"
        assert views[2].view.agent(1).position[0] == 1  # the other manager has it now
        assert views[1].view.agent(2) is None  # not under the busy step's feet
        feed.deliver(swarm_of({j: odom(10 * j, 0, 0, (0, 0, 0)) for j in (1, 2, 3)}, 3.0))  # a newer one
    thread.join()
    with views[1].lock:  # the next step: the newest message only
        assert views[1].view.agent(2).position[0] == 20 and views[1].view.agent(3).position[0] == 30
        assert views[1].view.agent(2).stamp == 3.0


def test_a_message_left_waiting_runs_at_the_next_entry_unless_a_newer_one_ran_first():
    lock, applied = ViewLock(), []
    with lock:
        assert lock.apply_or_leave(lambda: applied.append("old")) is False
    assert applied == []  # left for the next holder
    assert lock.apply_or_leave(lambda: applied.append("new")) is True  # free: runs now, and drops "old"
    with lock:
        assert applied == ["new"]
        lock.apply_or_leave(lambda: applied.append("later"))
    with lock:
        assert applied == ["new", "later"]  # run on entry, before the holder reads anything


def test_a_waiting_message_that_fails_leaves_the_lock_free():
    lock = ViewLock()
    with lock:
        lock.apply_or_leave(lambda: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        with lock:
            pass
    assert lock.apply_or_leave(lambda: None) is True  # not left held


def test_markers_fill_the_views_obstacles():
    view = WorldView(1)
    data = WorldUpdater(view, [], {1: 0.3})
    problems = data.on_markers(MarkerArray([marker(Marker.CUBE, 0, scale=(2, 2, 2)), marker(Marker.ARROW, 1)]))
    assert [o.name for o in view.obstacles] == ["obstacle_0"] and len(problems) == 1 and "ARROW" in problems[0]


def test_every_agent_needs_a_safety_radius():
    with pytest.raises(ValueError, match="safety_radii: no safety radius for UAV 1, 3"):
        WorldUpdater(WorldView(1), [2, 3], {2: 0.3})


# --- live ------------------------------------------------------------------------------------------------------

@pytest.mark.ros
def test_topics_fill_the_view(rospy_node):
    rospy = rospy_node
    from magna_uav.ros_data import RosWorldData, topics

    own, other = 91, 92
    view = WorldView(own)
    pubs = []

    def publisher(topic, msg_type):
        pubs.append(rospy.Publisher(topic, msg_type, queue_size=1, latch=True))
        return pubs[-1]

    data = RosWorldData(view, [own, other], {own: 0.3, other: 0.4}, depth=True)
    try:
        publisher(topics(own)["velocity"], TwistStamped).publish(twist(0, 1, 0, 0.1))
        publisher(topics(own)["state"], State).publish(State(state=State.FLYING_AUTO))
        wait_until(lambda: data.heard(own).ual_state == State.FLYING_AUTO, "the state of uav_91")
        assert not view.has_own
        # the other UAV's topics other than odom are not listened to
        publisher(topics(other)["pose"], PoseStamped).publish(pose(9, 9, 9, stamp=3.0))
        publisher(topics(own)["pose"], PoseStamped).publish(pose(1, 0, 2, stamp=3.0))
        publisher(topics(other)["odom"], Odometry).publish(odom(1, 3, 2, body_velocity=(1, 0, 0), stamp=3.0))
        publisher(topics(own)["battery"], BatteryState).publish(BatteryState(percentage=0.8))
        publisher(topics(own)["depth"], Image).publish(
            Image(height=1, width=2, encoding="32FC1", step=8, data=struct.pack("<2f", 2.5, 7.0)))
        box = marker(Marker.CUBE, 41, scale=(2, 2, 2), position=(1, 0, 5), text="test91_box")
        publisher(names.WORLD_MARKERS, MarkerArray).publish(MarkerArray([Marker(action=Marker.DELETEALL), box]))

        def filled():
            with data.lock:
                return (view.has_own and view.agent(other) is not None and view.own.depth is not None
                        and view.own.battery == pytest.approx(0.8)
                        and any(o.name == "test91_box" for o in view.obstacles))

        wait_until(filled, "the view of uav_91 to fill from its topics")
        with data.lock:
            (near, gap), = view.nearest_agents()
            assert near.id == other and gap == pytest.approx(3 - 0.7)
            np.testing.assert_allclose(near.velocity, [0, 1, 0], atol=1e-12)  # body x of a UAV yawed 90 degrees
            assert view.own.ual_state == State.FLYING_AUTO and view.own.velocity[1] == pytest.approx(1.0)
            np.testing.assert_array_equal(view.own.depth, [[2.5, 7.0]])
            (obstacle, obstacle_gap), = [(o, g) for o, g in view.nearest_obstacles() if o.name == "test91_box"]
            assert obstacle_gap == pytest.approx(3 - 1 - 0.3)  # to the box's bottom face, 1 m below its centre

        data.close()
        pubs[3].publish(pose(8, 0, 2, stamp=4.0))
        # A witness on the same topic in this process: once it has the new pose, a subscription of
        # `data` still open would have had it too (rospy hands a message to every callback of the topic).
        witnessed = []
        witness = rospy.Subscriber(topics(own)["pose"], PoseStamped, lambda msg: witnessed.append(msg.header.stamp))
        pubs.append(witness)  # unregistered with the publishers
        wait_until(lambda: rospy.Time(4.0) in witnessed, "the pose sent after close() to arrive")
        np.testing.assert_allclose(view.own.position, [1, 0, 2])  # nothing heard after close()
    finally:
        data.close()
        for p in pubs:
            p.unregister()


@pytest.mark.ros
def test_a_simulated_own_uav_is_heard_on_the_swarm_alone_and_a_mavlink_one_on_its_topics(rospy_node):
    rospy = rospy_node
    from magna_uav.ros_data import RosWorldData, topics

    own, other, radii = 93, 94, {93: 0.3, 94: 0.4}
    feed = SwarmFeed(topic="/test93/swarm_state")
    swarm_pub = rospy.Publisher(feed.topic, SwarmState, queue_size=1, latch=True)
    simulated = RosWorldData(WorldView(own), [own, other], radii, swarm=feed)
    mavlink_flown = RosWorldData(WorldView(own), [own, other], radii, swarm=feed, odom_ids=[own])
    try:
        own_topics = {topics(own)[name] for name in ("pose", "velocity", "state")}
        assert not own_topics & set(simulated.topics_heard), simulated.topics_heard
        assert own_topics <= set(mavlink_flown.topics_heard), mavlink_flown.topics_heard
        assert topics(own)["battery"] in simulated.topics_heard  # the battery is not in the swarm's message
        with pytest.raises(LookupError, match="UAV 93 has no pose yet \\(nothing heard on /test93/swarm_state\\)"):
            _ = simulated.view.own
        assert mavlink_flown.view.own_pose_topic == topics(own)["pose"]
        swarm_pub.publish(swarm_of({own: odom(1, 2, 3, (0, 0, 0)), other: odom(4, 5, 6, (0, 0, 0))}, 2.0,
                                   {own: State.FLYING_AUTO, other: State.LANDED_ARMED}))

        def heard():
            with simulated.lock:
                return simulated.view.has_own and simulated.view.agent(other) is not None

        wait_until(heard, "uav_93's view to fill from the swarm's state")
        with simulated.lock:
            assert simulated.view.own.ual_state == State.FLYING_AUTO
            np.testing.assert_array_equal(simulated.view.own.position, [1, 2, 3])
        with mavlink_flown.lock:  # the same message: the other UAV from it, not the own one
            assert mavlink_flown.view.agent(other) is not None and not mavlink_flown.view.has_own
    finally:
        simulated.close()
        mavlink_flown.close()
        feed.close()
        swarm_pub.unregister()
