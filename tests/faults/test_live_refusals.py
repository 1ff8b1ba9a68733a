"""On a running mission, bad operator commands and bad UAL set-points are refused with a reason, and the
mission keeps flying to its end (issue 26, item 6).

One live stack: the project's Safe_Stop mission (two UAVs reach their stations, then wait for the
operator's button) under simulation.launch on a private master. While it waits, an operator process
sends /magna/gs/command requests with NaN, inf, huge and unicode values, and UAV 1's UAL
go_to_waypoint, set_pose and set_velocity with NaN, inf and targets far outside the world. Each
service answer is a refusal with its reason; each streamed set-point is refused with a warning on
/rosout naming why. UAV 1 stays flying where it was, and after `resume` the mission ends completed,
as the ground station reports it to a Master (served here by the operator process).
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from magna_common.processes import tagged_processes
from tests.support import ROOT

pytestmark = [pytest.mark.ros, pytest.mark.timeout(400)]

# (intent, action, agent, {name: (number, text, unit)}): each must be refused with a reason.
BAD_COMMANDS = [
    ("basic_action", "move", "1", {"direction": (0.0, "up", ""), "distance": (math.nan, "", "m")}),
    ("basic_action", "move", "1", {"direction": (0.0, "up", ""), "distance": (math.inf, "", "m")}),
    ("basic_action", "move", "1", {"direction": (0.0, "forward", ""), "distance": (1e308, "", "m")}),
    ("basic_action", "move", "1", {"direction": (0.0, "\u2191\U0001f681", ""), "distance": (1.0, "", "m")}),
    ("basic_action", "take_off", "2", {"height": (-math.inf, "", "m")}),
    ("basic_action", "turn", "1", {"angle": (math.nan, "", "deg")}),
    ("basic_action", "follow", "2", {"target": (math.nan, "", "")}),
    ("basic_action", "follow", "2", {"target": (math.inf, "", "")}),
    ("basic_action", "land", "1e400", {}),
    ("basic_action", "land", "\u00fc\U0001f681", {}),
    ("\u00e9tat", "get", "1", {}),
    ("parameters", "get", "1", {"altitude\u00b2": (0.0, "", "")}),
    ("algorithms", "set", "all", {"algorithm": (0.0, "orca\u00b3", "")}),
    ("mission", "abort\u2026", "all", {}),
]


def wall_wait(predicate, what, seconds=120.0):
    """A guard against a hang while waiting on a condition, never a timing expectation."""
    deadline = time.monotonic() + seconds
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def operator_session(out: Path) -> None:
    """The operator's side, in a process of its own (rospy allows one node per process)."""
    import numpy as np
    import rospy
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from magna_msgs.msg import NamedValue, SMStatus
    from magna_msgs.srv import GroundStationCommand, SimulationTermination, SimulationTerminationResponse
    from rosgraph_msgs.msg import Log
    from uav_abstraction_layer.msg import State
    from uav_abstraction_layer.srv import GoToWaypoint

    from magna_common.ros_names import GS_COMMAND, MASTER_TERMINATION, ual

    rospy.init_node("operator", anonymous=True, disable_signals=True)
    seen = {"states": set(), "position": None, "ual_state": None, "warnings": [], "result": None, "time": 0.0}

    def on_log(msg):
        if msg.level >= Log.WARN:
            seen["warnings"].append(msg.msg)

    def on_termination(req):
        seen["result"] = {"success": req.success, "outcome": req.outcome, "message": req.message}
        return SimulationTerminationResponse(True)

    rospy.Subscriber("/magna/sm/mission/status", SMStatus,
                     lambda msg: seen["states"].update(msg.active_states) if msg.path == "/MISSION" else None)
    rospy.Subscriber(ual(1, "pose"), PoseStamped, lambda msg: seen.update(
        position=np.array([msg.pose.position.x, msg.pose.position.y, msg.pose.position.z])))
    rospy.Subscriber(ual(1, "state"), State, lambda msg: seen.update(ual_state=msg.state))
    rospy.Subscriber("/rosout", Log, on_log)
    rospy.Service(MASTER_TERMINATION, SimulationTermination, on_termination)
    wall_wait(lambda: "operator_wait" in seen["states"], "the mission to wait for the operator", 240.0)
    wall_wait(lambda: seen["position"] is not None and seen["ual_state"] == State.FLYING_AUTO, "UAV 1 flying")
    station = seen["position"].copy()
    refusals = []

    # --- ground-station commands ---------------------------------------------------------------------------------
    rospy.wait_for_service(GS_COMMAND, timeout=30.0)
    command = rospy.ServiceProxy(GS_COMMAND, GroundStationCommand)
    for intent, action, agent, params in BAD_COMMANDS:
        values = [NamedValue(name=name, number=number, text=text, unit=unit)
                  for name, (number, text, unit) in params.items()]
        answer = command(intent=intent, action=action, agent=agent, parameters=values)
        assert not answer.accepted and answer.message.strip(), (intent, action, agent, params, answer)
        refusals.append(f"command {intent} {action} {agent!r}: {answer.message}")

    # --- UAL services: each call fails with the reason -----------------------------------------------------------
    go_to = rospy.ServiceProxy(ual(1, "go_to_waypoint"), GoToWaypoint)
    for target, reason in [((math.nan, 0.0, 3.0), "not three finite numbers"),
                           ((0.0, 0.0, math.inf), "not three finite numbers"),
                           ((1e6, 0.0, 3.0), "outside the world's boundaries"),
                           ((0.0, -1e308, 3.0), "outside the world's boundaries")]:
        waypoint = PoseStamped()
        waypoint.header.frame_id = "map"
        waypoint.pose.position.x, waypoint.pose.position.y, waypoint.pose.position.z = target
        waypoint.pose.orientation.w = 1.0
        try:
            go_to(waypoint=waypoint, blocking=False)
        except rospy.ServiceException as error:
            assert reason in str(error), (target, str(error))
            refusals.append(f"go_to_waypoint {target}: {error}")
        else:
            raise AssertionError(f"go_to_waypoint {target} was accepted")

    # --- UAL streams: refused with a warning naming why ------------------------------------------------------------
    set_pose = rospy.Publisher(ual(1, "set_pose"), PoseStamped, queue_size=10)
    set_velocity = rospy.Publisher(ual(1, "set_velocity"), TwistStamped, queue_size=10)
    wall_wait(lambda: set_pose.get_num_connections() and set_velocity.get_num_connections(), "the UAL's streams")
    for stream, make, reason in [
            (set_pose, lambda m: setattr(m.pose.position, "x", 1e6), "outside the world's boundaries"),
            (set_velocity, lambda m: setattr(m.twist.linear, "x", math.nan), "not three finite numbers")]:
        message = PoseStamped() if stream is set_pose else TwistStamped()
        message.header.frame_id = "map"
        if stream is set_pose:
            message.pose.position.z, message.pose.orientation.w = 3.0, 1.0
        make(message)
        before = len(seen["warnings"])
        name = "set_pose" if stream is set_pose else "set_velocity"

        def warned(name=name, reason=reason, before=before):
            return any(name in w and reason in w for w in seen["warnings"][before:])

        deadline = time.monotonic() + 60.0
        while not warned():  # the UAL throttles its warnings: repeat until one is heard
            assert time.monotonic() < deadline, f"no warning for {name}: {seen['warnings'][-5:]}"
            stream.publish(message)
            time.sleep(0.1)
        refusals.append(next(w for w in seen["warnings"][before:] if name in w and reason in w))

    # --- the UAV still flies where it was, and the mission goes on to its end ------------------------------------
    assert seen["ual_state"] == State.FLYING_AUTO, seen["ual_state"]
    drift = float(np.linalg.norm(seen["position"] - station))
    assert drift < 0.5, f"UAV 1 moved {drift:.2f} m while its bad set-points were refused"
    resume = command(intent="mission", action="resume", agent="all", parameters=[])
    assert resume.accepted, resume.message
    wall_wait(lambda: seen["result"] is not None, "the ground station's report", 240.0)
    out.write_text(json.dumps({"refusals": refusals, "result": seen["result"], "drift": drift}, indent=1))
    rospy.signal_shutdown("operator done")


def test_bad_commands_and_set_points_are_refused_and_the_mission_completes(fresh_ros_master, tmp_path, capsys):
    master = fresh_ros_master
    started = time.monotonic()
    launch = master.spawn(["roslaunch", "magna_gs", "simulation.launch",
                           f"mission_file:={ROOT / 'missions/Gym/Safe_Stop.json'}", "world:=Gym",
                           "subworld:=Central_Obstacle_Torus", f"data_dir:={tmp_path / 'data'}", "rtf:=5",
                           "bag:=false", "button_timeout:=0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    env = master.env()
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    out = tmp_path / "operator.json"
    operator = subprocess.run([sys.executable, __file__, str(out)], env=env, capture_output=True, text=True,
                              timeout=360, cwd=ROOT)
    assert operator.returncode == 0, operator.stdout[-3000:] + operator.stderr[-3000:]
    launch.wait(120)  # the ground station ended the mission, and the launch with it
    # Every node of the launch ended with it: nothing but the master itself is left on this master's URI.
    leftovers = [(pid, command) for pid, command in tagged_processes("ROS_MASTER_URI", master.uri, {os.getpid()})
                 if "rosmaster" not in command]
    assert leftovers == [], leftovers
    seen = json.loads(out.read_text())
    assert seen["result"]["outcome"] == "completed" and seen["result"]["success"], seen["result"]
    assert len(seen["refusals"]) == len(BAD_COMMANDS) + 4 + 2
    with capsys.disabled():
        print(f"\n[live] {len(seen['refusals'])} bad commands and set-points refused, UAV 1 drifted "
              f"{seen['drift']:.2f} m, mission {seen['result']['outcome']}, no process left "
              f"({time.monotonic() - started:.0f} s):")
        for refusal in seen["refusals"]:
            print(f"  {refusal[:160]}")


if __name__ == "__main__":
    operator_session(Path(sys.argv[1]))
