"""ual_mavlink in front of magna_sim's PX4-like MAVLink vehicle (UAVs spawned with interface "mavlink": no UAL of
magna_sim's own, free UDP ports), as a hardware-in-the-loop UAV is flown:

- magna_sim's UAL behaviour cases (UalBehaviour of src/magna_sim/test/ual_api_rostest.py, run by
  ual_behaviour_runner.py) pass against two ual_mavlink bridges;
- frames, live: an ENU +x velocity moves the vehicle east, seen in the UAL pose and in the vehicle's own
  LOCAL_POSITION_NED (+y, east), and an ENU heading of 90 degrees is the vehicle's NED yaw 0;
- `rosrun magna_sim fly` flies the MAVLink UAV: take_off, go_to, velocity, land.
"""
import math
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from magna_common.ports import free_udp_ports
from magna_mavlink.link import MavlinkLink
from tests.support import wait_until

HERE = Path(__file__).resolve().parent
ORIGIN = (37.41, -6.0, 0.0)  # the map's geo origin, given to magna_sim and to each bridge
RTF = "2"
TIMEOUT = 240  # s for one command: a guard against hangs

SPAWN = """
import sys, rospy
from magna_msgs.srv import SpawnModel, SpawnModelRequest
rospy.init_node("mavlink_stand_in_spawner", anonymous=True)
rospy.wait_for_service("/magna/sim/spawn_model", timeout=60)
spawn = rospy.ServiceProxy("/magna/sim/spawn_model", SpawnModel)
words = sys.argv[1:]
for index in range(0, len(words), 4):
    uav_id, y, local, remote = int(words[index]), float(words[index + 1]), int(words[index + 2]), int(words[index + 3])
    request = SpawnModelRequest(name=f"uav_{uav_id}", kind="uav", uav_id=uav_id, airframe="iris", interface="mavlink",
                                mavlink_local_port=local, mavlink_remote_port=remote)
    request.pose.position.y, request.pose.orientation.w = y, 1.0
    answer = spawn(request)
    assert answer.success, answer.message
    print(answer.message)
"""


class StandIns:
    """magna_sim with MAVLink-only UAVs, and one ual_mavlink bridge each (udpin on the port the vehicle sends to)."""

    def __init__(self, master, ids, logs: Path):
        import rosgraph

        self.master, self.ids, self.logs = master, ids, logs
        logs.mkdir(parents=True, exist_ok=True)
        master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=60)
        master.spawn(["rosparam", "set", "/magna_sim/map_origin_geo", str(list(ORIGIN))]).wait(timeout=60)
        self.processes = [master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=0", f"_real_time_factor:={RTF}"],
                                       stdout=self._log("sim"), stderr=subprocess.STDOUT)]
        ports = free_udp_ports(2 * len(ids))
        self.local_port = dict(zip(ids, ports[::2], strict=True))  # the vehicle binds it (a GCS writes there)
        self.remote_port = dict(zip(ids, ports[1::2], strict=True))  # the vehicle sends there: the bridge listens
        args = []
        for index, uav_id in enumerate(ids):
            args += [uav_id, 2.0 * index - 1.0, self.local_port[uav_id], self.remote_port[uav_id]]
        spawned = subprocess.run([sys.executable, "-c", SPAWN, *map(str, args)], capture_output=True, text=True,
                                 timeout=TIMEOUT, env=master.env())
        assert spawned.returncode == 0, spawned.stdout + spawned.stderr + self.tail("sim")
        for uav_id in ids:
            self.processes.append(master.spawn(
                ["rosrun", "magna_mavlink", "ual_mavlink", "--id", str(uav_id), "--url",
                 f"udpin:127.0.0.1:{self.remote_port[uav_id]}", "--origin-geo", *map(str, ORIGIN)],
                stdout=self._log(f"ual_mavlink_{uav_id}"), stderr=subprocess.STDOUT))
        ros = rosgraph.Master("/magna_test", master_uri=master.uri)
        wait_until(lambda: ros.hasParam("/ual_ids") and sorted(ros.getParam("/ual_ids")) == list(ids),
                   f"the bridges' ids in /ual_ids\n{self.tail()}", timeout=90)

    def _log(self, name):
        return open(self.logs / f"{name}.log", "w")  # noqa: SIM115 - the process writes it until it ends

    def tail(self, *names) -> str:
        names = names or tuple(path.stem for path in sorted(self.logs.glob("*.log")))
        return "".join(f"\n--- {name}.log\n" + (self.logs / f"{name}.log").read_text()[-3000:] for name in names)

    def check_alive(self):
        dead = [p.args for p in self.processes if p.poll() is not None]
        assert not dead, f"ended during the test: {dead}{self.tail()}"

    def stop(self):
        from magna_common.processes import end_process_group

        for process in reversed(self.processes):
            end_process_group(process)


@pytest.fixture
def stand_ins(fresh_ros_master, tmp_path):
    started = []

    def start(*ids):
        started.append(StandIns(fresh_ros_master, ids, tmp_path / "logs"))
        return started[-1]

    yield start
    for one in started:
        one.stop()


def test_magna_sims_ual_behaviour_cases_pass_against_ual_mavlink(stand_ins):
    uavs = stand_ins(1, 2)
    run = subprocess.run([sys.executable, str(HERE / "ual_behaviour_runner.py"), "1", "2"], capture_output=True,
                         text=True, timeout=TIMEOUT, env=uavs.master.env())
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-6000:] + uavs.tail()
    report = run.stdout + run.stderr
    for case in ("test_1_landed_side_by_side_with_ids_and_battery", "test_2_refusals",
                 "test_3_take_off_blocking_and_not", "test_4_set_pose_set_velocity_and_bad_setpoints",
                 "test_6_geographic_waypoint_home_frame_and_manual_recovery",
                 "test_7_go_to_and_land_where_they_started"):
        assert any(line.startswith(case) and line.endswith("... ok") for line in report.splitlines()), case
    uavs.check_alive()


def fly(master, *args):
    out = subprocess.run(["rosrun", "magna_sim", "fly", "--id", "1", *args], capture_output=True, text=True,
                         timeout=TIMEOUT, env=master.env())
    return out.returncode, out.stdout + out.stderr


def printed_position(text):
    return tuple(float(v) for v in text.split("(")[1].split(")")[0].split(","))


class VehicleSide:
    """The vehicle's own telemetry, heard as a ground station hears it: by writing to the port it binds."""

    def __init__(self, port):
        self.latest = {}
        self._lock = threading.Lock()
        self.link = MavlinkLink(f"udpout:127.0.0.1:{port}", 1, on_message=self._store, source_system=255,
                                source_component=190).open()
        self.link.wait_for_vehicle(30.0)
        wait_until(lambda: "LOCAL_POSITION_NED" in self.latest and "ATTITUDE" in self.latest,
                   "the vehicle's telemetry", timeout=30)

    def _store(self, msg):
        with self._lock:
            self.latest[msg.get_type()] = msg

    def ned(self):
        with self._lock:
            msg = self.latest["LOCAL_POSITION_NED"]
        return msg.x, msg.y, msg.z

    def speed(self):
        with self._lock:
            msg = self.latest["LOCAL_POSITION_NED"]
        return math.sqrt(msg.vx ** 2 + msg.vy ** 2 + msg.vz ** 2)

    def yaw(self):
        with self._lock:
            return self.latest["ATTITUDE"].yaw


def test_enu_east_is_the_vehicles_east_and_the_fly_tool_flies_it(stand_ins):
    uavs = stand_ins(1)
    master = uavs.master
    vehicle = VehicleSide(uavs.local_port[1])
    try:
        code, text = fly(master, "take_off", "2")
        assert code == 0 and "uav 1: FLYING_AUTO" in text, text + uavs.tail()
        assert math.dist(printed_position(text), (0.0, -1.0, 2.0)) <= 0.165
        code, text = fly(master, "go_to", "3", "1", "2.5", "--yaw", "90")  # facing north
        assert code == 0 and "FLYING_AUTO" in text, text
        assert math.dist(printed_position(text), (3.0, 1.0, 2.5)) <= 0.165
        assert abs(vehicle.yaw()) < 0.1  # ENU 90 degrees is NED 0 (north), on the vehicle's side
        before_enu, before_ned = printed_position(text), vehicle.ned()
        code, text = fly(master, "velocity", "0.5", "0", "0", "--duration", "2")  # ENU +x: east
        assert code == 0, text
        wait_until(lambda: vehicle.speed() < 0.05, "the vehicle to hold after the velocity timeout", timeout=60)
        code, text = fly(master, "state")
        after_enu, after_ned = printed_position(text), vehicle.ned()
        assert after_enu[0] - before_enu[0] == pytest.approx(1.0, abs=0.4)  # the UAL pose went east (+x) ...
        assert abs(after_enu[1] - before_enu[1]) < 0.1
        assert after_ned[1] - before_ned[1] == pytest.approx(after_enu[0] - before_enu[0], abs=0.05)  # ... the
        assert abs(after_ned[0] - before_ned[0]) < 0.1 and abs(after_ned[2] - before_ned[2]) < 0.1  # vehicle: NED +y
        code, text = fly(master, "land")
        assert code == 0 and ("uav 1: LANDED_ARMED" in text or "uav 1: LANDED_DISARMED" in text), text
        assert printed_position(text)[2] < 0.06
    finally:
        vehicle.link.close()
    uavs.check_alive()
