"""Check a MAVLink link before flying: is a vehicle there, which, in what state, with a position and a home.

`check_link(url)` connects as a ground station would (system 255, component MISSIONPLANNER), sends its
own HEARTBEAT once a second (a vehicle behind `udpout:` learns our address from it, as PX4 does),
waits for the vehicle's HEARTBEAT, then asks once a second for HOME_POSITION, LOCAL_POSITION_NED and
GLOBAL_POSITION_INT with MAV_CMD_REQUEST_MESSAGE (PX4 streams the positions anyway; ArduPilot needs
asking) until it has them or the timeout passes. It returns one LinkCheck per line: heartbeat,
autopilot, system id, flight mode, armed, position valid, home; each failure says how to fix it.

`magna doctor --mavlink URL` prints these lines. The connection here is deliberately small (pymavlink's
mavutil, nothing kept open): magna_mavlink.link.MavlinkLink serves one known system id and reconnects, where a
check must hear whichever vehicle is there and fail at once. URLs follow magna_mavlink.link.parse_url.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

from magna_mavlink.autopilot import UnknownAutopilot, autopilot_of, decode_mode
from magna_mavlink.pymavlink_types import MavConnection, MavMessage

GCS_SYSTEM, GCS_COMPONENT = 255, 190  # MAV_COMP_ID_MISSIONPLANNER: how a ground station introduces itself
MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID = 6, 8
MAV_CMD_REQUEST_MESSAGE = 512
MSG_LOCAL_POSITION_NED, MSG_GLOBAL_POSITION_INT, MSG_HOME_POSITION = 32, 33, 242
MAV_SYS_STATUS_SENSOR_GPS, MAV_SYS_STATUS_AHRS = 32, 2097152
MAV_RESULTS = {0: "ACCEPTED", 1: "TEMPORARILY_REJECTED", 2: "DENIED", 3: "UNSUPPORTED", 4: "FAILED",
               5: "IN_PROGRESS", 6: "CANCELLED"}
ASK_EVERY = 1.0  # s between our heartbeats and requests
CHECKS = ("heartbeat", "autopilot", "system id", "flight mode", "armed", "position valid", "home")


class BadUrl(ValueError):
    """A URL that is not a MAVLink connection pymavlink can open; the message names it and the forms."""


class LinkUnavailable(Exception):
    """The URL is well formed but cannot be opened (a port in use, a missing device, a refused TCP)."""

    def __init__(self, detail: str, fix: str):
        super().__init__(detail)
        self.detail, self.fix = detail, fix


@dataclass(frozen=True)
class LinkCheck:
    name: str
    ok: bool
    detail: str
    fix: str = ""


@dataclass(frozen=True)
class LinkUrl:
    text: str
    kind: str  # udpin, udpout, tcp, tcpin, serial
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 57600

    @property
    def pymavlink_device(self) -> str:
        return self.device if self.kind == "serial" else f"{self.kind}:{self.host}:{self.port}"

    def no_heartbeat_fix(self) -> str:
        if self.kind == "udpin":
            return (f"is the vehicle running and sending MAVLink to this machine's port {self.port}? (PX4 SITL "
                    f"instance i sends to 14540+i; ArduPilot: its --out or SERIALn to udp:THIS_HOST:{self.port}); or "
                    "reach a vehicle that waits to be spoken to with udpout:HOST:PORT (PX4 SITL: 14580+i)")
        if self.kind == "udpout":
            return (f"is a vehicle running and listening at {self.host}:{self.port}? (PX4 SITL instance i listens "
                    "on 14580+i); a vehicle that only sends to a fixed port needs udpin:0.0.0.0:PORT instead")
        if self.kind == "tcp":
            return f"{self.host}:{self.port} accepted the connection but sent no MAVLink: is it the vehicle's port?"
        if self.kind == "tcpin":
            return f"is the vehicle (or its bridge) connecting to this machine's TCP port {self.port}?"
        return (f"check the cable, that MAVLink runs on {self.device} and its baud rate (given {self.baud}; "
                "telemetry radios use 57600, USB 115200)")


def parse_url(text: str) -> LinkUrl:
    """A URL as ual_mavlink takes it (magna_mavlink.link.parse_url: one rule for both), sorted by the kind of
    link for the fixes; BadUrl names the text and the forms that work."""
    from magna_mavlink.link import LinkError
    from magna_mavlink.link import parse_url as parse_link_url

    try:
        endpoint = parse_link_url(text)
    except LinkError as error:
        raise BadUrl(str(error)) from None
    scheme, sep, rest = endpoint.device.partition(":")
    if sep and scheme in ("udpin", "udpout", "udp", "tcp", "tcpin"):
        host, _, port = rest.rpartition(":")
        kind = "udpin" if scheme == "udp" else scheme  # pymavlink's plain udp: listens
        return LinkUrl(text.strip(), kind, host, int(port))
    return LinkUrl(text.strip(), "serial", device=endpoint.device, baud=endpoint.baud)


@dataclass
class Observations:
    """What the vehicle said during the check (fed message by message, times in s since the start)."""

    vehicle: tuple[int, int] | None = None  # (system, component) of the first autopilot heartbeat
    heartbeat: MavMessage | None = None  # its latest HEARTBEAT
    first_heartbeat_at: float = 0.0
    heartbeats: int = 0
    not_autopilots: set[tuple[int, int]] = field(default_factory=set)  # (system, component) of GCSs, companions
    other_systems: set[int] = field(default_factory=set)  # other vehicles' system ids
    local_position: MavMessage | None = None
    global_position: MavMessage | None = None
    sys_status: MavMessage | None = None
    home: MavMessage | None = None
    refused: int | None = None  # a MAV_RESULT other than ACCEPTED to one of our message requests

    def add(self, msg: MavMessage, now: float) -> None:
        kind = msg.get_type()
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if kind == "HEARTBEAT":
            if msg.type == MAV_TYPE_GCS or msg.autopilot == MAV_AUTOPILOT_INVALID:
                self.not_autopilots.add(source)
                return
            if self.vehicle is None:
                self.vehicle, self.first_heartbeat_at = source, now
            if source == self.vehicle:
                self.heartbeat = msg
                self.heartbeats += 1
            elif source[0] != self.vehicle[0]:
                self.other_systems.add(source[0])
            return
        if self.vehicle is None or source[0] != self.vehicle[0]:
            return
        if kind == "LOCAL_POSITION_NED":
            self.local_position = msg
        elif kind == "GLOBAL_POSITION_INT" and (msg.lat, msg.lon) != (0, 0):  # 0, 0: no fix yet (ArduPilot)
            self.global_position = msg
        elif kind == "SYS_STATUS":
            self.sys_status = msg
        elif kind == "HOME_POSITION" and (msg.latitude, msg.longitude) != (0, 0):
            self.home = msg
        elif kind == "COMMAND_ACK" and msg.command == MAV_CMD_REQUEST_MESSAGE and msg.result != 0:
            self.refused = msg.result  # an ACK does not say which message was asked for: kept for the reader

    @property
    def position_valid(self) -> bool:
        return self.local_position is not None or self.global_position is not None

    @property
    def complete(self) -> bool:
        return self.heartbeat is not None and self.position_valid and self.home is not None


def evaluate(url: LinkUrl, seen: Observations, timeout: float, waited: float) -> list[LinkCheck]:
    """The lines of the check from what was seen; only the heartbeat line when no vehicle answered."""
    if seen.heartbeat is None:
        heard = ""
        if seen.not_autopilots:
            heard = ("; heard only HEARTBEATs of ground stations or companions (system/component "
                     + ", ".join(f"{s}/{c}" for s, c in sorted(seen.not_autopilots)) + ")")
        return [LinkCheck("heartbeat", False, f"no HEARTBEAT from a vehicle at {url.text} within {timeout:g} s"
                          + heard, url.no_heartbeat_fix())]
    hb = seen.heartbeat
    assert seen.vehicle is not None  # a heartbeat is kept only from the vehicle it names
    system, component = seen.vehicle
    rate = ""
    if seen.heartbeats > 1 and waited > seen.first_heartbeat_at:
        rate = f", {seen.heartbeats} in {waited - seen.first_heartbeat_at:.1f} s"
    checks = [LinkCheck("heartbeat", True, f"from {url.text} after {seen.first_heartbeat_at:.2f} s{rate}")]
    try:
        autopilot = autopilot_of(hb.autopilot)
    except UnknownAutopilot as error:
        checks.append(LinkCheck("autopilot", False, str(error),
                                "point the URL at the PX4 or ArduPilot flight controller itself"))
        return checks + [LinkCheck(name, False, "not checked: the autopilot is not one the UAL flies",
                                   "see the autopilot line") for name in CHECKS[2:]]
    checks.append(LinkCheck("autopilot", True, f"{'PX4' if autopilot == 'px4' else 'ArduPilot'} "
                            f"(HEARTBEAT.autopilot {hb.autopilot}), vehicle type {_mav_type(hb.type)}"))
    others = ""
    if seen.other_systems:
        others = (f"; other vehicles on this link: {', '.join(map(str, sorted(seen.other_systems)))} (give "
                  "ual_mavlink --system-id to choose)")
    checks.append(LinkCheck("system id", True, f"{system}, component {component}{others}"))
    mode = decode_mode(hb.autopilot, hb.base_mode, hb.custom_mode)
    checks.append(LinkCheck("flight mode", True, mode.name + (" (the UAL's set-point mode)"
                                                             if mode.follows_set_points else "")))
    checks.append(LinkCheck("armed", True, "armed" if mode.armed else "disarmed"))
    checks.append(_position_line(seen, timeout))
    checks.append(_home_line(seen, timeout))
    return checks


def _position_line(seen: Observations, timeout: float) -> LinkCheck:
    parts = []
    if seen.local_position is not None:
        p = seen.local_position
        parts.append(f"LOCAL_POSITION_NED ({p.x:.2f}, {p.y:.2f}, {p.z:.2f}) m")
    if seen.global_position is not None:
        g = seen.global_position
        parts.append(f"GLOBAL_POSITION_INT {g.lat / 1e7:.7f}, {g.lon / 1e7:.7f}, {g.alt / 1000:.1f} m")
    if parts:
        return LinkCheck("position valid", True, "; ".join(parts))
    detail = f"no LOCAL_POSITION_NED nor GLOBAL_POSITION_INT with a fix within {timeout:g} s"
    status = seen.sys_status
    if status is not None:
        present, healthy = status.onboard_control_sensors_present, status.onboard_control_sensors_health
        unhealthy = [name for bit, name in ((MAV_SYS_STATUS_SENSOR_GPS, "GPS"), (MAV_SYS_STATUS_AHRS, "AHRS"))
                     if present & bit and not healthy & bit]
        if unhealthy:
            detail += f"; SYS_STATUS: {' and '.join(unhealthy)} unhealthy"
    return LinkCheck("position valid", False, detail,
                     "wait for a GPS fix and the estimator (PX4: EKF2; ArduPilot: an EKF origin); indoors, give "
                     "the autopilot a position source (motion capture) and, on ArduPilot, set the EKF origin")


def _home_line(seen: Observations, timeout: float) -> LinkCheck:
    if seen.home is not None:
        h = seen.home
        return LinkCheck("home", True, f"{h.latitude / 1e7:.7f}, {h.longitude / 1e7:.7f}, {h.altitude / 1000:.1f} m")
    answer = ""
    if seen.refused is not None:
        answer = (f"; the vehicle answered a MAV_CMD_REQUEST_MESSAGE with "
                  f"{MAV_RESULTS.get(seen.refused, seen.refused)}")
    return LinkCheck("home", False, f"no HOME_POSITION within {timeout:g} s{answer}",
                     "the autopilot sets home at its first position fix (PX4) or when it arms (ArduPilot); once "
                     "the position is valid, set it with the UAL's set_home (MAV_CMD_DO_SET_HOME)")


def _mav_type(number: int) -> str:
    enum = _mavutil().mavlink.enums.get("MAV_TYPE", {})
    return enum[number].name.removeprefix("MAV_TYPE_") if number in enum else str(number)


def _mavutil():
    """pymavlink's mavutil speaking MAVLink 2 (PX4 and magna_sim's vehicle do; its decoder reads 1 and 2)."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    if mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":
        os.environ["MAVLINK20"] = "1"
        mavutil.set_dialect(mavutil.current_dialect)
    return mavutil


def connect(url: LinkUrl) -> MavConnection:
    """pymavlink's connection for the URL; LinkUnavailable (the URL, the reason, the fix) when it cannot be
    opened."""
    mavutil = _mavutil()
    try:
        if url.kind == "serial":
            if not os.path.exists(url.device):
                raise FileNotFoundError(f"no such device {url.device}")
            return mavutil.mavlink_connection(url.device, baud=url.baud, source_system=GCS_SYSTEM,
                                              source_component=GCS_COMPONENT)
        return mavutil.mavlink_connection(url.pymavlink_device, source_system=GCS_SYSTEM,
                                          source_component=GCS_COMPONENT, retries=0)
    except OSError as error:
        reason = error.strerror or str(error)
        raise LinkUnavailable(f"cannot open {url.text}: {reason}", _connection_fix(url)) from None
    except Exception as error:  # pyserial's SerialException and the like
        raise LinkUnavailable(f"cannot open {url.text}: {error}", _connection_fix(url)) from None


def _connection_fix(url: LinkUrl) -> str:
    if url.kind == "udpin":
        return (f"another program may hold port {url.port} (QGroundControl, MAVSDK, a running ual_mavlink): stop it, "
                "or reach the vehicle with udpout:HOST:PORT (PX4 SITL: 14580+i)")
    if url.kind == "udpout":
        return f"check the host {url.host!r} (an IP address or a known name)"
    if url.kind == "tcp":
        return (f"is the vehicle listening for TCP at {url.host}:{url.port}? (ArduPilot SITL serves "
                "tcp:127.0.0.1:5760)")
    if url.kind == "tcpin":
        return f"another program may hold TCP port {url.port}: stop it or choose another port"
    return ("plug the autopilot in, look for it with 'ls /dev/ttyACM* /dev/ttyUSB*', and make sure you may open it "
            "(group dialout)")


def check_link(text: str, timeout: float = 5.0) -> list[LinkCheck]:
    """Connect to `text`, watch and ask for up to `timeout` s for the heartbeat, then again for position and
    home; the lines of the check. BadUrl for a URL that is not one."""
    url = parse_url(text)
    try:
        link = connect(url)
    except LinkUnavailable as error:
        return [LinkCheck("connection", False, error.detail, error.fix)]
    seen = Observations()
    start = time.monotonic()
    deadline = start + timeout
    next_ask = start
    try:
        while True:
            now = time.monotonic()
            if seen.complete or now >= deadline:
                break
            if now >= next_ask:
                next_ask = now + ASK_EVERY
                link.mav.heartbeat_send(MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, 0)
                if seen.vehicle is not None:
                    _ask(link, seen)
            msg = link.recv_match(blocking=True, timeout=max(0.0, min(next_ask, deadline) - now))
            if msg is None or msg.get_type() == "BAD_DATA":
                continue
            had_vehicle = seen.vehicle is not None
            seen.add(msg, time.monotonic() - start)
            if not had_vehicle and seen.vehicle is not None:
                deadline = time.monotonic() + timeout  # as long again for the position and the home
                next_ask = time.monotonic()
    finally:
        link.close()
    return evaluate(url, seen, timeout, time.monotonic() - start)


def _ask(link: MavConnection, seen: Observations) -> None:
    assert seen.vehicle is not None  # check_link asks once a vehicle is heard
    system, component = seen.vehicle
    wanted = []
    if seen.home is None:
        wanted.append(MSG_HOME_POSITION)
    if not seen.position_valid:
        wanted += [MSG_LOCAL_POSITION_NED, MSG_GLOBAL_POSITION_INT]
    for message_id in wanted:
        link.mav.command_long_send(system, component, MAV_CMD_REQUEST_MESSAGE, 0, message_id, 0, 0, 0, 0, 0, 0)
