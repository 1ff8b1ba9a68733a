"""The MAVLink link check against a scripted vehicle in this process (a UDP socket speaking MAVLink 2 through
pymavlink's encoder): the good lines for PX4 and ArduPilot, each failure with its fix, and the URL forms.

ScriptedVehicle is also used by magna_master's test of `magna doctor --mavlink`.
"""
from __future__ import annotations

import select
import socket
import threading
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink

from magna_common.ports import free_port
from magna_mavlink import link_check
from magna_mavlink.autopilot import encode_mode
from magna_mavlink.link_check import BadUrl, LinkUrl, check_link, parse_url
from magna_mavlink.udp_proxy import UdpProxy

WAIT = 10.0  # s: the check returns as soon as it has everything; this only bounds a broken run
SHORT = 3.0  # s: for checks that must wait out their timeout (something never comes)


class ScriptedVehicle:
    """A MAVLink vehicle on a UDP socket: it answers whoever sends to it (PX4's port 14580+i does that) and,
    with send_to, also sends to a fixed port (PX4's 14540+i). Sends HEARTBEAT, SYS_STATUS and, when it has
    a position, LOCAL_POSITION_NED and GLOBAL_POSITION_INT at `rate`; answers MAV_CMD_REQUEST_MESSAGE for
    HOME_POSITION with the home (if it has one) and a COMMAND_ACK with `request_result`."""

    def __init__(self, *, send_to: int | None = None, autopilot: int = mavlink.MAV_AUTOPILOT_PX4, system: int = 1,
                 mode: str = "POSCTL", armed: bool = False, position: bool = True, home: bool = True,
                 request_result: int = mavlink.MAV_RESULT_ACCEPTED, rate: float = 20.0,
                 vehicle_type: int = mavlink.MAV_TYPE_QUADROTOR):
        self.autopilot, self.system, self.vehicle_type = autopilot, system, vehicle_type
        name = "px4" if autopilot == mavlink.MAV_AUTOPILOT_PX4 else "ardupilot"
        try:
            base, self.custom_mode = encode_mode(name, mode)
        except ValueError:
            base, self.custom_mode = 1, 0
        self.base_mode = base | (mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
        self.position, self.has_home, self.request_result = position, home, request_result
        self.period = 1.0 / rate
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=mavlink.MAV_COMP_ID_AUTOPILOT1)
        self.parser = mavlink.MAVLink(None)
        self.peers = {("127.0.0.1", send_to)} if send_to else set()
        self.received: list = []  # every message the client sent
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> ScriptedVehicle:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        self.sock.close()

    def _send(self, msg) -> None:
        data = msg.pack(self.mav)
        for peer in list(self.peers):
            self.sock.sendto(data, peer)

    def _tick(self) -> None:
        self._send(self.mav.heartbeat_encode(self.vehicle_type, self.autopilot, self.base_mode, self.custom_mode,
                                             mavlink.MAV_STATE_STANDBY))
        sensors = mavlink.MAV_SYS_STATUS_SENSOR_GPS | mavlink.MAV_SYS_STATUS_AHRS
        health = sensors if self.position else 0
        self._send(self.mav.sys_status_encode(sensors, sensors, health, 0, 12000, -1, -1, 0, 0, 0, 0, 0, 0))
        if self.position:
            self._send(self.mav.local_position_ned_encode(0, 1.0, 2.0, -0.1, 0, 0, 0))
            self._send(self.mav.global_position_int_encode(0, 473977420, 85455940, 488000, 0, 0, 0, 0, 0))

    def _answer(self, msg) -> None:
        self.received.append(msg)
        if msg.get_type() != "COMMAND_LONG" or msg.command != mavlink.MAV_CMD_REQUEST_MESSAGE:
            return
        if int(msg.param1) == mavlink.MAVLINK_MSG_ID_HOME_POSITION and self.has_home:
            self._send(self.mav.home_position_encode(473977420, 85455940, 488000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0))
        self._send(self.mav.command_ack_encode(msg.command, self.request_result))

    def _run(self) -> None:
        next_tick = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_tick:
                self._tick()
                next_tick = now + self.period
            ready, _, _ = select.select([self.sock], [], [], max(0.0, next_tick - now))
            if ready:
                data, sender = self.sock.recvfrom(65535)
                self.peers.add(sender)
                for msg in self.parser.parse_buffer(data) or []:
                    self._answer(msg)


def lines(checks) -> dict[str, link_check.LinkCheck]:
    return {c.name: c for c in checks}


def test_a_px4_vehicle_reached_with_udpout_passes_every_line():
    with ScriptedVehicle(mode="POSCTL") as vehicle:
        checks = check_link(f"udpout:127.0.0.1:{vehicle.port}", timeout=WAIT)
    assert [c.name for c in checks] == list(link_check.CHECKS)
    assert all(c.ok for c in checks), checks
    got = lines(checks)
    assert got["heartbeat"].detail.startswith(f"from udpout:127.0.0.1:{vehicle.port} after ")
    assert got["autopilot"].detail.startswith("PX4 (HEARTBEAT.autopilot 12), vehicle type QUADROTOR")
    assert got["system id"].detail == "1, component 1"
    assert got["flight mode"].detail == "POSCTL" and got["armed"].detail == "disarmed"
    assert "LOCAL_POSITION_NED (1.00, 2.00, -0.10) m" in got["position valid"].detail
    assert got["home"].detail == "47.3977420, 8.5455940, 488.0 m"
    assert any(m.get_type() == "HEARTBEAT" and m.type == mavlink.MAV_TYPE_GCS for m in vehicle.received), \
        "the check introduces itself with a ground station's HEARTBEAT"


def test_an_ardupilot_vehicle_sending_to_a_udpin_port_passes():
    port = free_port(udp=True)
    with ScriptedVehicle(send_to=port, autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, system=3, mode="GUIDED",
                         armed=True):
        checks = check_link(f"udpin:127.0.0.1:{port}", timeout=WAIT)
    got = lines(checks)
    assert all(c.ok for c in checks), checks
    assert got["autopilot"].detail.startswith("ArduPilot (HEARTBEAT.autopilot 3)")
    assert got["system id"].detail.startswith("3, component 1")
    assert got["flight mode"].detail == "GUIDED (the UAL's set-point mode)" and got["armed"].detail == "armed"


def test_the_check_passes_through_a_lossy_slow_link_and_fails_while_it_is_cut():
    with ScriptedVehicle() as vehicle, \
            UdpProxy(("127.0.0.1", 0), ("127.0.0.1", vehicle.port), loss=0.2, delay=0.05, seed=1) as proxy:
        url = f"udpout:127.0.0.1:{proxy.listen_address[1]}"
        checks = check_link(url, timeout=WAIT)
        assert all(c.ok for c in checks), checks  # 20 % lost each way, 50 ms each way: asked again until answered
        proxy.cut()
        (line,) = check_link(url, timeout=1.0)
        assert not line.ok and line.detail == f"no HEARTBEAT from a vehicle at {url} within 1 s"
        assert proxy.stats().to_vehicle.cut > 0


def test_no_vehicle_at_the_url_gives_one_line_with_the_url_and_the_fix():
    port = free_port(udp=True)
    checks = check_link(f"udpout:127.0.0.1:{port}", timeout=0.5)
    assert len(checks) == 1
    (line,) = checks
    assert not line.ok and line.name == "heartbeat"
    assert line.detail == f"no HEARTBEAT from a vehicle at udpout:127.0.0.1:{port} within 0.5 s"
    assert "listening at 127.0.0.1:" in line.fix and "14580+i" in line.fix
    checks = check_link(f"udpin:127.0.0.1:{port}", timeout=0.2)
    assert checks[0].detail.endswith("within 0.2 s") and "sending MAVLink to this machine's port" in checks[0].fix


def test_a_vehicle_without_position_or_home_fails_those_lines_with_fixes():
    with ScriptedVehicle(position=False, home=False, request_result=mavlink.MAV_RESULT_DENIED) as vehicle:
        checks = check_link(f"udpout:127.0.0.1:{vehicle.port}", timeout=SHORT)
    got = lines(checks)
    assert got["heartbeat"].ok and got["autopilot"].ok
    position, home = got["position valid"], got["home"]
    assert not position.ok and "SYS_STATUS: GPS and AHRS unhealthy" in position.detail
    assert "GPS fix" in position.fix
    assert not home.ok and "answered a MAV_CMD_REQUEST_MESSAGE with DENIED" in home.detail
    assert "set_home" in home.fix


def test_an_autopilot_the_ual_cannot_fly_is_named():
    with ScriptedVehicle(autopilot=mavlink.MAV_AUTOPILOT_GENERIC) as vehicle:
        checks = check_link(f"udpout:127.0.0.1:{vehicle.port}", timeout=WAIT)
    got = lines(checks)
    assert got["heartbeat"].ok
    assert not got["autopilot"].ok and "HEARTBEAT.autopilot 0 is neither PX4 (12) nor ArduPilot (3)" in \
        got["autopilot"].detail
    assert not any(c.ok for c in checks[2:])


def test_a_ground_station_alone_is_not_a_vehicle():
    with ScriptedVehicle(autopilot=mavlink.MAV_AUTOPILOT_INVALID, system=250, vehicle_type=mavlink.MAV_TYPE_GCS,
                         ) as other_gcs:
        (line,) = check_link(f"udpout:127.0.0.1:{other_gcs.port}", timeout=1.0)
    assert not line.ok and "heard only HEARTBEATs of ground stations or companions (system/component 250/1)" in \
        line.detail


def test_a_port_held_by_another_program_is_a_connection_failure():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]
        (line,) = check_link(f"udpin:127.0.0.1:{port}", timeout=0.5)
    assert line.name == "connection" and not line.ok
    assert line.detail.startswith(f"cannot open udpin:127.0.0.1:{port}: ") and "another program" in line.fix


def test_a_missing_serial_device_and_a_refused_tcp_are_connection_failures(tmp_path):
    (line,) = check_link(f"{tmp_path}/ttyACM9,57600", timeout=0.5)
    assert not line.ok and f"no such device {tmp_path}/ttyACM9" in line.detail and "dialout" in line.fix
    port = free_port()
    (line,) = check_link(f"tcp:127.0.0.1:{port}", timeout=0.5)
    assert not line.ok and line.detail.startswith(f"cannot open tcp:127.0.0.1:{port}: ")
    assert "listening for TCP" in line.fix


@pytest.mark.parametrize(("text", "expected"), [
    ("udpin:0.0.0.0:14540", LinkUrl("udpin:0.0.0.0:14540", "udpin", "0.0.0.0", 14540)),
    ("udpout:127.0.0.1:14580", LinkUrl("udpout:127.0.0.1:14580", "udpout", "127.0.0.1", 14580)),
    ("udp:0.0.0.0:14550", LinkUrl("udp:0.0.0.0:14550", "udpin", "0.0.0.0", 14550)),
    ("tcp:localhost:5760", LinkUrl("tcp:localhost:5760", "tcp", "localhost", 5760)),
    ("tcpin:0.0.0.0:5760", LinkUrl("tcpin:0.0.0.0:5760", "tcpin", "0.0.0.0", 5760)),
    ("/dev/ttyACM0,57600", LinkUrl("/dev/ttyACM0,57600", "serial", device="/dev/ttyACM0", baud=57600)),
    ("/dev/ttyUSB0", LinkUrl("/dev/ttyUSB0", "serial", device="/dev/ttyUSB0", baud=57600)),
])
def test_urls_as_pymavlink_writes_them(text, expected):
    assert parse_url(text) == expected


@pytest.mark.parametrize(("text", "words"), [
    ("udpin:14540", "expected SCHEME:HOST:PORT"),
    ("udpout:127.0.0.1:mav", "expected SCHEME:HOST:PORT"),
    ("udpin::14540", "no host"),
    ("udpin:0.0.0.0:70000", "not in 1..65535"),
    ("udp://:14540", "without '//'"),
    ("/dev/ttyACM0,fast", "not a connection URL"),
])
def test_bad_urls_are_refused_as_ual_mavlink_refuses_them(text, words):
    with pytest.raises(BadUrl) as refused:
        parse_url(text)
    assert str(refused.value).startswith(f"{text}: ") and words in str(refused.value)
