"""Fly magna_sim's ROS node through a list of velocity commands, as a UAV manager would, and print the poses.

Run under a ROS master with the sim node up (mlr/tests/test_gym_consistency.py does). Standard input: JSON
{"height": m, "commands": [[[vx, vy, vz] per UAV] per control step]}, UAV ids 1..M. It takes every UAV off
to `height` (blocking UAL calls), lets them settle for a simulated second, then at each control step
(every 0.1 s of simulated time, read from /clock) announces the step for the simulator's lockstep, as the
UAV manager does, and publishes the step's set_velocity to every UAV. Standard output: JSON {"t0": the
simulated time of the first command, "poses": {id: [[t, x, y, z], ...]}}, every /uav_<id>/ual/pose heard.
"""
from __future__ import annotations

import json
import sys
import threading

CONTROL_PERIOD = 0.1  # s, the UAV manager's control rate of 10 Hz


def main() -> None:
    import rospy
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64
    from uav_abstraction_layer.msg import State
    from uav_abstraction_layer.srv import TakeOff

    request = json.load(sys.stdin)
    commands, height = request["commands"], float(request["height"])
    ids = list(range(1, len(commands[0]) + 1))
    rospy.init_node("gym_consistency_probe")
    lock = threading.Condition()
    clock = [0.0]
    poses: dict[int, list] = {i: [] for i in ids}

    def on_clock(msg):
        with lock:
            clock[0] = msg.clock.to_sec()
            lock.notify_all()

    def on_pose(msg, uav_id):
        p = msg.pose.position
        with lock:
            poses[uav_id].append([msg.header.stamp.to_sec(), p.x, p.y, p.z])

    def wait_clock(t: float) -> None:
        with lock:
            # t is on /clock's grid, up to rounding
            if not lock.wait_for(lambda: clock[0] >= t - 1e-6, timeout=60):
                raise SystemExit(f"probe: /clock did not reach {t:.3f} s (stands at {clock[0]:.3f} s)")

    rospy.Subscriber("/clock", Clock, on_clock, queue_size=10, tcp_nodelay=True)
    for i in ids:
        rospy.Subscriber(f"/uav_{i}/ual/pose", PoseStamped, on_pose, i, queue_size=100, tcp_nodelay=True)
    steps = {i: rospy.Publisher(f"/magna/uav_{i}/control_step", Float64, queue_size=1, tcp_nodelay=True) for i in ids}
    velocity = {i: rospy.Publisher(f"/uav_{i}/ual/set_velocity", TwistStamped, queue_size=1, tcp_nodelay=True)
                for i in ids}
    for i in ids:
        rospy.wait_for_service(f"/uav_{i}/ual/take_off", timeout=60)
        while rospy.wait_for_message(f"/uav_{i}/ual/state", State, timeout=60).state == State.UNINITIALIZED:
            pass
        rospy.ServiceProxy(f"/uav_{i}/ual/take_off", TakeOff)(height=height, blocking=True)
    for publisher in [*steps.values(), *velocity.values()]:
        while publisher.get_num_connections() == 0 and not rospy.is_shutdown():
            rospy.sleep(0.01)
    wait_clock(clock[0] + 1.0)
    t0 = clock[0]
    for k, step in enumerate(commands):
        t = t0 + k * CONTROL_PERIOD
        wait_clock(t)
        for publisher in steps.values():
            publisher.publish(Float64(t))  # the simulator never runs more than its lead ahead of this
        for i, (vx, vy, vz) in zip(ids, step, strict=True):
            command = TwistStamped()
            command.header.stamp, command.header.frame_id = rospy.Time.from_sec(t), "map"
            command.twist.linear.x, command.twist.linear.y, command.twist.linear.z = vx, vy, vz
            velocity[i].publish(command)
    end = t0 + len(commands) * CONTROL_PERIOD
    for publisher in steps.values():
        publisher.publish(Float64(end))
    wait_clock(end + 0.1)
    for publisher in steps.values():
        publisher.publish(Float64(-1.0))  # released, as a manager going idle
    with lock:
        print(json.dumps({"t0": t0, "poses": {str(i): poses[i] for i in ids}}))


if __name__ == "__main__":
    main()
