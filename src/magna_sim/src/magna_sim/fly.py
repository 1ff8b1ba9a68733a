"""`rosrun magna_sim fly`: fly one UAV by hand through its UAL API (simulated or real).

Only UAL names are used, so it works against any UAL server.
"""
from __future__ import annotations

import argparse
import math
import sys

from magna_common import ros_names as names
from magna_common.ros_errors import service_error_text

# How rospy's client wraps a server's refusal; the reason comes as a bytes literal under Python 3.


DESCRIPTION = """\
Fly one UAV by hand through the UAL API under /uav_{id}/ual/ (magna_sim or a real UAL server).

take_off and go_to wait until the UAV is there (magna_sim: within half of UAL's position_th,
0.165 m, and never farther than the airframe's accepted_target_radius, held for 1 s of simulated
time) and then print its state and pose; a target it cannot reach fails with the reason, exit
status 1. --no-wait returns at once."""

EXAMPLES = """\
examples:
  roslaunch magna_sim sim.launch uavs:=1   # a simulated UAV to fly, until Ctrl-C [background]
  rosrun magna_sim fly --id 1 take_off 2
  rosrun magna_sim fly --id 1 go_to 3 0 2 --yaw 90
  rosrun magna_sim fly --id 1 velocity 0.5 0 0 --duration 2
  rosrun magna_sim fly --id 1 land
  rosrun magna_sim fly --id 1 state"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rosrun magna_sim fly",
        description=DESCRIPTION,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--id", type=int, default=1, help="UAL id of the UAV (default 1)")
    parser.add_argument("--no-wait", action="store_true", help="return at once instead of when the move is done")
    sub = parser.add_subparsers(dest="command", required=True)
    take_off = sub.add_parser("take_off", help="take off to HEIGHT metres above the current position")
    take_off.add_argument("height", type=float)
    sub.add_parser("land", help="land where the UAV is")
    go_to = sub.add_parser("go_to", help="fly to X Y Z in the map frame")
    for axis in "xyz":
        go_to.add_argument(axis, type=float)
    go_to.add_argument("--yaw", type=float, default=0.0, help="heading in degrees (default 0)")
    velocity = sub.add_parser("velocity", help="fly at VX VY VZ m/s (map frame) for a while")
    for axis in ("vx", "vy", "vz"):
        velocity.add_argument(axis, type=float)
    velocity.add_argument("--duration", type=float, default=1.0, help="seconds of sim time (default 1)")
    sub.add_parser("state", help="print the UAL state and pose once")
    return parser


def main(argv=None) -> int:
    import rospy

    args = build_parser().parse_args(rospy.myargv()[1:] if argv is None else argv)
    rospy.init_node("magna_fly", anonymous=True)
    try:
        run(args)
    except (rospy.ServiceException, rospy.ROSException, LookupError) as err:
        print(f"fly: {service_error_text(err)}", file=sys.stderr)
        return 1
    return 0


def run(args) -> None:
    import rospy
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from uav_abstraction_layer.msg import State
    from uav_abstraction_layer.srv import GoToWaypoint, Land, TakeOff

    _wait_for_server(args.id, ready=args.command != "state")
    wait = not args.no_wait
    if args.command == "take_off":
        _service(names.ual(args.id, "take_off"), TakeOff)(height=args.height, blocking=wait)
    elif args.command == "land":
        _service(names.ual(args.id, "land"), Land)(blocking=wait)
    elif args.command == "go_to":
        target = PoseStamped()
        target.header.frame_id = "map"
        target.pose.position.x, target.pose.position.y, target.pose.position.z = args.x, args.y, args.z
        half = math.radians(args.yaw) / 2.0
        target.pose.orientation.z, target.pose.orientation.w = math.sin(half), math.cos(half)
        _service(names.ual(args.id, "go_to_waypoint"), GoToWaypoint)(waypoint=target, blocking=wait)
    elif args.command == "velocity":
        topic = names.ual(args.id, "set_velocity")
        publisher = rospy.Publisher(topic, TwistStamped, queue_size=1)
        _wait_wall(lambda: publisher.get_num_connections() > 0, f"{topic} to have its subscriber")
        _wait_wall(lambda: not rospy.Time.now().is_zero(), "the clock (is /clock published?)")
        command = TwistStamped()
        command.header.frame_id = "map"
        command.twist.linear.x, command.twist.linear.y, command.twist.linear.z = args.vx, args.vy, args.vz
        rate, end = rospy.Rate(20), rospy.Time.now() + rospy.Duration(args.duration)
        while not rospy.is_shutdown() and rospy.Time.now() < end:
            command.header.stamp = rospy.Time.now()
            publisher.publish(command)
            rate.sleep()
    state = rospy.wait_for_message(names.ual(args.id, "state"), State, timeout=10.0)
    pose = rospy.wait_for_message(names.ual(args.id, "pose"), PoseStamped, timeout=10.0).pose.position
    state_names = {v: k for k, v in vars(State).items() if k.isupper()}
    print(f"uav {args.id}: {state_names.get(state.state, state.state)} at ({pose.x:.2f}, {pose.y:.2f}, {pose.z:.2f})")


def _wait_for_server(uav_id: int, ready: bool) -> None:
    """Wait for the UAL server of `uav_id`: a simulator started a moment ago may not serve it yet.

    `/ual_ids` lists the ids served; once it lists others but not ours, ours is not coming. With
    `ready`, also wait for the UAV to leave UNINITIALIZED (a UAL refuses every command before).
    """
    import rospy
    from uav_abstraction_layer.msg import State

    ids: list = []

    def listed() -> bool:
        nonlocal ids
        ids = rospy.get_param(names.UAL_IDS, [])
        return bool(ids)

    try:
        _wait_wall(listed, names.UAL_IDS)
    except LookupError:
        pass
    if uav_id not in ids:
        hint = "" if ids else " (is magna_sim running? roslaunch magna_sim sim.launch)"
        raise LookupError(f"no UAL server for UAV {uav_id}; {names.UAL_IDS} = {ids}{hint}")
    if not ready:
        return
    latest: dict[str, int] = {}
    subscriber = rospy.Subscriber(names.ual(uav_id, "state"), State, lambda msg: latest.__setitem__("state", msg.state),
                                  queue_size=1)
    try:
        _wait_wall(lambda: latest.get("state", State.UNINITIALIZED) != State.UNINITIALIZED,
                   f"UAV {uav_id} to be ready ({names.ual(uav_id, 'state')} leaving UNINITIALIZED)")
    finally:
        subscriber.unregister()


def _wait_wall(condition, what: str, seconds: float = 10.0) -> None:
    """Wait on wall time: sim time may not be running yet, which is what we wait for."""
    import time

    deadline = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > deadline:
            raise LookupError(f"timed out after {seconds} s waiting for {what}")
        time.sleep(0.01)


def _service(name, kind):
    import rospy

    rospy.wait_for_service(name, timeout=10.0)
    return rospy.ServiceProxy(name, kind)
