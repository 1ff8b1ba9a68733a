"""The fleet file: how a mission reaches its hil and real UAVs over MAVLink.

A mission says which UAVs are `sitl`, `hil` or `real` (Agents_Config "mode"); it cannot say where a
real autopilot is plugged in, because that changes from one field day to the next. The fleet file does:

    # fleet.yaml
    origin_geo: [37.4107, -6.0028, 12.0]   # optional: lat, lon, alt of the map origin (else the world's)
    uavs:
      3:
        url: udpin:0.0.0.0:14542            # pymavlink URL: udpin:, udpout:, tcp:, or /dev/ttyACM0,57600
        autopilot: px4                      # px4 | ardupilot | auto (read from the heartbeat; default)
        arming: auto                        # auto (SITL, HIL) | pilot (a safety pilot arms; default for real)
        system_id: 3                        # MAVLink system id of the vehicle (default: the ID)
      4:
        stand_in: true                      # hil only: magna_sim flies a PX4-like vehicle for it
        link_faults: {loss: 0.2, delay: 0.05, cut_at: 30, cut_for: 5, seed: 1}   # optional, stand-ins only

Every hil or real UAV of the mission needs an entry, and only they may have one. A `stand_in` UAV
has no URL: the ground station gives magna_sim's vehicle free ports and connects to them. Its
`link_faults` put a udp_proxy on that link (a fraction of packets lost each way, a one-way delay in s,
a cut of `cut_for` s starting `cut_at` wall s after the bridge starts), to try a mission on a bad radio.
`load_fleet` parses and checks a file once; `check_against_mission` says what does not fit a
mission. Errors name the file, the field and the fix.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import yaml

from magna_mavlink.autopilot import ARDUPILOT, PX4

AUTOPILOT_CHOICES = ("auto", PX4, ARDUPILOT)
ARMING_POLICIES = ("auto", "pilot")
UAV_KEYS = ("url", "autopilot", "arming", "system_id", "stand_in", "link_faults")
FAULT_KEYS = ("loss", "delay", "cut_at", "cut_for", "seed")
TOP_KEYS = ("origin_geo", "uavs")
MAVLINK_MODES = ("hil", "real")

# pymavlink's connection strings (mavutil.mavlink_connection): network ones and serial devices.
_NETWORK_URL = re.compile(r"^(udpin|udpout|udp|udpbcast|tcp|tcpin):([^:/]*):(\d{1,5})$")
_SERIAL_URL = re.compile(r"^(/dev/\S+|COM\d+)(,\d+)?$")


class FleetError(ValueError):
    """A fleet file that cannot be used; the message is `<file>: <field>: <what is wrong and the fix>`."""


@dataclass(frozen=True)
class LinkFaults:
    loss: float = 0.0  # fraction of packets dropped in each direction
    delay: float = 0.0  # s added one way
    cut_at: float | None = None  # wall s after the bridge starts
    cut_for: float = 0.0  # s
    seed: int = 0

    def proxy_arguments(self) -> list[str]:
        """The udp_proxy options that make these faults."""
        args = ["--loss", f"{self.loss:g}", "--delay", f"{self.delay:g}", "--seed", str(self.seed)]
        if self.cut_at is not None:
            args += ["--cut-at", f"{self.cut_at:g}", "--cut-for", f"{self.cut_for:g}"]
        return args


@dataclass(frozen=True)
class FleetUav:
    id: int
    url: str  # "" for a stand-in: the ground station picks its ports
    autopilot: str  # auto | px4 | ardupilot
    arming: str | None  # auto | pilot; None: the mode decides (pilot for real, auto for hil)
    system_id: int
    stand_in: bool
    link_faults: LinkFaults | None = None

    def arming_for(self, mode: str) -> str:
        if self.arming is not None:
            return self.arming
        return "pilot" if mode == "real" else "auto"


@dataclass(frozen=True)
class Fleet:
    source: str
    origin_geo: tuple[float, float, float] | None
    uavs: dict[int, FleetUav]


def check_url(url: str) -> str | None:
    """Why `url` is not a pymavlink connection string, or None when it is one."""
    network = _NETWORK_URL.match(url)
    if network:
        port = int(network.group(3))
        return None if 0 < port < 65536 else f"port {port} is not 1..65535"
    if _SERIAL_URL.match(url):
        return None
    return ("is not a MAVLink connection string; write udpin:0.0.0.0:14540 (listen), udpout:192.168.1.10:14540 "
            "(send), tcp:127.0.0.1:5760 or a serial port such as /dev/ttyACM0,57600")


def load_fleet(path: Path | str) -> Fleet:
    path = Path(path)
    source = str(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise FleetError(f"{source}: no such file; give the fleet file of the run (see src/magna_mavlink/README.md, "
                         f"'The fleet file')") from None
    except yaml.YAMLError as error:
        raise FleetError(f"{source}: not valid YAML: {error}") from None
    if not isinstance(data, dict):
        raise FleetError(f"{source}: the file must be a mapping with 'uavs' (and optionally 'origin_geo'); "
                         f"it holds {type(data).__name__}")
    _no_unknown_keys(source, "", data, TOP_KEYS)
    origin = _origin(source, data.get("origin_geo"))
    uavs_data = data.get("uavs")
    if not isinstance(uavs_data, dict) or not uavs_data:
        raise FleetError(f"{source}: uavs: give one entry per hil or real UAV, keyed by its mission ID, "
                         f"e.g. 'uavs: {{3: {{url: udpin:0.0.0.0:14542}}}}'")
    uavs = {}
    for key, entry in uavs_data.items():
        uav = _uav(source, key, entry)
        if uav.id in uavs:
            raise FleetError(f"{source}: uavs.{key}: UAV {uav.id} is listed twice; keep one entry")
        uavs[uav.id] = uav
    urls = [u.url for u in uavs.values() if u.url]
    for url in set(urls):
        if urls.count(url) > 1:
            owners = sorted(u.id for u in uavs.values() if u.url == url)
            raise FleetError(f"{source}: uavs: UAVs {owners} share the URL {url}; each UAV needs its own link "
                             f"(MAVLink system ids tell vehicles apart only behind a router)")
    return Fleet(source, origin, uavs)


def check_against_mission(fleet: Fleet, modes: dict[int, str]) -> list[str]:
    """What does not fit the mission's UAVs (`modes`: ID -> sitl | hil | real); empty when all fits."""
    problems = []
    for uav_id, mode in sorted(modes.items()):
        if mode in MAVLINK_MODES and uav_id not in fleet.uavs:
            problems.append(f"{fleet.source}: uavs: UAV {uav_id} is {mode} in the mission but has no entry; add "
                            f"'{uav_id}: {{url: ...}}' (or 'stand_in: true' for a simulated HIL vehicle)")
    for uav_id, uav in sorted(fleet.uavs.items()):
        mission_mode = modes.get(uav_id)
        where = f"{fleet.source}: uavs.{uav_id}"
        if mission_mode is None:
            problems.append(f"{where}: the mission has no UAV {uav_id} (its IDs: {sorted(modes)}); remove the entry "
                            f"or fix the ID")
        elif mission_mode not in MAVLINK_MODES:
            problems.append(f"{where}: UAV {uav_id} is {mission_mode} in the mission, so magna_sim flies it; remove "
                            f"the entry or make it hil or real in the mission's Agents_Config")
        elif uav.stand_in and mission_mode == "real":
            problems.append(f"{where}.stand_in: UAV {uav_id} is real in the mission: a real UAV has no simulated "
                            f"stand-in; remove stand_in or make the UAV hil")
    return problems


def mavlink_uavs(modes: dict[int, str]) -> list[int]:
    """The UAVs flown over MAVLink (hil or real). They fly in wall time, stand-ins included: their links,
    heartbeats and timeouts are wall time, so a mission with any of them runs at real time."""
    return sorted(i for i, mode in modes.items() if mode in MAVLINK_MODES)


# --- parsing ------------------------------------------------------------------------------------------------
def _no_unknown_keys(source: str, where: str, data: dict, known: tuple[str, ...]) -> None:
    for key in data:
        if key not in known:
            raise FleetError(f"{source}: {where}{key}: unknown field; the fields are {', '.join(known)}")


def _origin(source: str, value) -> tuple[float, float, float] | None:
    if value is None:
        return None
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise FleetError(f"{source}: origin_geo: {value!r} must be [latitude, longitude, altitude], "
                         f"e.g. [37.4107, -6.0028, 12.0]")
    lat, lon, alt = (float(v) for v in value)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise FleetError(f"{source}: origin_geo: latitude must be -90..90 and longitude -180..180 degrees, "
                         f"got {lat}, {lon}")
    return lat, lon, alt


def _uav(source: str, key, entry) -> FleetUav:
    if isinstance(key, bool) or not isinstance(key, int) or key < 1:
        raise FleetError(f"{source}: uavs.{key}: the keys are the UAVs' mission IDs (1, 2, ...), got {key!r}")
    where = f"uavs.{key}"
    if not isinstance(entry, dict):
        raise FleetError(f"{source}: {where}: give a mapping such as {{url: udpin:0.0.0.0:14542}}, "
                         f"got {entry!r}")
    _no_unknown_keys(source, f"{where}.", entry, UAV_KEYS)
    stand_in = entry.get("stand_in", False)
    if not isinstance(stand_in, bool):
        raise FleetError(f"{source}: {where}.stand_in: {stand_in!r} must be true or false")
    url = entry.get("url", "")
    if not isinstance(url, str):
        raise FleetError(f"{source}: {where}.url: {url!r} must be text such as udpin:0.0.0.0:14542")
    url = url.strip()
    if stand_in and url:
        raise FleetError(f"{source}: {where}.url: a stand_in UAV gets its ports from the ground station; remove "
                         f"the url, or remove stand_in to fly the vehicle at {url}")
    if not stand_in:
        if not url:
            raise FleetError(f"{source}: {where}.url: missing; say where the autopilot is, e.g. "
                             f"url: udpin:0.0.0.0:14542 (or stand_in: true for a simulated HIL vehicle)")
        why = check_url(url)
        if why:
            raise FleetError(f"{source}: {where}.url: {url!r} {why}")
    autopilot = entry.get("autopilot", "auto")
    if autopilot not in AUTOPILOT_CHOICES:
        raise FleetError(f"{source}: {where}.autopilot: {autopilot!r} is not one of {', '.join(AUTOPILOT_CHOICES)}")
    if stand_in and autopilot == ARDUPILOT:
        raise FleetError(f"{source}: {where}.autopilot: magna_sim's stand-in is PX4-like; use px4 or auto")
    arming = entry.get("arming")
    if arming is not None and arming not in ARMING_POLICIES:
        raise FleetError(f"{source}: {where}.arming: {arming!r} is not one of {', '.join(ARMING_POLICIES)} "
                         f"(auto: MAVLink arms it; pilot: the safety pilot arms and switches mode)")
    system_id = entry.get("system_id", key)
    if isinstance(system_id, bool) or not isinstance(system_id, int) or not 1 <= system_id <= 255:
        raise FleetError(f"{source}: {where}.system_id: {system_id!r} must be a MAVLink system id, 1..255")
    faults = _faults(source, f"{where}.link_faults", entry.get("link_faults"), stand_in)
    return FleetUav(id=key, url=url, autopilot=autopilot, arming=arming, system_id=system_id, stand_in=stand_in,
                    link_faults=faults)


def _faults(source: str, where: str, value, stand_in: bool) -> LinkFaults | None:
    if value is None:
        return None
    if not stand_in:
        raise FleetError(f"{source}: {where}: only a stand_in's link can be given faults; for a real link run "
                         f"`rosrun magna_mavlink udp_proxy` in front of it and point url at the proxy")
    if not isinstance(value, dict):
        raise FleetError(f"{source}: {where}: give a mapping such as {{loss: 0.2, delay: 0.05}}, got {value!r}")
    _no_unknown_keys(source, f"{where}.", value, FAULT_KEYS)
    numbers = {}
    for key in ("loss", "delay", "cut_at", "cut_for"):
        number = value.get(key)
        if number is None:
            continue
        if isinstance(number, bool) or not isinstance(number, (int, float)) or not math.isfinite(number) \
                or number < 0:
            raise FleetError(f"{source}: {where}.{key}: {number!r} must be a number of 0 or more")
        numbers[key] = float(number)
    if numbers.get("loss", 0.0) >= 1.0:
        raise FleetError(f"{source}: {where}.loss: {numbers['loss']:g} is a fraction of packets, below 1 "
                         f"(0.2 drops one in five)")
    if ("cut_at" in numbers) != ("cut_for" in numbers):
        raise FleetError(f"{source}: {where}: give cut_at and cut_for together (when the cut starts, how long "
                         f"it lasts, in s)")
    seed = value.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise FleetError(f"{source}: {where}.seed: {seed!r} must be a whole number")
    return LinkFaults(loss=numbers.get("loss", 0.0), delay=numbers.get("delay", 0.0), cut_at=numbers.get("cut_at"),
                      cut_for=numbers.get("cut_for", 0.0), seed=seed)
