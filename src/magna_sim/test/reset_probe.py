"""Probe of a running magna_sim for test_sim_reset.py; prints one JSON line with what it saw.

  reset_probe.py reset SEED  spawn a UAV and an obstacle, let time run, reset with SEED, then record
  reset_probe.py cold        record from the start of a simulator started after this line: "listening"

Recorded: UAV 1's odom and the swarm state with stamps up to RECORD_UNTIL s of simulated time, and the UAL states
heard on UAV 1's ual/state (it stands landed throughout: one state).
"""
import json
import sys
import threading

import rosgraph
import rospy
from magna_msgs.msg import SwarmState
from magna_msgs.srv import DeleteModel, ResetSimulation, SpawnModel, SpawnModelRequest
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from uav_abstraction_layer.msg import State

from magna_common import ros_names as names

RECORD_UNTIL = 4.0
WAIT = 60.0  # s: a guard against hangs


class Recorder:
    def __init__(self):
        self.odom, self.swarm, self.clock, self.states = {}, {}, [], set()
        self.changed = threading.Condition()

    def listen_to_clock(self):
        rospy.Subscriber("/clock", Clock, self._on_clock, queue_size=None)

    def listen_to_the_uavs(self):
        rospy.Subscriber(names.ual(1, "odom"), Odometry, self._on_odom, queue_size=None)
        rospy.Subscriber(names.SIM_SWARM_STATE, SwarmState, self._on_swarm, queue_size=None)
        rospy.Subscriber(names.ual(1, "state"), State, self._on_state, queue_size=None)

    def _on_clock(self, msg):
        with self.changed:
            self.clock.append(msg.clock.to_nsec())
            self.changed.notify_all()

    def _on_odom(self, msg):
        p, q, v, w = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear, msg.twist.twist.angular
        with self.changed:
            self.odom[msg.header.stamp.to_nsec()] = [p.x, p.y, p.z, q.x, q.y, q.z, q.w, v.x, v.y, v.z, w.x, w.y, w.z]
            self.changed.notify_all()

    def _on_state(self, msg):
        with self.changed:
            self.states.add(msg.state)
            self.changed.notify_all()

    def _on_swarm(self, msg):
        entry = {"frame": msg.header.frame_id, "ids": list(msg.ids),
                 "poses": [[p.position.x, p.position.y, p.position.z,
                            p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in msg.poses],
                 "velocities": [[v.x, v.y, v.z] for v in msg.velocities],
                 "angular_velocities": [[w.x, w.y, w.z] for w in msg.angular_velocities], "states": list(msg.states)}
        with self.changed:
            self.swarm[msg.header.stamp.to_nsec()] = entry
            self.changed.notify_all()

    def until(self, condition, what):
        with self.changed:
            if not self.changed.wait_for(lambda: condition(self), timeout=WAIT):
                raise SystemExit(f"reset_probe: timed out waiting for {what}")

    def recorded(self):
        return self.until(lambda r: r.odom and max(r.odom) >= RECORD_UNTIL * 1e9 and r.swarm and r.states
                          and max(r.swarm) >= RECORD_UNTIL * 1e9, f"{RECORD_UNTIL} s of odom, swarm and UAL state")


def sim_entries(master):
    """Every topic, subscription and service of the UAV 2 namespaces that magna_sim holds at the master."""
    publishers, subscribers, services = master.getSystemState()
    return sorted(name for group in (publishers, subscribers, services) for name, nodes in group
                  if "uav_2" in name and "/magna_sim" in nodes)


def spawn(request):
    return rospy.ServiceProxy(names.SIM_SPAWN_MODEL, SpawnModel)(request)


def uav_2():
    request = SpawnModelRequest(name="uav_2", kind="uav", uav_id=2)
    request.pose.position.x, request.pose.orientation.w = 3.0, 1.0
    return request


def reset_then_record(seed):
    recorder = Recorder()
    recorder.listen_to_clock()
    master = rosgraph.Master(rospy.get_name())
    rospy.wait_for_service(names.SIM_RESET, timeout=WAIT)  # registered after the other services
    box = SpawnModelRequest(name="box", kind="obstacle", shape="cube", dimensions=[1, 1, 1])
    box.pose.position.x, box.pose.position.y, box.pose.position.z, box.pose.orientation.w = 5.0, 5.0, 0.5, 1.0
    spawned = spawn(uav_2()).success and spawn(box).success
    recorder.until(lambda r: r.clock and r.clock[-1] >= 0.5e9, "0.5 s of simulated time")
    before = sim_entries(master)
    reset = rospy.ServiceProxy(names.SIM_RESET, ResetSimulation)
    refused = reset(seed=-1)
    answer = reset(seed=seed)
    after = sim_entries(master)
    delete = rospy.ServiceProxy(names.SIM_DELETE_MODEL, DeleteModel)
    deleted = [delete(name=name).message for name in ("box", "uav_2")]
    ual_ids = rospy.get_param(names.UAL_IDS)
    recorder.listen_to_the_uavs()  # only now: nothing published before the reset can reach these
    recorder.recorded()
    respawned = spawn(uav_2())
    recorder.until(lambda r: r.swarm[max(r.swarm)]["ids"] == [1, 2], "the swarm state with the new UAV 2")
    with recorder.changed:
        clock = list(recorder.clock)
        return {"spawned": spawned, "before": before, "refused": [refused.success, refused.message],
                "reset": [answer.success, answer.message], "after": after, "deleted": deleted, "ual_ids": ual_ids,
                "respawned": [respawned.success, respawned.message], "clock": clock,
                "odom": recorder.odom, "swarm": recorder.swarm,
                "states": sorted(recorder.states)}


def record_from_the_start():
    recorder = Recorder()
    recorder.listen_to_the_uavs()
    print("listening", flush=True)
    recorder.recorded()
    with recorder.changed:
        return {"odom": recorder.odom, "swarm": recorder.swarm,
                "states": sorted(recorder.states)}


def main():
    rospy.init_node("reset_probe")
    result = reset_then_record(int(sys.argv[2])) if sys.argv[1] == "reset" else record_from_the_start()
    print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
