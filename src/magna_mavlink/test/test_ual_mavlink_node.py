"""The ual_mavlink node as users start it, against the scripted autopilot: exit 2 naming the URL when nothing
answers, the UAL topics and services under /uav_{id}/ual/ with magna_sim's frame ids, /ual_ids, the telemetry it
asks for, the link topic and UNINITIALIZED when the autopilot falls silent, a pilot's take-over, and its id out of
/ual_ids when it ends."""
import subprocess

import pytest
from fake_autopilot import FakeAutopilot

from magna_common.ports import free_port
from magna_common.processes import end_process_group
from magna_mavlink.link import mavlink
from tests.support import wait_until

UAV = 47  # an id no other test on the session's master uses
WAIT = 30.0


def run_node(master, *args):
    return subprocess.run(["rosrun", "magna_mavlink", "ual_mavlink", *args], capture_output=True, text=True,
                          timeout=120, env=master.env())


def test_no_vehicle_at_the_url_exits_2_with_one_line_naming_it(fresh_ros_master):
    url = f"udpin:127.0.0.1:{free_port(udp=True)}"
    out = run_node(fresh_ros_master, "--id", "5", "--url", url, "--connect-timeout", "1")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines()[-1] == (
        f"ual_mavlink: UAV 5: no heartbeat from system 5 at {url} within 1 s: is the vehicle on, and does it send "
        f"to this port? (magna doctor --mavlink {url} checks a link)")


def test_bad_settings_exit_2_naming_the_option(fresh_ros_master):
    out = run_node(fresh_ros_master, "--id", "5", "--url", "udp://:14540")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines()[-1].startswith("ual_mavlink: --url udp://:14540: write the URL as")


class Listener:
    def __init__(self, rospy, topic, kind):
        self.msg = None
        self.subscriber = rospy.Subscriber(topic, kind, self._store, queue_size=1)

    def _store(self, msg):
        self.msg = msg


@pytest.fixture
def node(rospy_node, ros_master):
    port = free_port(udp=True)
    fake = FakeAutopilot(f"udpout:127.0.0.1:{port}", system_id=UAV).start()
    process = ros_master.spawn(["rosrun", "magna_mavlink", "ual_mavlink", "--id", str(UAV), "--url",
                                f"udpin:127.0.0.1:{port}", "--heartbeat-timeout", "1.5"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield fake, process, f"udpin:127.0.0.1:{port}"
    finally:
        end_process_group(process)
        fake.stop()


def test_the_ual_api_over_a_mavlink_link(rospy_node, node):
    import rospy
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import BatteryState
    from std_msgs.msg import String
    from uav_abstraction_layer.msg import State
    from uav_abstraction_layer.srv import Land, TakeOff

    fake, process, url = node
    ns = f"/uav_{UAV}/ual/"
    state = Listener(rospy, ns + "state", State)
    pose = Listener(rospy, ns + "pose", PoseStamped)
    velocity = Listener(rospy, ns + "velocity", TwistStamped)
    odom = Listener(rospy, ns + "odom", Odometry)
    battery = Listener(rospy, f"/uav_{UAV}/mavros/battery", BatteryState)
    link = Listener(rospy, f"/uav_{UAV}/ual_mavlink/link", String)
    wait_until(lambda: state.msg is not None and state.msg.state == State.LANDED_ARMED, "LANDED_ARMED", WAIT)
    assert UAV in rospy.get_param("/ual_ids")
    wait_until(lambda: pose.msg and velocity.msg and odom.msg and battery.msg and link.msg, "every topic", WAIT)
    assert (pose.msg.header.frame_id, velocity.msg.header.frame_id) == ("map", "map")
    assert (odom.msg.header.frame_id, odom.msg.child_frame_id) == ("map", f"uav_{UAV}/base_link")
    assert link.msg.data == "" and battery.msg.percentage == pytest.approx(0.8)
    wait_until(lambda: any(c.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL and c.param1 == 32
                           and c.param2 == pytest.approx(1e6 / 30) for c in list(fake.commands)),
               "LOCAL_POSITION_NED asked for at 30 Hz (MAV_CMD_SET_MESSAGE_INTERVAL)", WAIT)

    rospy.wait_for_service(ns + "land", timeout=WAIT)
    with pytest.raises(rospy.ServiceException, match=f"land refused: UAV {UAV} is LANDED_ARMED; land needs "
                                                     f"FLYING_AUTO"):
        rospy.ServiceProxy(ns + "land", Land)(blocking=True)
    rospy.ServiceProxy(ns + "take_off", TakeOff)(height=1.0, blocking=True)
    wait_until(lambda: state.msg.state == State.FLYING_AUTO, "FLYING_AUTO", WAIT)
    assert pose.msg.pose.position.z == pytest.approx(1.0, abs=0.2)

    fake.pilot_selects("POSCTL")  # a safety pilot takes over
    wait_until(lambda: state.msg.state == State.FLYING_MANUAL, "FLYING_MANUAL", WAIT)
    fake.heartbeat = False  # the link goes
    lost = f"no heartbeat from {url} for 1.5 s (nor any other message)"
    wait_until(lambda: link.msg.data == lost, "the link topic to say so", WAIT)
    wait_until(lambda: state.msg.state == State.UNINITIALIZED, "UNINITIALIZED", WAIT)
    fake.heartbeat = True
    wait_until(lambda: link.msg.data == "", "the link back", WAIT)

    end_process_group(process, grace=20.0)  # SIGINT, as Ctrl-C or roslaunch; rospy's shutdown is slow under load
    assert process.returncode == 0, "ual_mavlink ended by SIGINT, not killed"
    assert UAV not in rospy.get_param("/ual_ids")
