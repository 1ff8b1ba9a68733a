"""A UTM plan change in flight, through the whole stack: the UAV flies its mission path, the UTM issues a
new plan, the follow_path ends with utm_new_flightplan, and the mission's "from utm" state flies the new
plan to success.

simulation.launch runs on a private master with utm_plan:=FILE; an observer process serves the Master's
termination service and records the states the mission went through.
"""
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(400)]
ROOT = Path(__file__).resolve().parents[3]


def spot(x, y, z):
    """A point in the Ground_Station volume's frame (its origin is at y = -11 in Gym/Four_Cylinders)."""
    return {"definition": ["Ground_Station", "volume", "coordinates", [[x, y, z], [0, 0, 0, 1]]]}


ROUTE = [spot(9, 3, 3), spot(-9, 3, 3), spot(9, 3, 3), spot(-9, 3, 3), spot(9, 3, 3)]  # ~80 m, 40 s and more
NEW_PLAN_END = [3.0, -5.0, 3.0]  # map frame
MISSION = {
    "Agents_Config": [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]}],
    "State_Machine": [
        {"type": "CBState", "state_type": "world_config", "name": "new_world",
         "parameters": {"action": "spawn", "id": 1}, "outcomes": {"completed": "add_world"}},
        {"type": "CBState", "state_type": "world_config", "name": "add_world",
         "parameters": {"action": "add", "world_part_def": "from_hyperparameters"}, "outcomes": {"completed": "spawn"}},
        {"type": "CBState", "state_type": "spawn_agents", "name": "spawn",
         "parameters": {"initial_poses": [["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]]]},
         "outcomes": {"completed": "1_take_off", "failed": "failed"}},
        {"type": "SimpleActionState", "state_type": "take_off", "name": "take_off", "ids": 1,
         "parameters": {"height": 3}, "outcomes": {"succeeded": "1_route", "aborted": "failed"}},
        # the route is long: the plan change (at 12 s) comes while the UAV flies it; it must not end otherwise
        {"type": "SimpleActionState", "state_type": "follow_path", "name": "route", "ids": 1,
         "parameters": {"path": ROUTE, "dynamic": "position"},
         "outcomes": {"succeeded": "failed", "utm_new_flightplan": "1_replanned", "aborted": "failed",
                      "collision": "failed", "preempted": "failed"}},
        {"type": "SimpleActionState", "state_type": "follow_path", "name": "replanned", "ids": 1,
         "parameters": {"path": "from utm", "dynamic": "position"},
         "outcomes": {"succeeded": "1_land", "utm_new_flightplan": "1_replanned", "aborted": "failed",
                      "collision": "failed", "preempted": "failed"}},
        {"type": "SimpleActionState", "state_type": "land", "name": "land", "ids": 1,
         "outcomes": {"succeeded": "completed", "aborted": "failed"}},
    ],
}
PLAN = {"flight_plans": [{"ids": [1], "at": 12.0,
                          "waypoints": [[0.0, -5.0, 3.0], ["Ground_Station", "volume", "coordinates",
                                                           [[3, 6, 3], [0, 0, 0, 1]]]]}],
        "conflict": {"distance": 3, "time": 3}}


def observer(out: Path) -> None:
    """Serve the Master's termination service and record the mission's states, in a process of its own."""
    import rospy
    from magna_msgs.msg import SMStatus
    from magna_msgs.srv import SimulationTermination, SimulationTerminationResponse

    rospy.init_node("observer", anonymous=True, disable_signals=True)
    seen = {"states": [], "result": None}

    def on_status(msg):
        if msg.path == "/MISSION":
            seen["states"].extend(s for s in msg.active_states if not seen["states"] or seen["states"][-1] != s)

    def on_termination(req):
        seen["result"] = {"success": req.success, "outcome": req.outcome, "message": req.message}
        return SimulationTerminationResponse(True)

    rospy.Subscriber("/magna/sm/mission/status", SMStatus, on_status)
    rospy.Service("/magna/master/simulation_termination", SimulationTermination, on_termination)
    deadline = time.monotonic() + 300
    while seen["result"] is None and time.monotonic() < deadline:
        time.sleep(0.05)
    out.write_text(json.dumps(seen))
    rospy.signal_shutdown("observer done")


def test_a_plan_change_in_flight_is_flown(fresh_ros_master, tmp_path):
    mission_file, plan_file = tmp_path / "utm_mission.json", tmp_path / "plan.json"
    mission_file.write_text(json.dumps(MISSION))
    plan_file.write_text(json.dumps(PLAN))
    data_dir = tmp_path / "data"
    env = fresh_ros_master.env()
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    seen_file = tmp_path / "seen.json"
    watcher = subprocess.Popen([sys.executable, __file__, str(seen_file)], env=env, cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    launch = fresh_ros_master.spawn(["roslaunch", "magna_gs", "simulation.launch", f"mission_file:={mission_file}",
                                     "world:=Gym", "subworld:=Four_Cylinders", f"data_dir:={data_dir}", "rtf:=5",
                                     "bag:=false", f"utm_plan:={plan_file}"],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 320
    while watcher.poll() is None and launch.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    if watcher.poll() is None:  # the launch ended (or hung) without a report
        time.sleep(2.0)
        watcher.kill()
    _, errors = watcher.communicate(timeout=30)
    launch.wait(120)
    assert seen_file.is_file(), f"the observer recorded nothing: {errors[-3000:]}"
    seen = json.loads(seen_file.read_text())
    result = seen["result"]
    assert result is not None, f"the ground station never reported; states: {seen['states']}"
    assert result["success"] and result["outcome"] == "completed", result
    states = seen["states"]
    assert states.index("1_route") < states.index("1_replanned") < states.index("1_land"), states

    with (data_dir / "uav_1.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    outcomes = [r["outcome"] for r in rows if r["outcome"]]
    # take-off, the route ended by the new plan, the new plan flown, landing
    assert outcomes == ["succeeded", "utm_new_flightplan", "succeeded", "succeeded"], outcomes
    ended = next(i for i, r in enumerate(rows) if r["outcome"] == "utm_new_flightplan")
    flown = next(i for i, r in enumerate(rows) if i > ended and r["outcome"] == "succeeded")
    end = np.array([float(rows[flown][a]) for a in ("pos.x", "pos.y", "pos.z")])
    assert np.linalg.norm(end - NEW_PLAN_END) < 1.0, end  # the new plan's last waypoint (from a pose definition)


if __name__ == "__main__":
    observer(Path(sys.argv[1]))
