"""The GRVC UAL v3 API of one simulated UAV, under /uav_{id}/ual/.

Topics and services are those of a real UAL server, so a client cannot tell
the difference. Every callback hands its work to the simulation loop through
the CommandQueue; a refused command fails the service call with the reason
(the UAL services have empty responses, so the error travels as the ROS
service error) and is logged. A blocking take_off or go_to_waypoint returns once
the UAV has arrived (ual_logic: held within the arrival radius), and fails with
"not reached: ..." when its target is out of reach.
"""
from __future__ import annotations

import math

import numpy as np
import rospy
from geometry_msgs.msg import Pose, PoseStamped, TwistStamped, Vector3
from magna_msgs.msg import SwarmState
from nav_msgs.msg import Odometry
from std_srvs.srv import EmptyResponse
from uav_abstraction_layer.msg import State
from uav_abstraction_layer.srv import (
    GoToWaypointGeoResponse,
    GoToWaypointResponse,
    LandResponse,
    SetHomeResponse,
    TakeOffResponse,
)

from magna_common import geo
from magna_common import ros_names as names
from magna_common.ual_ros import serve_ual, ual_publishers

from .command_queue import CommandQueue, LoopStopped
from .streams import stream_publisher
from .ual_logic import CommandRefused, UalLogic, UalState
from .vehicle import yaw_from_quaternion

MAP_FRAME = "map"


def quaternion_yaw(q) -> float:
    """Yaw of a geometry_msgs/Quaternion."""
    return yaw_from_quaternion(q.x, q.y, q.z, q.w)


def rotate_into_body(orientation_xyzw, vector) -> tuple[float, float, float]:
    """Express a map-frame vector in the body frame (R^T v), in plain floats: numpy is slower at this size."""
    x, y, z, w = (float(c) for c in orientation_xyzw)
    vx, vy, vz = (float(c) for c in vector)
    # R^T v = v + 2 q' x (q' x v + w v) with q' = -(x, y, z)
    tx, ty, tz = -y * vz + z * vy + w * vx, -z * vx + x * vz + w * vy, -x * vy + y * vx + w * vz
    return (vx + 2.0 * (-y * tz + z * ty), vy + 2.0 * (-z * tx + x * tz), vz + 2.0 * (-x * ty + y * tx))


def swarm_state(stamp: rospy.Time, states) -> SwarmState:
    """The swarm's state at one publication instant.

    `states`: (uav_id, position, orientation_xyzw, velocity, angular_velocity, ual_state) per UAV, the values its
    own UAL topics carry at `stamp` (converted to floats the same way, so they compare equal)."""
    msg = SwarmState()
    msg.header.stamp, msg.header.frame_id = stamp, MAP_FRAME
    ual_states = []
    for uav_id, position, orientation, velocity, angular, ual_state in sorted(states, key=lambda state: state[0]):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = (float(c) for c in position)
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (float(c) for c in orientation)
        msg.ids.append(uav_id)
        msg.poses.append(pose)
        msg.velocities.append(Vector3(*(float(c) for c in velocity)))
        msg.angular_velocities.append(Vector3(*(float(c) for c in angular)))
        ual_states.append(int(ual_state))
    msg.states = bytes(ual_states)  # uint8[]: bytes, as rospy hands it to subscribers
    return msg


class UalServer:
    def __init__(self, uav_id: int, logic: UalLogic, queue: CommandQueue, map_origin_geo=None):
        self.uav_id = uav_id
        self.logic = logic
        self.logic.on_warning = lambda message: rospy.logwarn_throttle(5.0, f"{names.ual(uav_id, '')}{message}")
        self.queue = queue
        self.map_origin_geo = map_origin_geo
        self.base_frame = f"uav_{uav_id}/base_link"
        self.home_frame = f"uav_{uav_id}_home"
        self._pose_pub, self._velocity_pub, self._odom_pub, self._state_pub = ual_publishers(uav_id, stream_publisher)
        self._subscribers, self._services = serve_ual(uav_id, self)
        self._pose = PoseStamped()
        self._pose.header.frame_id = MAP_FRAME
        self._twist = TwistStamped()
        self._twist.header.frame_id = MAP_FRAME
        self._odom = Odometry()
        self._odom.header.frame_id = MAP_FRAME
        self._odom.child_frame_id = self.base_frame
        self._state = State()

    def shutdown(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()
        for service in self._services:
            service.shutdown()
        for publisher in (self._pose_pub, self._velocity_pub, self._odom_pub, self._state_pub):
            publisher.unregister()

    # --- publishing (simulation thread) ----------------------------------------------------------------------
    def publish(self, stamp: rospy.Time, position: np.ndarray, velocity: np.ndarray) -> None:
        """Publish pose, velocity, odom and state; position and velocity may carry sensor noise.

        A topic nobody listens to is skipped, as rospy would drop it anyway after we filled it in.
        """
        vehicle = self.logic.vehicle
        q = vehicle.orientation
        pose = self._pose.pose
        pose.position.x, pose.position.y, pose.position.z = (float(c) for c in position)
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (float(c) for c in q)
        if self._pose_pub.get_num_connections():
            self._pose.header.stamp = stamp
            self._pose_pub.publish(self._pose)
        if self._velocity_pub.get_num_connections():
            twist = self._twist.twist
            twist.linear.x, twist.linear.y, twist.linear.z = (float(c) for c in velocity)
            twist.angular.x, twist.angular.y, twist.angular.z = (float(c) for c in vehicle.angular_velocity)
            self._twist.header.stamp = stamp
            self._velocity_pub.publish(self._twist)
        if self._odom_pub.get_num_connections():
            self._odom.header.stamp = stamp
            self._odom.pose.pose = pose
            body = self._odom.twist.twist
            body.linear.x, body.linear.y, body.linear.z = rotate_into_body(q, velocity)
            body.angular.x, body.angular.y, body.angular.z = rotate_into_body(q, vehicle.angular_velocity)
            self._odom_pub.publish(self._odom)
        if self._state_pub.get_num_connections():
            self._state.state = int(self.logic.state)
            self._state_pub.publish(self._state)

    # --- streamed setpoints ----------------------------------------------------------------------------------
    def on_set_pose(self, msg: PoseStamped) -> None:
        boundaries = self._world_boundaries()
        try:
            # Converted in the loop: the home frame moves with set_home, which runs there too.
            self.queue.run(lambda: self._within(boundaries).set_pose(self._to_map(msg.header.frame_id,
                                                                                  msg.pose.position),
                                                                     quaternion_yaw(msg.pose.orientation)))
        except (CommandRefused, LoopStopped) as err:
            rospy.logwarn_throttle(2.0, f"{names.ual(self.uav_id, 'set_pose')} ignored: {err}")

    def on_set_velocity(self, msg: TwistStamped) -> None:
        if msg.header.frame_id not in ("", MAP_FRAME):
            rospy.logwarn_throttle(2.0, f"{names.ual(self.uav_id, 'set_velocity')} ignored: header.frame_id "
                                        f"'{msg.header.frame_id}' unknown; send velocities in '{MAP_FRAME}'")
            return
        linear = (msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z)
        try:
            self.queue.run(lambda: self.logic.set_velocity(linear, msg.twist.angular.z))
        except (CommandRefused, LoopStopped) as err:
            rospy.logwarn_throttle(2.0, f"{names.ual(self.uav_id, 'set_velocity')} ignored: {err}")

    # --- services --------------------------------------------------------------------------------------------
    def take_off(self, req):
        boundaries = self._world_boundaries()
        self._command("take_off", lambda: self._within(boundaries).take_off(req.height),
                      req.blocking, lambda: self.logic.state == UalState.FLYING_AUTO)
        return TakeOffResponse()

    def land(self, req):
        self._command("land", self.logic.land, req.blocking, lambda: self.logic.state == UalState.LANDED_ARMED)
        return LandResponse()

    def go_to_waypoint(self, req):
        pose = req.waypoint.pose
        boundaries = self._world_boundaries()
        self._command("go_to_waypoint",
                      lambda: self._within(boundaries).go_to(self._to_map(req.waypoint.header.frame_id, pose.position),
                                                             quaternion_yaw(pose.orientation)),
                      req.blocking, self.logic.reached)
        return GoToWaypointResponse()

    def go_to_waypoint_geo(self, req):
        fix = req.waypoint
        position = self._service_guard("go_to_waypoint_geo", lambda: self._geo_to_map(fix))
        boundaries = self._world_boundaries()
        self._command("go_to_waypoint_geo", lambda: self._within(boundaries).go_to(position, self.logic.vehicle.yaw),
                      req.blocking, self.logic.reached)
        return GoToWaypointGeoResponse()

    def set_home(self, req):
        self._command("set_home", lambda: self.logic.set_home(req.set_z), False, None)
        return SetHomeResponse()

    def recover_from_manual(self, _req):
        self._command("recover_from_manual", self.logic.recover_from_manual, False, None)
        return EmptyResponse()

    def _command(self, name: str, action, blocking: bool, done) -> None:
        """Run a command in the loop; if blocking, wait until done() holds for that same command."""
        def start():
            action()
            return self.logic.command_id

        command_id = self._service_guard(name, lambda: self.queue.run(start))
        if not blocking:
            return

        def finished():
            if self.logic.command_id != command_id:
                raise CommandRefused(f"{name} interrupted: a newer command replaced it before it finished")
            if done():
                return True
            if self.logic.stuck is not None:
                raise CommandRefused(f"{name} not reached: {self.logic.stuck}")
            return None

        self._service_guard(name, lambda: self.queue.wait_for(finished))

    def _service_guard(self, name: str, fn):
        try:
            return fn()
        except (ValueError, LoopStopped) as err:  # CommandRefused is a ValueError
            rospy.logerr(f"{names.ual(self.uav_id, name)}: {err}")
            raise rospy.ServiceException(str(err)) from None

    # --- the world's boundaries ----------------------------------------------------------------------------------
    def _world_boundaries(self) -> np.ndarray | None:
        """The world's boundaries as the world node set them, or None before a world is there. Cached by rospy and
        kept current by the master's parameter updates: cheap enough for every streamed set-point."""
        value = rospy.get_param_cached(names.WORLD_BOUNDARIES, None)  # an unset parameter may read as {}
        box = np.asarray(value, dtype=float) if isinstance(value, list) else None
        return box if box is not None and box.shape == (3, 2) else None

    def _within(self, boundaries: np.ndarray | None) -> UalLogic:
        """The UAV's logic, checking position targets against `boundaries` (run in the loop, like the command)."""
        self.logic.boundaries = boundaries
        return self.logic

    # --- frames ----------------------------------------------------------------------------------------------
    def _to_map(self, frame_id: str, point) -> np.ndarray:
        position = np.array([point.x, point.y, point.z], dtype=float)
        if frame_id in ("", MAP_FRAME):
            return position
        if frame_id == self.home_frame:
            return position + self.logic.home
        raise CommandRefused(f"header.frame_id '{frame_id}' is not known here; use '{MAP_FRAME}' "
                             f"or '{self.home_frame}'")

    def _geo_to_map(self, fix) -> np.ndarray:
        if self.map_origin_geo is None:
            raise CommandRefused("no map origin: start magna_sim with ~map_origin_geo [lat, lon, alt] "
                                 "(or a world with origin_geo) to fly to geographic waypoints")
        values = (fix.latitude, fix.longitude, fix.altitude)
        if not all(math.isfinite(v) for v in values):
            raise CommandRefused(f"waypoint: latitude/longitude/altitude {list(values)} must be finite numbers")
        return geo.geodetic_to_enu(*values, self.map_origin_geo)
