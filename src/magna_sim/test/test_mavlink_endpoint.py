"""The UDP link of a simulated MAVLink vehicle, over real localhost sockets on free ports."""
import socket

import pytest
from pymavlink.dialects.v20 import common as mavlink

from magna_common.ports import free_port
from magna_sim.mavlink_endpoint import EndpointError, MavlinkEndpoint
from tests.support import wait_until


def heartbeat():
    return mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 1, 0, 3, 3)


class Client:
    """A UDP socket speaking MAVLink as system 255 (a ground station)."""

    def __init__(self, port=0):
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", port))
        self.socket.settimeout(5.0)
        self.packer = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.parser = mavlink.MAVLink(None)

    def send(self, message, port):
        self.socket.sendto(message.pack(self.packer), ("127.0.0.1", port))

    def receive(self):
        data, _ = self.socket.recvfrom(65535)
        return self.parser.parse_buffer(data)


@pytest.fixture
def endpoint():
    link = MavlinkEndpoint(3, free_port(udp=True), free_port(udp=True))
    yield link
    link.close()


def test_it_sends_to_the_offboard_port_as_system_and_component_1(endpoint):
    offboard = Client(endpoint.remote[1])  # where MAVSDK would listen (udpin)
    endpoint.send([heartbeat(), heartbeat()])
    first, second = offboard.receive()[0], offboard.receive()[0]
    assert (first.get_srcSystem(), first.get_srcComponent()) == (3, 1)
    assert first.get_type() == "HEARTBEAT" and second.get_seq() == (first.get_seq() + 1) % 256
    assert first.get_msgbuf()[0] == 0xFD  # MAVLink 2


def test_it_answers_whoever_sends_to_its_port(endpoint):
    assert endpoint.receive() == []  # nothing waiting: returns at once
    ground_station = Client()  # udpout:127.0.0.1:<local port>
    ground_station.send(heartbeat(), endpoint.local_port)
    ground_station.socket.sendto(b"\x00garbage", ("127.0.0.1", endpoint.local_port))  # ignored, not fatal
    received = []
    wait_until(lambda: received.extend(endpoint.receive()) or received, "the ground station's heartbeat")
    assert [(m.get_type(), m.get_srcSystem()) for m in received] == [("HEARTBEAT", 255)]
    endpoint.send([heartbeat()])
    assert ground_station.receive()[0].get_srcSystem() == 3


def test_a_taken_port_is_refused_by_name_and_close_frees_it(endpoint):
    with pytest.raises(EndpointError, match=f"mavlink_local_port: UDP 0.0.0.0:{endpoint.local_port} cannot be bound"):
        MavlinkEndpoint(4, endpoint.local_port, free_port(udp=True))
    endpoint.close()
    assert endpoint.closed and endpoint.receive() == []
    again = MavlinkEndpoint(4, endpoint.local_port, free_port(udp=True))
    again.close()


def test_sending_where_nobody_listens_is_harmless(endpoint):
    for _ in range(3):
        endpoint.send([heartbeat()])  # ICMP port unreachable must not break later reads or sends
        assert endpoint.receive() == []
