"""The node as users start it: --help, bad parameters, and the hand-flying tool against a live sim."""
import math
import subprocess

import pytest

from magna_common.airframes import load_airframe
from tests.support import wait_until

ARRIVAL_RADIUS = 0.33 / 2  # the sim's default arrival radius for iris: half of UAL's position_th


def test_node_help_lists_the_parameters():
    out = subprocess.run(["rosrun", "magna_sim", "sim", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    for text in ("/uav_{id}/ual/", "~real_time_factor", "~flight_model", "sim.launch uavs:=3"):
        assert text in out.stdout


def test_fly_help_shows_examples():
    out = subprocess.run(["rosrun", "magna_sim", "fly", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "fly --id 1 take_off 2" in out.stdout


def test_bad_parameters_stop_the_node_with_a_named_field(fresh_ros_master, tmp_path):
    node = fresh_ros_master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=1", "_model:=zeppelin"],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output, _ = node.communicate(timeout=60)
    assert node.returncode == 2
    assert "airframe: " in output and "zeppelin.json: no such airframe" in output


def start_sim(master, *params):
    import rosgraph

    master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    node = master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=2", "_real_time_factor:=5", *params],
                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ros = rosgraph.Master("/test", master_uri=master.uri)
    wait_until(lambda: ros.hasParam("/ual_ids") and len(ros.getParam("/ual_ids")) == 2, "two UAL ids", timeout=60)
    return node


@pytest.fixture
def sim(fresh_ros_master):
    node = start_sim(fresh_ros_master)
    yield fresh_ros_master
    assert node.poll() is None, "the sim died during the test"


def fly(master, *args):
    out = subprocess.run(["rosrun", "magna_sim", "fly", *args], capture_output=True, text=True, timeout=120,
                         env=master.env())
    return out.returncode, out.stdout + out.stderr


def printed_position(text):
    return tuple(float(v) for v in text.split("(")[1].split(")")[0].split(","))


def position_at_rest(master, uav_id):
    """The position `fly state` prints twice in a row (each call spans simulated seconds): the UAV holds it."""
    readings = []

    def at_rest():
        readings.append(printed_position(fly(master, "--id", str(uav_id), "state")[1]))
        return len(readings) >= 2 and math.dist(readings[-1], readings[-2]) <= 0.01

    wait_until(at_rest, f"UAV {uav_id} to hold its position", timeout=120, poll=0)
    return readings[-1]


def test_fly_a_uav_by_hand(sim):
    assert fly(sim, "--id", "2", "state")[1].strip().startswith("uav 2: LANDED_ARMED at (0.00, 1.00, 0.00)")
    code, text = fly(sim, "--id", "2", "take_off", "2")
    assert code == 0 and "uav 2: FLYING_AUTO" in text
    code, text = fly(sim, "--id", "2", "go_to", "3", "1", "2.5", "--yaw", "90")
    assert code == 0 and "FLYING_AUTO" in text
    assert math.dist(printed_position(text), (3.0, 1.0, 2.5)) <= ARRIVAL_RADIUS
    code, text = fly(sim, "--id", "2", "velocity", "0", "0.5", "0", "--duration", "2")
    assert code == 0
    streamed = printed_position(text)  # read once the stream of set-points ended
    rest = position_at_rest(sim, 2)
    # 0.5 m/s along y for 2 s of simulated time, then on for at most the velocity timeout (1 s of simulated
    # time without a set-point) before it holds: at least the 1 m streamed, less a start, and no further.
    # (How far the stream reaches is up to fly's clock, a subscriber that may lag behind the simulator's.)
    assert rest[1] - 1.0 >= 0.8, (streamed, rest)
    assert rest[1] - streamed[1] <= 0.5 * 1.0 + 0.15, (streamed, rest)
    assert math.dist(rest[::2], (3.0, 2.5)) <= ARRIVAL_RADIUS  # x and z as the go_to left them
    code, text = fly(sim, "--id", "2", "land")
    assert code == 0 and "uav 2: LANDED_ARMED" in text


def test_fly_refusals_are_clear(sim):
    code, text = fly(sim, "--id", "7", "state")
    assert code == 1 and "no UAL server for UAV 7; /ual_ids = [1, 2]" in text
    code, text = fly(sim, "--id", "1", "land")
    # the server's reason, not rospy's wrapping of it (service [...] responded with an error: b'service ...')
    assert code == 1 and text.strip() == ("fly: /uav_1/ual/land: land refused: UAV 1 is LANDED_ARMED; "
                                          "land needs FLYING_AUTO")


def test_blocking_take_off_and_go_to_return_only_once_the_uav_is_there(sim):
    # UAV 1 starts at (0, -1, 0). The printed pose is read after the call returned.
    code, text = fly(sim, "--id", "1", "take_off", "2")
    assert code == 0 and "uav 1: FLYING_AUTO" in text
    assert math.dist(printed_position(text), (0.0, -1.0, 2.0)) <= ARRIVAL_RADIUS
    code, text = fly(sim, "--id", "1", "go_to", "3", "0", "2")
    assert code == 0 and "uav 1: FLYING_AUTO" in text
    assert math.dist(printed_position(text), (3.0, 0.0, 2.0)) <= ARRIVAL_RADIUS
    assert ARRIVAL_RADIUS <= load_airframe("iris").accepted_target_radius


def test_a_waypoint_out_of_reach_fails_as_not_reached(sim):
    assert fly(sim, "--id", "1", "take_off", "1")[0] == 0
    code, text = fly(sim, "--id", "1", "go_to", "3", "-1", "-1")  # under the ground: the UAV stops on it
    assert code == 1
    assert text.startswith("fly: /uav_1/ual/go_to_waypoint: go_to_waypoint not reached: UAV 1 is at "
                           "(3.00, -1.00, 0.00), 1.00 m from (3.00, -1.00, -1.00), and has come no nearer in "
                           "10 s of simulated time"), text
    code, text = fly(sim, "--id", "1", "go_to", "3", "-1", "1")  # still under command: fly on
    assert code == 0 and math.dist(printed_position(text), (3.0, -1.0, 1.0)) <= ARRIVAL_RADIUS


def test_dynamic_model_flies_through_the_same_api(fresh_ros_master):
    """take_off, go_to_waypoint (with a heading), set_velocity and land: what test_fly_a_uav_by_hand flies."""
    node = start_sim(fresh_ros_master, "_flight_model:=dynamic", "_model:=typhoon_h480")
    code, text = fly(fresh_ros_master, "--id", "1", "take_off", "1.5")
    assert code == 0 and "uav 1: FLYING_AUTO" in text
    assert math.dist(printed_position(text), (0.0, -1.0, 1.5)) <= ARRIVAL_RADIUS
    code, text = fly(fresh_ros_master, "--id", "1", "go_to", "3", "-1", "2.5", "--yaw", "90")
    assert code == 0 and "uav 1: FLYING_AUTO" in text
    assert math.dist(printed_position(text), (3.0, -1.0, 2.5)) <= ARRIVAL_RADIUS
    code, text = fly(fresh_ros_master, "--id", "1", "velocity", "0", "0.5", "0", "--duration", "2")
    assert code == 0
    streamed = printed_position(text)
    rest = position_at_rest(fresh_ros_master, 1)  # checked as test_fly_a_uav_by_hand checks the light model
    assert rest[1] - (-1.0) >= 0.8, (streamed, rest)
    assert rest[1] - streamed[1] <= 0.5 * 1.0 + 0.15, (streamed, rest)
    code, text = fly(fresh_ros_master, "--id", "1", "land")
    assert code == 0 and "uav 1: LANDED_ARMED" in text and printed_position(text)[2] < 0.05
    assert node.poll() is None


def test_depth_camera_publishes_metric_images(fresh_ros_master):
    node = start_sim(fresh_ros_master, "_depth_camera/enabled:=true", "_depth_camera/width:=32",
                     "_depth_camera/height:=24")
    script = (
        "import time, rospy, numpy as np\n"
        "from sensor_msgs.msg import Image, CameraInfo\n"
        "from magna_msgs.srv import SpawnModel, SpawnModelRequest\n"
        "rospy.init_node('depth_probe')\n"
        "rospy.wait_for_service('/magna/sim/spawn_model', timeout=30)\n"
        "wall = SpawnModelRequest(name='wall', kind='obstacle', shape='cube', dimensions=[1, 6, 6])\n"
        "wall.pose.position.x, wall.pose.position.y, wall.pose.orientation.w = 3.0, -1.0, 1.0\n"
        "assert rospy.ServiceProxy('/magna/sim/spawn_model', SpawnModel)(wall).success\n"
        "def depth_image():\n"
        "    image = rospy.wait_for_message('/uav_1/camera/depth/image_raw', Image, timeout=30)\n"
        "    return image, np.frombuffer(image.data, dtype='<f4').reshape(image.height, image.width)\n"
        "image, depth = depth_image()\n"
        "deadline = time.monotonic() + 30\n"
        "while not np.isfinite(depth[6, 16]) and time.monotonic() < deadline:  # an image drawn before the spawn\n"
        "    image, depth = depth_image()\n"
        "info = rospy.wait_for_message('/uav_1/camera/depth/camera_info', CameraInfo, timeout=30)\n"
        "print(image.encoding, image.width, image.height, info.K[0] > 0, round(float(depth[6, 16]), 2))\n")
    out = subprocess.run(["python", "-c", script], capture_output=True, text=True, timeout=90,
                         env=fresh_ros_master.env())
    # UAV 1 stands at (0, -1, 0) looking along +x; above the horizon (row 6) it sees the wall face at x = 2.5.
    assert out.stdout.split() == ["32FC1", "32", "24", "True", "2.5"], out.stderr
    assert node.poll() is None


def test_pause_stops_simulated_time_but_not_spawning_or_the_ual_topics(fresh_ros_master):
    node = start_sim(fresh_ros_master, "_start_paused:=true")
    # Counted /clock messages and simulated time, never wall time: paused, the simulator sends the frozen time
    # again and again (once per publishing period); running, every message carries a new time.
    script = (
        "import threading, time, rospy\n"
        "from geometry_msgs.msg import PoseStamped\n"
        "from rosgraph_msgs.msg import Clock\n"
        "from std_srvs.srv import SetBool\n"
        "from magna_msgs.srv import SpawnModel, SpawnModelRequest\n"
        "rospy.init_node('pause_probe')\n"
        "heard, arrived = [], threading.Condition()\n"
        "def on_clock(msg):\n"
        "    with arrived:\n"
        "        heard.append(msg.clock.to_sec())\n"
        "        arrived.notify_all()\n"
        "rospy.Subscriber('/clock', Clock, on_clock)\n"
        "def until(condition):\n"
        "    with arrived:\n"
        "        assert arrived.wait_for(lambda: condition(heard), timeout=30), 'timed out on /clock'\n"
        "        return list(heard)\n"
        "def next_clocks(n):\n"
        "    start = len(until(lambda h: h))\n"
        "    return until(lambda h: len(h) >= start + n)[start:start + n]\n"
        "def standing(h, n=10):\n"
        "    return len(h) >= n and len(set(h[-n:])) == 1\n"
        "rospy.wait_for_service('/magna/sim/pause', timeout=30)\n"
        "pause = rospy.ServiceProxy('/magna/sim/pause', SetBool)\n"
        "still = next_clocks(10)\n"
        "first = still[0]\n"
        "pose = rospy.wait_for_message('/uav_2/ual/pose', PoseStamped, timeout=30)\n"
        "uav = SpawnModelRequest(name='uav_3', kind='uav', uav_id=3)\n"
        "uav.pose.position.x, uav.pose.orientation.w = 4.0, 1.0\n"
        "spawned = rospy.ServiceProxy('/magna/sim/spawn_model', SpawnModel)(uav).success\n"
        "third = rospy.wait_for_message('/uav_3/ual/pose', PoseStamped, timeout=30).pose.position.x\n"
        "resumed = pause(data=False).message\n"
        "running = until(lambda h: h[-1] > first + 1.0)[-1]\n"
        "paused = pause(data=True).message\n"
        "paused_at = float(paused.split('t=')[1].split()[0])\n"
        "frozen = until(standing)[-1]\n"
        "after = next_clocks(10)\n"
        "print(set(still) == {first}, pose.header.stamp.to_sec() == first, spawned, third,\n"
        "      resumed.startswith('resumed'), running > first + 1.0, paused.startswith('paused'),\n"
        "      set(after) == {frozen} and -0.0005 <= frozen - paused_at < 0.1)\n")  # the answer says t to ms
    out = subprocess.run(["python", "-c", script], capture_output=True, text=True, timeout=120,
                         env=fresh_ros_master.env())
    # paused: the clock stands, poses come with the frozen time, a UAV spawns; resumed: it runs; paused: it stands
    assert out.stdout.split() == ["True", "True", "True", "4.0", "True", "True", "True", "True"], out.stderr
    assert node.poll() is None


def test_ids_left_in_ual_ids_by_a_killed_sim_do_not_stop_the_next_one(fresh_ros_master):
    import rosgraph

    # A simulator killed with SIGKILL leaves its ids in /ual_ids with no server behind them.
    fresh_ros_master.spawn(["rosparam", "set", "/ual_ids", "[1, 2]"]).wait(timeout=30)
    node = fresh_ros_master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=2", "_real_time_factor:=5"],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    ros = rosgraph.Master("/test", master_uri=fresh_ros_master.uri)

    def served_or_ended():
        if node.poll() is not None:
            return True
        try:
            ros.lookupService("/uav_2/ual/take_off")
        except rosgraph.MasterError:
            return False
        return True

    wait_until(served_or_ended, "UAV 2's UAL served, or the sim ended", timeout=60)
    assert node.poll() is None, node.communicate()[0][-2000:]
    assert sorted(ros.getParam("/ual_ids")) == [1, 2]
