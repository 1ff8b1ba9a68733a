"""The MAVLink link against a scripted autopilot over real UDP: URLs, connecting both ways, our HEARTBEAT,
the vehicle that is not there, other systems ignored, and commands acknowledged, refused or unanswered."""
import time

import pytest
from fake_autopilot import FakeAutopilot

from magna_common.ports import free_port
from magna_mavlink.link import (
    MAV_COMP_ID_ONBOARD_COMPUTER,
    CommandFailed,
    Endpoint,
    LinkError,
    MavlinkLink,
    mavlink,
    parse_url,
)
from tests.support import wait_until


@pytest.mark.parametrize(("url", "endpoint"), [
    ("udpin:0.0.0.0:14540", Endpoint("udpin:0.0.0.0:14540")),
    ("udpout:127.0.0.1:14580", Endpoint("udpout:127.0.0.1:14580")),
    ("tcp:127.0.0.1:5760", Endpoint("tcp:127.0.0.1:5760")),
    ("/dev/ttyACM0,57600", Endpoint("/dev/ttyACM0", 57600)),
    ("/dev/ttyUSB1", Endpoint("/dev/ttyUSB1", 57600)),  # a telemetry radio's usual rate
])
def test_urls_as_pymavlink_writes_them(url, endpoint):
    assert parse_url(url) == endpoint


@pytest.mark.parametrize(("url", "words"), [
    ("udp://:14540", "without '//' (e.g. udpin:0.0.0.0:14540"),
    ("udpin:14540", "expected SCHEME:HOST:PORT"),
    ("udpin::14540", "no host; e.g. udpin:0.0.0.0:14540"),
    ("udpout:127.0.0.1:70000", "port 70000 is not in 1..65535"),
    ("ttyACM0", "not a connection URL; accepted: udpin:HOST:PORT"),
])
def test_bad_urls_name_themselves_and_the_accepted_forms(url, words):
    with pytest.raises(LinkError, match="^" + url.replace("/", "\\/") + ": ") as caught:
        parse_url(url)
    assert words in str(caught.value)


def test_a_serial_device_that_is_not_there_is_named():
    with pytest.raises(LinkError, match="/dev/ttyNOPE9,57600: no such serial device /dev/ttyNOPE9"):
        MavlinkLink("/dev/ttyNOPE9,57600", 1).open()


def test_listening_we_hear_the_vehicle_and_it_hears_our_heartbeat_as_an_onboard_controller():
    port = free_port(udp=True)
    fake = FakeAutopilot(f"udpout:127.0.0.1:{port}", system_id=4).start()
    try:
        with MavlinkLink(f"udpin:127.0.0.1:{port}", 4) as link:
            heartbeat = link.wait_for_vehicle(10.0)
            assert heartbeat.autopilot == mavlink.MAV_AUTOPILOT_PX4
            wait_until(lambda: (4, MAV_COMP_ID_ONBOARD_COMPUTER) in fake.senders, "our HEARTBEAT at the vehicle")
    finally:
        fake.stop()


def test_sending_first_the_vehicle_learns_where_to_answer():
    port = free_port(udp=True)
    fake = FakeAutopilot(f"udpin:127.0.0.1:{port}", system_id=2).start()  # answers whoever writes to it
    try:
        with MavlinkLink(f"udpout:127.0.0.1:{port}", 2) as link:
            assert link.wait_for_vehicle(10.0).get_srcSystem() == 2
    finally:
        fake.stop()


def test_no_vehicle_is_an_error_naming_the_url():
    url = f"udpin:127.0.0.1:{free_port(udp=True)}"
    with MavlinkLink(url, 1) as link, pytest.raises(LinkError) as caught:
        link.wait_for_vehicle(0.3)
    assert str(caught.value).startswith(f"no heartbeat from system 1 at {url} within 0.3 s: is the vehicle on")


def test_another_system_on_the_link_is_not_our_vehicle():
    port = free_port(udp=True)
    fake = FakeAutopilot(f"udpout:127.0.0.1:{port}", system_id=7).start()
    heard = []
    try:
        with MavlinkLink(f"udpin:127.0.0.1:{port}", 1, on_message=heard.append) as link:
            wait_until(lambda: fake.senders, "the other system to hear us")
            time.sleep(0.3)  # it sends at 50 Hz: plenty would have come by now
            with pytest.raises(LinkError):
                link.wait_for_vehicle(0.1)
        assert heard == []
    finally:
        fake.stop()


def test_commands_are_acknowledged_refused_or_retried_until_given_up():
    port = free_port(udp=True)
    fake = FakeAutopilot(f"udpout:127.0.0.1:{port}", system_id=1).start()
    try:
        with MavlinkLink(f"udpin:127.0.0.1:{port}", 1) as link:
            link.wait_for_vehicle(10.0)
            link.command_accepted(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, name="arm")
            assert fake.armed
            assert link.command(mavlink.MAV_CMD_DO_SET_SERVO) == mavlink.MAV_RESULT_UNSUPPORTED
            with pytest.raises(CommandFailed, match="MAV_CMD_DO_SET_SERVO: system 1 answered UNSUPPORTED"):
                link.command_accepted(mavlink.MAV_CMD_DO_SET_SERVO)
            fake.answer_commands = False
            sent = len(fake.commands)
            with pytest.raises(CommandFailed, match=r"arm: no COMMAND_ACK from system 1 at udpin:.* after 5 tries"):
                link.command_accepted(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, name="arm", timeout=0.2)
            wait_until(lambda: len(fake.commands) == sent + 5, "five sends of the unanswered command")
            assert [c.confirmation for c in fake.commands[sent:]] == [0, 1, 2, 3, 4]  # as the command protocol says
    finally:
        fake.stop()
