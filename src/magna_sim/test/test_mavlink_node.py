"""The sim node's MAVLink vehicles, live: pymavlink over UDP on free ports, and the spawn service's interfaces."""
import json
import re
import socket
import subprocess
import time

import pytest
import rosgraph
from pymavlink.dialects.v20 import common as mavlink

from magna_common.geo import enu_to_geodetic
from magna_common.ports import free_port
from magna_mavlink import autopilot
from tests.support import wait_until

WAIT = 60.0  # wall s: a guard against hangs, never a performance expectation
ORIGIN = (37.4107, -6.0028, 12.0)  # a stand-in's map origin on the Earth, as the ground station gives it
NAN = float("nan")


def port_is_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind(("0.0.0.0", port))
        except OSError:
            return False
    return True


class Client:
    """pymavlink over a UDP socket, as system 255: `udpin` on a port (listen where the vehicle sends) or, with
    `to`, `udpout` towards the vehicle's own port."""

    def __init__(self, port: int = 0, to: int | None = None, system: int = 1):
        self.system = system  # the vehicle's
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", port))
        self.socket.settimeout(0.1)
        self.vehicle = None if to is None else ("127.0.0.1", to)
        self.packer = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.latest: dict[str, object] = {}

    def close(self):
        self.socket.close()

    def send(self, message):
        assert self.vehicle is not None, "nothing heard from the vehicle yet"
        self.socket.sendto(message.pack(self.packer), self.vehicle)

    def poll(self) -> list:
        try:
            data, address = self.socket.recvfrom(65535)
        except TimeoutError:
            return []
        self.vehicle = self.vehicle or address  # udpin: answer whoever sends
        messages = [m for m in self.parser.parse_buffer(data) or () if m.get_type() != "BAD_DATA"
                    and m.get_srcSystem() == self.system]
        for message in messages:
            self.latest[message.get_type()] = message
        return messages

    def wait_for(self, condition, what, timeout=WAIT, each=None):
        """Read until condition(message) holds for a message; `each()` runs between reads (a set-point stream)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if each is not None:
                each()
            for message in self.poll():
                if condition(message):
                    return message
        raise AssertionError(f"timed out waiting for {what}; last heard: "
                             f"{ {k: str(v) for k, v in self.latest.items() if k in ('HEARTBEAT', 'COMMAND_ACK')} }")

    def drain(self) -> None:
        """Read what queued up while the test did something else (a full socket buffer drops new datagrams)."""
        self.socket.settimeout(0.0)
        try:
            while True:
                try:
                    self.poll()
                except BlockingIOError:
                    return
        finally:
            self.socket.settimeout(0.1)

    def command(self, command, *params):
        """COMMAND_LONG, sent again each wall second without an answer (as MAVSDK does); the COMMAND_ACK's result."""
        params = list(params) + [NAN] * (7 - len(params))
        self.drain()
        for _ in range(int(WAIT)):
            self.send(mavlink.MAVLink_command_long_message(self.system, 1, command, 0, *params))
            try:
                return self.wait_for(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command,
                                     f"COMMAND_ACK of {command}", timeout=1.0).result
            except AssertionError:
                continue
        raise AssertionError(f"no COMMAND_ACK of {command} within {WAIT} s")

    def mode(self) -> tuple[str, bool]:
        heartbeat = self.latest["HEARTBEAT"]
        decoded = autopilot.decode_mode(heartbeat.autopilot, heartbeat.base_mode, heartbeat.custom_mode)
        return decoded.name, decoded.armed


def start_sim(master, *params):
    master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    node = master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=1", "_real_time_factor:=5", *params],
                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ros = rosgraph.Master("/test", master_uri=master.uri)
    wait_until(lambda: ros.hasParam("/ual_ids") and ros.getParam("/ual_ids") == [1], "magna_sim's UAV 1", timeout=60)
    return node, ros


def ual_state(master):
    """`fly --id 1 state`: the UAL's view (ENU map frame) of UAV 1, as (state, (x, y, z))."""
    out = subprocess.run(["rosrun", "magna_sim", "fly", "--id", "1", "state"], capture_output=True, text=True,
                         timeout=120, env=master.env())
    match = re.search(r"uav 1: (\w+) at \(([-\d.]+), ([-\d.]+), ([-\d.]+)\)", out.stdout)
    assert match, out.stdout + out.stderr
    return match.group(1), tuple(float(v) for v in match.group(2, 3, 4))


def test_pymavlink_flies_a_ual_plus_mavlink_uav_and_the_ual_sees_it_in_enu(fresh_ros_master):
    local, remote = free_port(udp=True), free_port(udp=True)
    offboard_api = Client(remote)  # where PX4 SITL's offboard API listens
    node, _ = start_sim(fresh_ros_master, "_mavlink:=true", f"_mavlink_local_port_base:={local}",
                        f"_mavlink_remote_port_base:={remote}")
    try:
        client = offboard_api
        heartbeat = client.wait_for(lambda m: m.get_type() == "HEARTBEAT", "a HEARTBEAT from system 1")
        assert (heartbeat.autopilot, heartbeat.type, heartbeat.get_srcComponent()) == (12, 2, 1)
        # A loose offboard-loss timeout: this test's set-points come on wall time at 5x simulated speed.
        client.send(mavlink.MAVLink_param_set_message(1, 1, b"COM_OF_LOSS_T", 10.0, mavlink.MAV_PARAM_TYPE_REAL32))
        client.wait_for(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == "COM_OF_LOSS_T"
                        and m.param_value == 10.0, "COM_OF_LOSS_T = 10")
        assert client.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
        assert client.command(mavlink.MAV_CMD_NAV_TAKEOFF) == mavlink.MAV_RESULT_ACCEPTED
        client.wait_for(lambda m: m.get_type() == "HEARTBEAT" and client.mode() == ("AUTO.LOITER", True)
                        and client.latest["LOCAL_POSITION_NED"].z < -2.3, "take-off to 2.5 m, then AUTO.LOITER")
        state, before = ual_state(fresh_ros_master)
        assert state == "FLYING_MANUAL"  # flown through MAVLink: for the UAL, a pilot's take-over

        # 1 m/s east (NED y) in OFFBOARD: the map's x (ENU east) grows, its y stays.
        east = mavlink.MAVLink_set_position_target_local_ned_message(0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED,
                                                                     0b110111000111, 0, 0, 0, 0, 1.0, 0, 0, 0, 0,
                                                                     0, 0)
        last = [0.0]

        def stream():
            if time.monotonic() - last[0] >= 0.05:
                client.send(east)
                last[0] = time.monotonic()

        stream()
        assert client.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 6, 0) == mavlink.MAV_RESULT_ACCEPTED  # OFFBOARD
        start_y = client.latest["LOCAL_POSITION_NED"].y
        client.wait_for(lambda m: m.get_type() == "LOCAL_POSITION_NED" and m.y > start_y + 3.0,
                        "3 m east under OFFBOARD", each=stream)
        assert client.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4, 3) == mavlink.MAV_RESULT_ACCEPTED  # AUTO.LOITER
        _, after = ual_state(fresh_ros_master)
        assert after[0] - before[0] > 2.5 and abs(after[1] - before[1]) < 0.3 and abs(after[2] - before[2]) < 0.3

        # A ground station on the vehicle's own port (udpout) is answered too.
        ground_station = Client(to=local)
        ground_station.send(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
        ground_station.wait_for(lambda m: m.get_type() == "HEARTBEAT", "a HEARTBEAT on the ground station's link")
        ground_station.close()

        # Land; the vehicle disarms by itself, and the UAL has its UAV back on the ground.
        assert client.command(mavlink.MAV_CMD_NAV_LAND) == mavlink.MAV_RESULT_ACCEPTED
        client.wait_for(lambda m: m.get_type() == "HEARTBEAT" and not client.mode()[1], "auto-disarm after landing")
        assert ual_state(fresh_ros_master)[0] == "LANDED_ARMED"
        assert node.poll() is None
    finally:
        offboard_api.close()


SPAWN = """
import json, rospy
from magna_msgs.srv import SpawnModel, SpawnModelRequest, DeleteModel
rospy.init_node('mavlink_spawn_probe')
rospy.wait_for_service('/magna/sim/spawn_model', timeout=30)
spawn = rospy.ServiceProxy('/magna/sim/spawn_model', SpawnModel)
results = {}
for name, uav_id, interface, local, remote, *origin in json.loads(ARGS):
    request = SpawnModelRequest(name=name, kind='uav', uav_id=uav_id, interface=interface, mavlink_local_port=local,
                                mavlink_remote_port=remote, mavlink_origin_geo=origin[0] if origin else [])
    request.pose.position.x, request.pose.orientation.w = 3.0 * uav_id, 1.0
    answer = spawn(request)
    results[name] = [answer.success, answer.message]
for name in json.loads(DELETE):
    results['delete ' + name] = rospy.ServiceProxy('/magna/sim/delete_model', DeleteModel)(name).success
print(json.dumps(results))
"""


def call(master, spawns=(), delete=()):
    """Spawn UAVs (name, uav_id, interface, local port, remote port[, origin_geo]) and delete models through the
    services."""
    script = SPAWN.replace("ARGS", repr(json.dumps(list(spawns)))).replace("DELETE", repr(json.dumps(list(delete))))
    out = subprocess.run(["python3", "-c", script], capture_output=True, text=True, timeout=120, env=master.env())
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_mavlink_only_stand_in_has_no_ual_and_deleting_it_frees_its_port(fresh_ros_master):
    """All while the simulation is paused (as the ground station spawns): spawning, answers and heartbeats go on."""
    node, ros = start_sim(fresh_ros_master, "_start_paused:=true")  # UAV 1: UAL only
    local, remote, other = free_port(udp=True), free_port(udp=True), free_port(udp=True)
    offboard_api = Client(remote, system=2)
    try:
        results = call(fresh_ros_master, spawns=[
            ("uav_2", 2, "mavlink", local, remote, list(ORIGIN)),
            ("uav_3", 3, "px4", 0, 0),
            ("uav_6", 6, "mavlink", free_port(udp=True), other, [137.0, 8.0, 0.0]),
            ("uav_4", 4, "mavlink", local, other),  # the port uav_2 holds
            ("uav_5", 5, "ual+mavlink", free_port(udp=True), other)])
        assert results["uav_2"] == [True, f"spawned UAV 'uav_2' as MAVLink system 2 on UDP {local} "
                                          f"(sending to 127.0.0.1:{remote})"]
        assert results["uav_3"][0] is False and results["uav_3"][1].startswith(
            "interface: 'px4' must be one of ual, mavlink, ual+mavlink")
        assert results["uav_4"][0] is False and results["uav_4"][1].startswith(
            f"mavlink_local_port: UDP 0.0.0.0:{local} cannot be bound")
        assert results["uav_6"][0] is False and results["uav_6"][1].startswith(
            "mavlink_origin_geo: [137.0, 8.0, 0.0] must be [lat, lon, alt]")
        assert results["uav_5"][0] is True and results["uav_5"][1].startswith(
            "spawned UAV 'uav_5' as /uav_5/ual and MAVLink system 5")
        assert sorted(ros.getParam("/ual_ids")) == [1, 5]  # the stand-in is nobody's UAL
        with pytest.raises(rosgraph.MasterError):
            ros.lookupService("/uav_2/ual/take_off")
        assert ros.lookupService("/uav_5/ual/take_off")

        heartbeat = offboard_api.wait_for(lambda m: m.get_type() == "HEARTBEAT", "a HEARTBEAT from the stand-in")
        assert heartbeat.get_srcComponent() == 1
        # Its GPS puts the map origin where the request said: uav_2 stands at map (6, 0, 0).
        assert offboard_api.command(mavlink.MAV_CMD_REQUEST_MESSAGE,
                                    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT) == mavlink.MAV_RESULT_ACCEPTED
        gps = offboard_api.latest.get("GLOBAL_POSITION_INT") or offboard_api.wait_for(
            lambda m: m.get_type() == "GLOBAL_POSITION_INT", "the stand-in's position")  # telemetry waits for time
        lat, lon, _ = enu_to_geodetic([6.0, 0.0, 0.0], ORIGIN)
        assert gps.lat == pytest.approx(lat * 1e7, abs=2) and gps.lon == pytest.approx(lon * 1e7, abs=2)
        assert offboard_api.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
        offboard_api.wait_for(lambda m: m.get_type() == "HEARTBEAT" and offboard_api.mode()[1], "armed, while paused")
        # The refused uav_4 left nothing behind: its name spawns now, on a free port.
        assert call(fresh_ros_master, spawns=[("uav_4", 4, "mavlink", free_port(udp=True), other)])["uav_4"][0]
        assert not port_is_free(local)
        assert call(fresh_ros_master, delete=["uav_2"])["delete uav_2"] is True
        wait_until(lambda: port_is_free(local), f"UDP {local} released by the deleted model")
        assert node.poll() is None
    finally:
        offboard_api.close()


@pytest.mark.parametrize("param, value", [("_mavlink_local_port_base", "70000"), ("_mavlink", "perhaps")])
def test_bad_mavlink_parameters_stop_the_node_with_a_named_field(fresh_ros_master, param, value):
    node = fresh_ros_master.spawn(["rosrun", "magna_sim", "sim", f"{param}:={value}"], stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True)
    output, _ = node.communicate(timeout=60)
    assert node.returncode == 2 and f"~{param[1:]}: " in output
