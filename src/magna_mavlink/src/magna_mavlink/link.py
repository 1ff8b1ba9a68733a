"""The MAVLink connection to one autopilot: open a URL, hear it, send to it, and have commands acknowledged.

URLs are written as pymavlink writes them: `udpin:0.0.0.0:14540` (listen; PX4 SITL's offboard port),
`udpout:127.0.0.1:14580` (send first; the autopilot answers whoever writes to it), `tcp:host:5760`,
or a serial device `/dev/ttyACM0,57600`. We are an onboard controller: our own HEARTBEAT goes out at
1 Hz (MAV_TYPE_ONBOARD_CONTROLLER, component MAV_COMP_ID_ONBOARD_COMPUTER) from the moment the link
opens, so a `udpout:` peer learns where to answer. Only messages of the target system reach the
caller, and only HEARTBEATs of its autopilot component count as the vehicle being there (a camera
or gimbal of the same system sends HEARTBEATs too, with autopilot MAV_AUTOPILOT_INVALID).

Commands go out as COMMAND_LONG and wait for their COMMAND_ACK; a lost packet is resent with the
confirmation counter raised, as the MAVLink command protocol says. These are protocol waits, on
wall time: they do not depend on how fast a simulator runs.
"""
from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from .pymavlink_types import MavConnection, MavEncoder, MavMessage

os.environ.setdefault("MAVLINK20", "1")  # before pymavlink is imported: speak MAVLink 2, as PX4 does
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink

MAV_COMP_ID_AUTOPILOT1 = 1
MAV_COMP_ID_ONBOARD_COMPUTER = 191
HEARTBEAT_PERIOD = 1.0  # s between our own HEARTBEATs (MAVLink's heartbeat microservice asks for 1 Hz)
ACK_TIMEOUT = 1.0  # s for one COMMAND_ACK before the command is sent again
ATTEMPTS = 5  # sends of one command before it counts as unanswered (a radio losing 1 packet in 5: 1 in 150)
SERIAL_BAUD = 57600  # a telemetry radio's usual rate, when the URL gives none

RESULT_NAMES = {0: "ACCEPTED", 1: "TEMPORARILY_REJECTED", 2: "DENIED", 3: "UNSUPPORTED", 4: "FAILED",
                5: "IN_PROGRESS", 6: "CANCELLED"}
URL_FORMS = ("udpin:HOST:PORT (listen), udpout:HOST:PORT (send first), tcp:HOST:PORT, "
             "or a serial device /dev/ttyACM0,57600")


class LinkError(RuntimeError):
    """The URL cannot be opened, or no vehicle answers on it; the message names the URL and the fix."""


class CommandFailed(RuntimeError):
    """A command the autopilot refused or never acknowledged; the message says which and why."""


@dataclass(frozen=True)
class Endpoint:
    """What pymavlink opens for a URL."""

    device: str  # as pymavlink.mavutil.mavlink_connection takes it
    baud: int = 115200  # serial only


def parse_url(url: str) -> Endpoint:
    """Check a connection URL before anything is opened; errors name the URL and the accepted forms."""
    text = url.strip()
    if re.match(r"^[a-z]+://", text):
        raise LinkError(f"{url}: write the URL as pymavlink does, without '//' (e.g. udpin:0.0.0.0:14540 "
                        f"where MAVSDK says udp://:14540); accepted: {URL_FORMS}")
    network = re.fullmatch(r"(udpin|udpout|udp|tcp|tcpin):([^:]*):(\d+)", text)
    if network:
        scheme, host, port = network.groups()
        if not host:
            raise LinkError(f"{url}: no host; e.g. udpin:0.0.0.0:{port} or udpout:127.0.0.1:{port}")
        if not 0 < int(port) < 65536:
            raise LinkError(f"{url}: port {port} is not in 1..65535")
        return Endpoint(text)
    if text.startswith(("udpin:", "udpout:", "udp:", "tcp:", "tcpin:")):
        raise LinkError(f"{url}: expected SCHEME:HOST:PORT; accepted: {URL_FORMS}")
    serial = re.fullmatch(r"(/[^,]+|COM\d+)(?:,(\d+))?", text)
    if serial:
        return Endpoint(serial.group(1), int(serial.group(2) or SERIAL_BAUD))
    raise LinkError(f"{url}: not a connection URL; accepted: {URL_FORMS}")


def open_connection(url: str, source_system: int, source_component: int) -> MavConnection:
    """The pymavlink connection of a URL (a socket bound or a serial port opened), or LinkError naming it."""
    endpoint = parse_url(url)
    if endpoint.device.startswith("/") and not os.path.exists(endpoint.device):
        raise LinkError(f"{url}: no such serial device {endpoint.device} (is the autopilot plugged in? "
                        f"ls /dev/ttyACM* /dev/ttyUSB*)")
    try:
        return mavutil.mavlink_connection(endpoint.device, baud=endpoint.baud, source_system=source_system,
                                          source_component=source_component, autoreconnect=True)
    except (OSError, ValueError) as err:
        raise LinkError(f"{url}: cannot open: {err}") from None


class MavlinkLink:
    """One autopilot (`target_system`) behind one URL; messages are handed to `on_message` in the receive thread.

    `connect` opens the connection (a pymavlink mavfile); tests give one of their own.
    """

    def __init__(self, url: str, target_system: int, on_message: Callable[[MavMessage], None] | None = None,
                 source_system: int | None = None, source_component: int = MAV_COMP_ID_ONBOARD_COMPUTER,
                 connect: Callable[[str, int, int], MavConnection] = open_connection,
                 heartbeat_period: float = HEARTBEAT_PERIOD):
        self.url = url
        self.target_system = target_system
        # A companion computer is a component of the vehicle it flies: the same system id.
        self.source_system = target_system if source_system is None else source_system
        self.source_component = source_component
        self.on_message = on_message
        self.heartbeat_period = heartbeat_period
        self._connect = connect
        self._connection: MavConnection | None = None
        self._send_lock = threading.Lock()
        self._acks: dict[int, list[MavMessage]] = {}  # command -> acks received since it was sent
        self._ack_changed = threading.Condition()
        self._heard = threading.Event()  # the autopilot's first HEARTBEAT
        self.last_heartbeat: MavMessage | None = None  # the autopilot's latest HEARTBEAT message
        self.last_heartbeat_wall: float | None = None  # time.monotonic() when it came
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._boot = time.monotonic()

    # --- lifetime ----------------------------------------------------------------------------------------------
    def open(self) -> MavlinkLink:
        self._connection = self._connect(self.url, self.source_system, self.source_component)
        for name, target in (("receive", self._receive_loop), ("heartbeat", self._heartbeat_loop)):
            thread = threading.Thread(target=target, name=f"mavlink {name} {self.url}", daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def wait_for_vehicle(self, timeout: float) -> MavMessage:
        """The autopilot's first HEARTBEAT, or LinkError naming the URL after `timeout` s of wall time."""
        if not self._heard.wait(timeout):
            hint = ("is the vehicle on, and does it send to this port?" if self.url.startswith(("udpin", "udp:"))
                    else "is the vehicle on, and is this its address?")
            raise LinkError(f"no heartbeat from system {self.target_system} at {self.url} within {timeout:g} s: "
                            f"{hint} (magna doctor --mavlink {self.url} checks a link)")
        heartbeat = self.last_heartbeat
        assert heartbeat is not None  # the receive thread keeps it before it sets _heard
        return heartbeat

    def close(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._threads.clear()
        if self._connection is not None:
            try:
                self._connection.close()
            except OSError:
                pass
            self._connection = None

    def __enter__(self) -> MavlinkLink:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    # --- receiving ---------------------------------------------------------------------------------------------
    def _receive_loop(self) -> None:
        while not self._stop.is_set():
            connection = self._connection
            if connection is None:  # closed: close() sets _stop before it lets the connection go
                return
            try:
                msg = connection.recv_match(blocking=True, timeout=0.1)
            except (OSError, ValueError, AttributeError):  # the socket closed under us at shutdown
                if self._stop.is_set():
                    return
                time.sleep(0.05)
                continue
            if msg is None or msg.get_type() == "BAD_DATA" or msg.get_srcSystem() != self.target_system:
                continue
            if msg.get_srcComponent() == self.source_component and msg.get_srcSystem() == self.source_system:
                continue  # our own, echoed by a router or proxy: not a sign of the vehicle
            kind = msg.get_type()
            if kind == "HEARTBEAT" and msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
                continue  # another component of the vehicle (camera, gimbal, our own echo)
            if kind == "COMMAND_ACK":
                with self._ack_changed:
                    self._acks.setdefault(msg.command, []).append(msg)
                    self._ack_changed.notify_all()
            if self.on_message is not None:
                self.on_message(msg)
            if kind == "HEARTBEAT":  # after on_message: whoever waits for it finds it handled
                self.last_heartbeat, self.last_heartbeat_wall = msg, time.monotonic()
                self._heard.set()

    # --- sending -----------------------------------------------------------------------------------------------
    def time_boot_ms(self) -> int:
        return int((time.monotonic() - self._boot) * 1000) & 0xFFFFFFFF

    def send(self, build: Callable[[MavEncoder], None]) -> None:
        """Run `build(mav)` (e.g. lambda mav: mav.heartbeat_send(...)) with the link to ourselves."""
        connection = self._connection
        if connection is None:
            return
        with self._send_lock:  # pymavlink's sequence numbers and writes are not thread-safe
            try:
                build(connection.mav)
            except OSError:
                pass  # a UDP peer gone or a radio unplugged: the heartbeat watchdog says so

    def _heartbeat_loop(self) -> None:
        while not self._stop.is_set():
            self.send(lambda mav: mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                                                     mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))
            self._stop.wait(self.heartbeat_period)

    def command(self, command: int, *params: float, target_component: int = MAV_COMP_ID_AUTOPILOT1,
                timeout: float = ACK_TIMEOUT, attempts: int = ATTEMPTS, name: str | None = None) -> int:
        """Send COMMAND_LONG until acknowledged; return the ACK's result (0 is MAV_RESULT_ACCEPTED).

        IN_PROGRESS answers extend the wait. Raises CommandFailed when no ACK comes after `attempts` sends.
        """
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        label = name or _command_name(command)
        with self._ack_changed:
            self._acks[command] = []
        for confirmation in range(attempts):
            self._send_command_long(target_component, command, confirmation, values)
            deadline = time.monotonic() + timeout
            with self._ack_changed:
                while True:
                    acks = self._acks[command]
                    final = next((ack for ack in acks if ack.result != mavlink.MAV_RESULT_IN_PROGRESS), None)
                    if final is not None:
                        return final.result
                    if acks:  # in progress: the autopilot works on it
                        deadline = max(deadline, time.monotonic() + timeout)
                        acks.clear()
                    left = deadline - time.monotonic()
                    if left <= 0 or self._stop.is_set():
                        break
                    self._ack_changed.wait(left)
        raise CommandFailed(f"{label}: no COMMAND_ACK from system {self.target_system} at {self.url} after "
                            f"{attempts} tries of {timeout:g} s")

    def _send_command_long(self, target_component: int, command: int, confirmation: int,
                           values: list[float]) -> None:
        self.send(lambda mav: mav.command_long_send(self.target_system, target_component, command, confirmation,
                                                    *values))

    def command_accepted(self, command: int, *params: float, name: str | None = None, **kwargs) -> None:
        """Like command(), but anything other than ACCEPTED raises CommandFailed with the result's name."""
        result = self.command(command, *params, name=name, **kwargs)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            label = name or _command_name(command)
            raise CommandFailed(f"{label}: system {self.target_system} answered "
                                f"{RESULT_NAMES.get(result, str(result))}")

    def set_message_interval(self, message_id: int, rate_hz: float) -> int:
        """Ask for a message at `rate_hz` (MAV_CMD_SET_MESSAGE_INTERVAL); returns the ACK's result."""
        return self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, message_id, 1e6 / rate_hz)

    def request_message(self, message_id: int) -> int:
        """Ask for one message now (MAV_CMD_REQUEST_MESSAGE), e.g. HOME_POSITION or AUTOPILOT_VERSION."""
        return self.command(mavlink.MAV_CMD_REQUEST_MESSAGE, message_id)


def _command_name(command: int) -> str:
    entry = mavlink.enums["MAV_CMD"].get(command)
    return entry.name if entry is not None else f"MAV_CMD {command}"
