"""ual_mavlink's ROS side: the GRVC UAL v3 API of one MAVLink UAV under /uav_{id}/ual/, as magna_sim serves it.

Same topics, services, frame ids and refusals as magna_sim's UAL server (both declare the API through
magna_common.ual_ros), so a client cannot tell them apart: pose, velocity and odom in `map` (odom's twist
in the body, child frame uav_{id}/base_link), set_pose and go_to_waypoint in `map` or `uav_{id}_home`,
set_velocity in `map`; a refused command fails its service call with the reason. Also
/uav_{id}/mavros/battery (sensor_msgs/BatteryState, from SYS_STATUS, as MAGNA's UAV managers read it),
tf map -> uav_{id}/base_link, and the latched /uav_{id}/ual_mavlink/link (std_msgs/String: "" or what is
wrong with the link).

The main loop runs on ROS time (simulated when /use_sim_time is set): every tick sends the set-point
and publishes the topics.
"""
from __future__ import annotations

import functools
import math
import sys
import threading

from magna_common import ros_names as names

from .backend import CommandRefused, UalBackend
from .cli import PARAMETERS, OptionError, Options, build_parser, id_from_argv, resolve
from .commands import Commander
from .link import LinkError, MavlinkLink, mavlink
from .ual_state import NAMES
from .vehicle_state import VehicleState

MAP_FRAME = "map"
BATTERY_PERIOD = 0.5  # s between BatteryState messages
# Telemetry asked of the autopilot (message, Hz); one it does not support keeps its own rate.
MESSAGE_RATES = (("LOCAL_POSITION_NED", 30.0), ("ATTITUDE", 30.0), ("GLOBAL_POSITION_INT", 10.0),
                 ("EXTENDED_SYS_STATE", 5.0), ("SYS_STATUS", 2.0), ("HOME_POSITION", 1.0))


def yaw_of(q) -> float:
    """Yaw (ENU) of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class RosLog:
    """The backend's logger, through rospy."""

    def __init__(self, rospy):
        self.info, self.warning, self.error = rospy.loginfo, rospy.logwarn, rospy.logerr


class UalServer:
    def __init__(self, backend: UalBackend, tf: bool = True):
        import rospy
        import tf2_ros
        from geometry_msgs.msg import PoseStamped, TransformStamped, TwistStamped
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import BatteryState
        from std_msgs.msg import String
        from uav_abstraction_layer.msg import State

        from magna_common.ual_ros import serve_ual, ual_publishers

        self.rospy = rospy
        self.backend = backend
        uav_id = backend.settings.uav_id
        self.uav_id = uav_id
        self._pose_pub, self._velocity_pub, self._odom_pub, self._state_pub = ual_publishers(
            uav_id, functools.partial(rospy.Publisher, queue_size=1))
        self._battery_pub = rospy.Publisher(names.battery(uav_id), BatteryState, queue_size=1)
        self._link_pub = rospy.Publisher(names.mavlink_link(uav_id), String, queue_size=1, latch=True)
        self._tf = tf2_ros.TransformBroadcaster() if tf else None
        self._subscribers, self._services = serve_ual(uav_id, self)
        self._pose, self._twist, self._odom = PoseStamped(), TwistStamped(), Odometry()
        self._pose.header.frame_id = self._twist.header.frame_id = self._odom.header.frame_id = MAP_FRAME
        self._odom.child_frame_id = f"uav_{uav_id}/base_link"
        self._transform = TransformStamped()
        self._transform.header.frame_id, self._transform.child_frame_id = MAP_FRAME, f"uav_{uav_id}/base_link"
        self._state = State()
        self._battery = BatteryState()
        self._battery.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LIPO
        self._battery_time = -math.inf
        self._link_text: str | None = None
        self._String = String

    def shutdown(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()
        for service in self._services:
            service.shutdown()

    # --- publishing (main loop) -----------------------------------------------------------------------------------
    def publish(self, stamp) -> None:
        backend, t = self.backend, self.backend.telemetry
        if backend.link_problem != self._link_text:
            self._link_text = backend.link_problem
            self._link_pub.publish(self._String(data=self._link_text))
        self._state.state = backend.state
        self._state_pub.publish(self._state)
        if t.position_time is None:
            return  # nothing heard yet: no pose to give
        import numpy as np
        from scipy.spatial.transform import Rotation

        pose = self._pose.pose
        pose.position.x, pose.position.y, pose.position.z = (float(c) for c in t.position)
        q = pose.orientation
        q.x, q.y, q.z, q.w = (float(c) for c in t.orientation)
        self._pose.header.stamp = stamp
        self._pose_pub.publish(self._pose)
        rotation = Rotation.from_quat(t.orientation)
        angular_world = rotation.apply(t.angular_velocity)
        twist = self._twist.twist
        twist.linear.x, twist.linear.y, twist.linear.z = (float(c) for c in t.velocity)
        twist.angular.x, twist.angular.y, twist.angular.z = (float(c) for c in angular_world)
        self._twist.header.stamp = stamp
        self._velocity_pub.publish(self._twist)
        self._odom.header.stamp = stamp
        self._odom.pose.pose = pose
        body = self._odom.twist.twist
        body.linear.x, body.linear.y, body.linear.z = (float(c) for c in rotation.inv().apply(np.asarray(t.velocity)))
        body.angular.x, body.angular.y, body.angular.z = (float(c) for c in t.angular_velocity)
        self._odom_pub.publish(self._odom)
        if self._tf is not None:
            self._transform.header.stamp = stamp
            translation = self._transform.transform.translation
            translation.x, translation.y, translation.z = pose.position.x, pose.position.y, pose.position.z
            self._transform.transform.rotation = q
            self._tf.sendTransform(self._transform)
        now = stamp.to_sec()
        if not now - BATTERY_PERIOD < self._battery_time <= now:
            self._battery_time = now
            self._battery.header.stamp = stamp
            self._battery.percentage, self._battery.voltage = t.battery, t.voltage
            self._battery.present = True
            self._battery_pub.publish(self._battery)

    # --- streamed set-points --------------------------------------------------------------------------------------
    def on_set_pose(self, msg) -> None:
        p = msg.pose.position
        try:
            self.backend.set_pose(msg.header.frame_id, (p.x, p.y, p.z), yaw_of(msg.pose.orientation))
        except CommandRefused as err:
            self.rospy.logwarn_throttle(2.0, f"{names.ual(self.uav_id, 'set_pose')} ignored: {err}")

    def on_set_velocity(self, msg) -> None:
        if msg.header.frame_id not in ("", MAP_FRAME):
            self.rospy.logwarn_throttle(2.0, f"{names.ual(self.uav_id, 'set_velocity')} ignored: header.frame_id "
                                             f"'{msg.header.frame_id}' unknown; send velocities in '{MAP_FRAME}'")
            return
        v = msg.twist.linear
        try:
            self.backend.set_velocity((v.x, v.y, v.z), msg.twist.angular.z)
        except CommandRefused as err:
            self.rospy.logwarn_throttle(2.0, f"{names.ual(self.uav_id, 'set_velocity')} ignored: {err}")

    # --- services -------------------------------------------------------------------------------------------------
    def take_off(self, req):
        return self._call("take_off", lambda: self.backend.take_off(req.height, req.blocking), req)

    def land(self, req):
        return self._call("land", lambda: self.backend.land(req.blocking), req)

    def go_to_waypoint(self, req):
        p = req.waypoint.pose.position
        return self._call("go_to_waypoint", lambda: self.backend.go_to(
            req.waypoint.header.frame_id, (p.x, p.y, p.z), yaw_of(req.waypoint.pose.orientation), req.blocking), req)

    def go_to_waypoint_geo(self, req):
        fix = req.waypoint
        return self._call("go_to_waypoint_geo", lambda: self.backend.go_to_geo(
            fix.latitude, fix.longitude, fix.altitude, req.blocking), req)

    def set_home(self, req):
        return self._call("set_home", lambda: self.backend.set_home(req.set_z), req)

    def recover_from_manual(self, req):
        return self._call("recover_from_manual", self.backend.recover_from_manual, req)

    def _call(self, name: str, action, req):
        try:
            action()
        except CommandRefused as err:
            self.rospy.logerr(f"{names.ual(self.uav_id, name)}: {err}")
            raise self.rospy.ServiceException(str(err)) from None
        return self._response_of(req)

    def _response_of(self, req):
        module = sys.modules[type(req).__module__]
        return getattr(module, type(req).__name__.replace("Request", "Response"))()


# --- /ual_ids -----------------------------------------------------------------------------------------------------
def register_id(rospy, uav_id: int) -> None:
    """Add `uav_id` to /ual_ids; refuse one a live UAL server already serves (a dead one's is taken over)."""
    import rosservice

    ids = list(rospy.get_param(names.UAL_IDS, []))
    if uav_id in ids:
        try:
            node = rosservice.get_service_node(names.ual(uav_id, "take_off"))
        except rosservice.ROSServiceIOException:
            node = None
        if node:
            raise OptionError(f"--id {uav_id}: UAV {uav_id} is already served by {node} ({names.UAL_IDS} = {ids}); "
                              f"pick a free id")
        rospy.logwarn(f"ual_mavlink: {names.UAL_IDS} lists {uav_id} but no UAL server serves it (one was killed?); "
                      f"taking it over")
    rospy.set_param(names.UAL_IDS, sorted(set(ids) | {uav_id}))


def unregister_id(rospy, uav_id: int) -> None:
    try:
        rospy.set_param(names.UAL_IDS, [i for i in rospy.get_param(names.UAL_IDS, []) if i != uav_id])
    except Exception:  # noqa: BLE001 - the master may be gone already at shutdown
        pass


# --- the node -----------------------------------------------------------------------------------------------------
def request_telemetry(link: MavlinkLink, rospy) -> None:
    """Ask for the messages the UAL reads at the rates it needs (in a thread: each waits for its ACK)."""
    for name, rate in MESSAGE_RATES:
        message_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
        try:
            result = link.set_message_interval(message_id, rate)
        except Exception as err:  # noqa: BLE001 - a link gone at shutdown, an autopilot that never answers
            rospy.logdebug(f"ual_mavlink: {name} at {rate:g} Hz: {err}")
            continue
        if result != mavlink.MAV_RESULT_ACCEPTED:
            rospy.logdebug(f"ual_mavlink: {name} at {rate:g} Hz not accepted ({result}); keeping its own rate")
    # Where the autopilot's local frame starts, and its home: the map and geo waypoints are placed with them.
    for message_id in (mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, mavlink.MAVLINK_MSG_ID_HOME_POSITION):
        try:
            link.request_message(message_id)
        except Exception:  # noqa: BLE001 - as above
            pass


def describe_arming(options: Options, autopilot: str) -> str:
    from .autopilot import SET_POINT_MODE

    mode = SET_POINT_MODE[autopilot]
    if options.arming == "auto":
        return (f"arming auto: ual_mavlink arms the UAV on the ground and selects {mode} itself "
                f"(for simulation and HIL; use --arming pilot on a real UAV)")
    return (f"arming pilot: ual_mavlink never arms; the safety pilot arms, and take_off waits for the pilot to "
            f"select {mode}")


def main(argv=None) -> int:
    import rospy

    full = sys.argv if argv is None else ["ual_mavlink", *argv]
    args = build_parser().parse_args(rospy.myargv(argv=full)[1:])
    uav_id = args.id if args.id is not None else id_from_argv(full)
    rospy.init_node(f"ual_mavlink_{uav_id}" if uav_id is not None else "ual_mavlink")
    params = {name: rospy.get_param("~" + name) for name in PARAMETERS if rospy.has_param("~" + name)}
    try:
        options = resolve(args, params)
    except OptionError as err:
        print(f"ual_mavlink: {err}", file=sys.stderr)
        return 2
    forced = None if options.autopilot == "auto" else options.autopilot
    vehicle = VehicleState(options.origin_geo, forced)
    link = MavlinkLink(options.url, options.system_id, on_message=lambda msg: vehicle.update(msg, rospy.get_time()))
    try:
        link.open()
        heard = link.wait_for_vehicle(options.connect_timeout)
    except LinkError as err:
        print(f"ual_mavlink: UAV {options.uav_id}: {err}", file=sys.stderr)
        link.close()
        return 2
    autopilot = forced or vehicle.snapshot().autopilot
    if autopilot is None:
        print(f"ual_mavlink: UAV {options.uav_id}: {options.url}: {vehicle.autopilot_error} (--autopilot px4 or "
              f"--autopilot ardupilot flies it as one of those)", file=sys.stderr)
        link.close()
        return 2
    rospy.loginfo(f"ual_mavlink: UAV {options.uav_id} is {autopilot} system {options.system_id} at {options.url} "
                  f"(HEARTBEAT autopilot {heard.autopilot}); {describe_arming(options, autopilot)}")
    backend = UalBackend(vehicle, Commander(link, autopilot), options.settings, options.url, clock=rospy.get_time,
                         log=RosLog(rospy))
    try:
        register_id(rospy, options.uav_id)
    except OptionError as err:
        print(f"ual_mavlink: {err}", file=sys.stderr)
        link.close()
        return 2
    server = UalServer(backend, tf=options.tf)

    # rospy runs shutdown hooks inside its signal handler, on top of whatever the main thread was doing:
    # only wake the calls that wait there; the master is told below, once the loop has ended.
    rospy.on_shutdown(backend.close)
    threading.Thread(target=request_telemetry, args=(link, rospy), name="telemetry requests", daemon=True).start()
    rate = rospy.Rate(options.pub_rate)
    try:
        while not rospy.is_shutdown():
            backend.tick(rospy.get_time())
            server.publish(rospy.Time.now())
            try:
                rate.sleep()
            except rospy.ROSTimeMovedBackwardsException:
                pass
    except rospy.ROSInterruptException:
        pass
    finally:
        backend.close()
        unregister_id(rospy, options.uav_id)
        server.shutdown()
        link.close()
    rospy.loginfo(f"ual_mavlink: UAV {options.uav_id} stopped ({NAMES[backend.state]}); id {options.uav_id} "
                  f"left {names.UAL_IDS}")
    return 0
