"""Introspection over a live master: structure and status topics, the snapshot service, the viewer node."""
import os
import subprocess
import threading
from pathlib import Path

import numpy as np
from magna_msgs.msg import SMStatus
from magna_msgs.srv import GetSMStructure
from PIL import Image

from magna_sm.draw import ACTIVE_FILL
from magna_sm.examples import filmed_delivery
from magna_sm.introspection import IntrospectionServer
from tests.support import WAIT, wait_until


def test_status_follows_every_transition_and_structure_is_served(rospy_node):
    rospy = rospy_node
    machine = filmed_delivery(step=0.05)
    server = IntrospectionServer("unit", machine, heartbeat=0.2).start()
    seen, lock = [], threading.Lock()

    def on_status(msg):
        if msg.path == "/MISSION" and msg.active_states:
            with lock:
                if not seen or seen[-1] != msg.active_states[0]:
                    seen.append(msg.active_states[0])

    subscriber = rospy.Subscriber("/magna/sm/unit/status", SMStatus, on_status, queue_size=1000)
    try:
        # Both ends connected: the server's publisher sends every transition from here on.
        wait_until(lambda: subscriber.get_num_connections() and server._status_pub.get_num_connections(),
                   "the status topic to connect")
        assert machine.execute() == "mission_completed"
        wait_until(lambda: "1_land" in seen, "the last transition on the status topic")
        rospy.wait_for_service("/magna/sm/unit/get_structure", timeout=5)
        containers = rospy.ServiceProxy("/magna/sm/unit/get_structure", GetSMStructure)().containers
    finally:
        subscriber.unregister()
        server.stop()
    with lock:
        assert [s for s in seen if s != "1_safe_land"] == ["spawn_agents", "1_take_off", "1_filmed_delivery",
                                                           "1_land"]
    by_path = {c.path: c for c in containers}
    assert set(by_path) == {"/MISSION", "/MISSION/1_filmed_delivery", "/MISSION/1_filmed_delivery/1_delivery",
                            "/MISSION/1_filmed_delivery/2_filming"}
    assert by_path["/MISSION/1_filmed_delivery"].container_type == "Concurrence"
    assert "mission_completed" in by_path["/MISSION"].container_outcomes


def test_viewer_node_redraws_the_live_machine(fresh_ros_master, tmp_path):
    picture = tmp_path / "live.png"
    demo = fresh_ros_master.spawn(["rosrun", "magna_sm", "demo", "--step", "0.4", "--repeat", "20"])
    viewer = fresh_ros_master.spawn(["rosrun", "magna_sm", "viewer", "demo", "-o", str(picture), "--period", "0.1"])
    target = np.array([int(ACTIVE_FILL[i:i + 2], 16) for i in (1, 3, 5)])

    def drawn():
        assert demo.poll() is None and viewer.poll() is None, "a node died"
        return picture.exists()

    def highlighted():  # the picture is replaced whole (written atomically) at each redraw
        drawn()
        pixels = np.asarray(Image.open(picture).convert("RGB"), dtype=int)
        return (np.abs(pixels - target).max(axis=2) <= 6).sum() > 100

    wait_until(drawn, "the viewer to draw the machine", timeout=3 * WAIT)
    wait_until(highlighted, "a redraw with an active state highlighted", timeout=3 * WAIT, poll=0.1)


def _free_display() -> int:
    return next(n for n in range(90, 200) if not Path(f"/tmp/.X11-unix/X{n}").exists()
                and not Path(f"/tmp/.X{n}-lock").exists())


def test_viewer_opens_a_window_when_a_display_exists(fresh_ros_master, tmp_path):
    display = _free_display()
    fresh_ros_master.spawn(["Xvfb", f":{display}", "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                           stderr=subprocess.DEVNULL)
    wait_until(lambda: Path(f"/tmp/.X11-unix/X{display}").exists(), "Xvfb to start")
    fresh_ros_master.spawn(["rosrun", "magna_sm", "demo", "--step", "0.4", "--repeat", "20"])
    log = tmp_path / "viewer.log"
    with log.open("w") as sink:
        viewer = fresh_ros_master.spawn(["rosrun", "magna_sm", "viewer", "demo", "-o", str(tmp_path / "w.png"),
                                         "--once", "--timeout", "30"],
                                        env={**os.environ, "DISPLAY": f":{display}"}, stdout=sink, stderr=sink)
        assert viewer.wait(timeout=60) == 0, log.read_text()
    assert (tmp_path / "w.png").exists()
    assert "no window" not in log.read_text(), log.read_text()
