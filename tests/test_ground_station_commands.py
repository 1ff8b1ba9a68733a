"""An operator commands a running mission through /magna/gs/command: questions are answered,
moves fly, bad requests are refused with the reason, and resume lets the mission finish.

The project's Safe_Stop mission waits for the operator's button after reaching its stations;
the test drives it there through the whole stack (simulation.launch on a private master).

A `real` UAV takes no operator command unless the mission opens it to the operator (issue 26): the same
mission with UAV 2 `real` (magna_mavlink's scripted PX4 over UDP as its autopilot, in wall time, so this
mission runs at real time) refuses every command
that would move it, "all" included, flies the ones for UAV 1, and still answers questions about UAV 2.
"""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from magna_common.ports import free_udp_ports
from tests.support import ROOT, load_module

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]


def fake_autopilot_class():
    """magna_mavlink's scripted autopilot (a test helper of that package, so loaded from its file)."""
    # its own name: magna_mavlink's conftest imports the same file as fake_autopilot
    return load_module(ROOT / "src" / "magna_mavlink" / "test" / "fake_autopilot.py",
                       "magna_mavlink_fake_autopilot").FakeAutopilot


def wall_wait(predicate, what, seconds=120.0):
    deadline = time.monotonic() + seconds
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def operator_session(data_dir: Path) -> None:
    """The operator's side, in a process of its own (rospy allows one node per process, and the
    pytest process already has one on another master)."""
    import rospy
    from geometry_msgs.msg import PoseStamped
    from magna_msgs.msg import CriticalEvent, NamedValue, SMStatus
    from magna_msgs.srv import GroundStationCommand, StateActualization

    rospy.init_node("operator", anonymous=True, disable_signals=True)
    seen = {"states": [], "z": None, "events": []}
    rospy.Subscriber("/magna/gs/critical_events", CriticalEvent, lambda msg: seen["events"].append(msg))
    rospy.Subscriber("/magna/sm/mission/status", SMStatus,
                     lambda msg: seen["states"].extend(msg.active_states) if msg.path == "/MISSION" else None)
    rospy.Subscriber("/uav_1/ual/pose", PoseStamped, lambda msg: seen.update(z=msg.pose.position.z))
    wall_wait(lambda: "operator_wait" in seen["states"], "the mission to wait for the operator")
    rospy.wait_for_service("/magna/gs/command", timeout=10.0)
    command = rospy.ServiceProxy("/magna/gs/command", GroundStationCommand)

    def ask(intent, action, agent, **params):
        values = [NamedValue(name=k, number=v if isinstance(v, float | int) else 0.0,
                             text=v if isinstance(v, str) else "", unit={"distance": "m"}.get(k, ""))
                  for k, v in params.items()]
        return command(intent=intent, action=action, agent=agent, parameters=values)

    battery = ask("parameters", "get", "all", battery="")
    assert battery.accepted, battery.message
    levels = {v.name: v.number for v in battery.values}
    assert set(levels) == {"uav_1.battery", "uav_2.battery"} and all(0 < x <= 100 for x in levels.values()), levels

    refused = ask("basic_action", "land", "7")
    assert not refused.accepted and "UAV 7 is not in this mission" in refused.message, refused.message
    too_high = ask("basic_action", "move", "1", direction="up", distance=100.0)
    assert not too_high.accepted and "would leave the world" in too_high.message, too_high.message

    start = seen["z"]
    moved = ask("basic_action", "move", "1", direction="up", distance=1.0)
    assert moved.accepted, moved.message
    wall_wait(lambda: seen["z"] is not None and seen["z"] > start + 0.8, "UAV 1 to climb 1 m", 60.0)

    # A critical event a manager reports is on /magna/gs/critical_events at once (the studio lists them).
    report = rospy.ServiceProxy("/magna/gs/state_actualization", StateActualization)
    assert report(id=2, state="hovering", critical_event="low_battery").success
    wall_wait(lambda: any(e.uav_id == 2 and e.event == "low_battery" and e.detail == "hovering" and e.sim_time > 0
                          for e in seen["events"]), "the low battery on /magna/gs/critical_events", 30.0)

    assert ask("mission", "resume", "all").accepted
    rospy.signal_shutdown("operator done")


def test_operator_commands_on_a_running_mission(fresh_ros_master, tmp_path):
    master = fresh_ros_master
    launch = master.spawn(["roslaunch", "magna_gs", "simulation.launch",
                           f"mission_file:={ROOT / 'missions/Gym/Safe_Stop.json'}", "world:=Gym",
                           "subworld:=Central_Obstacle_Torus", f"data_dir:={tmp_path}", "rtf:=5", "bag:=false",
                           "button_timeout:=0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    env = master.env()
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    operator = subprocess.run([sys.executable, __file__, str(tmp_path)], env=env, capture_output=True,
                              text=True, timeout=240, cwd=ROOT)
    assert operator.returncode == 0, operator.stdout[-3000:] + operator.stderr[-3000:]
    launch.wait(120)  # resumed: the ground station finishes the mission and the launch ends with it
    assert (tmp_path / "uav_1.csv").is_file() and (tmp_path / "uav_2.csv").is_file()


def real_uav_operator_session() -> None:
    """The operator's side against the mission whose UAV 2 is real and not opened to the operator."""
    import rospy
    from magna_msgs.msg import NamedValue, SMStatus
    from magna_msgs.srv import GroundStationCommand

    rospy.init_node("operator", anonymous=True, disable_signals=True)
    seen = {"states": []}
    rospy.Subscriber("/magna/sm/mission/status", SMStatus,
                     lambda msg: seen["states"].extend(msg.active_states) if msg.path == "/MISSION" else None)
    wall_wait(lambda: "operator_wait" in seen["states"], "the mission to wait for the operator", 180.0)
    rospy.wait_for_service("/magna/gs/command", timeout=10.0)
    command = rospy.ServiceProxy("/magna/gs/command", GroundStationCommand)
    up = [NamedValue(name="direction", text="up"), NamedValue(name="distance", number=1.0, unit="m")]

    for agent in ("2", "all"):
        refused = command(intent="basic_action", action="move", agent=agent, parameters=up)
        assert not refused.accepted, f"{agent}: {refused.message}"
        assert "UAV 2 is a real UAV" in refused.message and '"allow_real": [2]' in refused.message, refused.message
    position = command(intent="parameters", action="get", agent="2", parameters=[NamedValue(name="position")])
    assert position.accepted, position.message  # a question moves nothing: it is answered
    moved = command(intent="basic_action", action="move", agent="1", parameters=up)
    assert moved.accepted, moved.message
    assert command(intent="mission", action="resume", agent="all", parameters=[]).accepted
    rospy.signal_shutdown("operator done")


def test_a_real_uav_takes_no_operator_command_unless_the_mission_allows_it(fresh_ros_master, tmp_path, request):
    mission = json.loads((ROOT / "missions/Gym/Safe_Stop.json").read_text())
    assert mission["Agents_Config"][1]["ID"] == 2
    mission["Agents_Config"][1]["mode"] = "real"  # no "Operator_Commands": the operator may not command it
    mission_file = tmp_path / "Safe_Stop_Real_UAV_2.json"
    mission_file.write_text(json.dumps(mission))
    # UAV 2's autopilot: magna_mavlink's scripted PX4 over UDP (a real UAV has no stand-in in magna_sim)
    port = free_udp_ports(1)[0]
    fleet = tmp_path / "fleet.yaml"
    fleet.write_text(f"uavs:\n  2:\n    url: udpin:127.0.0.1:{port}\n    autopilot: px4\n    arming: auto\n")
    autopilot = fake_autopilot_class()(f"udpout:127.0.0.1:{port}", system_id=2).start()
    request.addfinalizer(autopilot.stop)
    master = fresh_ros_master
    launch = master.spawn(["roslaunch", "magna_gs", "simulation.launch", f"mission_file:={mission_file}",
                           "world:=Gym", "subworld:=Central_Obstacle_Torus", f"data_dir:={tmp_path / 'data'}",
                           "rtf:=1", "bag:=false", "button_timeout:=0", f"fleet:={fleet}", "output:=screen"],
                          stdout=(tmp_path / "launch.log").open("w"), stderr=subprocess.STDOUT)
    env = master.env()
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    operator = subprocess.run([sys.executable, __file__, "--real"], env=env, capture_output=True, text=True,
                              timeout=240, cwd=ROOT)
    launch_log = (tmp_path / "launch.log").read_text()
    assert operator.returncode == 0, operator.stdout[-3000:] + operator.stderr[-3000:] + launch_log[-6000:]
    launch.wait(120)
    assert (tmp_path / "data" / "uav_2.csv").is_file()


if __name__ == "__main__":
    if sys.argv[1] == "--real":
        real_uav_operator_session()
    else:
        operator_session(Path(sys.argv[1]))
