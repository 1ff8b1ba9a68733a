"""The command line of `rosrun magna_mavlink ual_mavlink`, and the same settings as private ROS parameters.

No ROS import: `--help` works without a master, and the settings are checked before anything opens.
A setting on the command line wins over the private parameter (`_id:=3`, or <param> in a launch
file), which wins over the default.
"""
from __future__ import annotations

import argparse
import math
import re
from dataclasses import dataclass

from .backend import AUTO, PILOT, Settings
from .link import LinkError, parse_url

DESCRIPTION = """\
Serve the GRVC UAL API of one UAV under /uav_{id}/ual/ over MAVLink: PX4 (flown in OFFBOARD) or
ArduPilot Copter (flown in GUIDED), told apart by the autopilot's HEARTBEAT. Topics pose, velocity,
odom, state, set_pose, set_velocity; services take_off, land, go_to_waypoint, go_to_waypoint_geo,
set_home, recover_from_manual; the id in /ual_ids while it runs. Link health on the latched topic
/uav_{id}/ual_mavlink/link: "" while the autopilot is heard, else what is wrong (the UAL state is then
UNINITIALIZED). Exit status 2 when the URL cannot be opened or no vehicle answers on it.

Every option is also a private parameter: _id:=3 _url:=udpin:0.0.0.0:14542 _origin_geo:="[lat, lon, alt]",
plus _position_th (0.33 m), _orientation_th (0.65 rad), _hold_pose_time (1 s), _take_off_speed (1 m/s),
_pub_rate (30 Hz)."""

EXAMPLES = """\
examples:
  rosrun magna_mavlink ual_mavlink --id 1 --url udpin:0.0.0.0:14540    # PX4 SITL's offboard port [hardware]
  rosrun magna_mavlink ual_mavlink --id 3 --url /dev/ttyACM0,57600 --system-id 1 --arming pilot \\
      --origin-geo 37.4101 -6.0023 55.0    # a real PX4 on a radio, the safety pilot arms [hardware]
  roslaunch magna_mavlink ual_mavlink.launch id:=2 url:=tcp:127.0.0.1:5762 autopilot:=ardupilot   # [hardware]"""

PARAMETERS = ("id", "url", "system_id", "autopilot", "arming", "origin_geo", "heartbeat_timeout", "connect_timeout",
              "tf", "position_th", "orientation_th", "hold_pose_time", "take_off_speed", "pub_rate")


class OptionError(ValueError):
    """A setting that cannot be used; the message names the option or parameter and the fix."""


@dataclass(frozen=True)
class Options:
    uav_id: int
    url: str
    system_id: int
    autopilot: str  # auto, px4, ardupilot
    arming: str
    origin_geo: tuple[float, float, float] | None
    heartbeat_timeout: float
    connect_timeout: float
    tf: bool
    pub_rate: float
    settings: Settings


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rosrun magna_mavlink ual_mavlink", description=DESCRIPTION,
                                     epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--id", type=int, help="UAL id of the UAV: its topics are /uav_{id}/ual/ (or _id:=N)")
    parser.add_argument("--url", help="MAVLink connection: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
                                      "or a serial device DEVICE,BAUD (or _url:=...)")
    parser.add_argument("--system-id", type=int, help="MAVLink system id of the autopilot (default: the --id)")
    parser.add_argument("--autopilot", choices=("auto", "px4", "ardupilot"),
                        help="auto (default): as the HEARTBEAT says; px4 or ardupilot to force one")
    parser.add_argument("--arming", choices=(AUTO, PILOT),
                        help="auto (default; simulation, HIL): ual_mavlink arms and selects OFFBOARD/GUIDED itself; "
                             "pilot (real UAVs): the safety pilot arms and switches, take_off waits for it")
    parser.add_argument("--origin-geo", type=float, nargs=3, metavar=("LAT", "LON", "ALT"),
                        help="geographic position of the map origin (a world's origin_geo; ALT in the autopilot's "
                             "datum, AMSL): poses are then in that map; default: the autopilot's local frame")
    parser.add_argument("--heartbeat-timeout", type=float, metavar="SECONDS",
                        help="without the autopilot's HEARTBEAT or any other message of it this long (ROS time) "
                             "the link counts as lost (2)")
    parser.add_argument("--connect-timeout", type=float, metavar="SECONDS",
                        help="wall-clock seconds to wait for the first HEARTBEAT before exiting with status 2 (10)")
    parser.add_argument("--no-tf", action="store_true",
                        help="do not broadcast tf map -> uav_{id}/base_link (when a simulator already does)")
    return parser


def id_from_argv(argv: list[str]) -> int | None:
    """The UAV id from `--id N` or `_id:=N`, before ROS starts (it names the node ual_mavlink_N)."""
    for index, arg in enumerate(argv):
        if arg == "--id" and index + 1 < len(argv) and re.fullmatch(r"\d+", argv[index + 1]):
            return int(argv[index + 1])
        match = re.fullmatch(r"(?:--id=|_id:=)(\d+)", arg)
        if match:
            return int(match.group(1))
    return None


def resolve(args: argparse.Namespace, params: dict) -> Options:
    """Options from the parsed command line and the private parameters given (name -> value)."""
    def pick(option, name, default=None):
        return option if option is not None else params.get(name, default)

    uav_id = pick(args.id, "id")
    if uav_id is None:
        raise OptionError("no UAV id: give --id N (or _id:=N)")
    uav_id = _integer("--id", uav_id, 1)
    url = pick(args.url, "url")
    if not url:
        raise OptionError("no connection: give --url URL, e.g. --url udpin:0.0.0.0:14540 (or _url:=...)")
    try:
        parse_url(str(url))
    except LinkError as err:
        raise OptionError(f"--url {err}") from None
    autopilot = str(pick(args.autopilot, "autopilot", "auto"))
    if autopilot not in ("auto", "px4", "ardupilot"):
        raise OptionError(f"_autopilot: {autopilot!r}; use auto, px4 or ardupilot")
    arming = str(pick(args.arming, "arming", AUTO))
    if arming not in (AUTO, PILOT):
        raise OptionError(f"_arming: {arming!r}; use {AUTO} (simulation, HIL) or {PILOT} (real UAVs)")
    origin = pick(args.origin_geo, "origin_geo")
    tf = not args.no_tf and _boolean("_tf", params.get("tf", True))
    settings = Settings(
        uav_id=uav_id, arming=arming,
        position_th=_positive("_position_th", params.get("position_th", Settings.position_th)),
        orientation_th=_positive("_orientation_th", params.get("orientation_th", Settings.orientation_th)),
        hold_pose_time=_positive("_hold_pose_time", params.get("hold_pose_time", Settings.hold_pose_time)),
        take_off_speed=_positive("_take_off_speed", params.get("take_off_speed", Settings.take_off_speed)),
        heartbeat_timeout=_positive("--heartbeat-timeout", pick(args.heartbeat_timeout, "heartbeat_timeout",
                                                                Settings.heartbeat_timeout)))
    return Options(
        uav_id=uav_id, url=str(url),
        system_id=_integer("--system-id", pick(args.system_id, "system_id", uav_id), 1, 255),
        autopilot=autopilot, arming=arming, origin_geo=_origin(origin),
        heartbeat_timeout=settings.heartbeat_timeout,
        connect_timeout=_positive("--connect-timeout", pick(args.connect_timeout, "connect_timeout", 10.0)),
        tf=tf, pub_rate=_positive("_pub_rate", params.get("pub_rate", 30.0)), settings=settings)


def _integer(name: str, value, low: int, high: int | None = None) -> int:
    try:
        number = int(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name}: {value!r} is not a whole number") from None
    fraction = isinstance(value, float) and not value.is_integer()
    if fraction or number < low or (high is not None and number > high):
        bounds = f"{low}..{high}" if high is not None else f">= {low}"
        raise OptionError(f"{name}: {value!r} must be a whole number {bounds}")
    return number


def _positive(name: str, value) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name}: {value!r} is not a number") from None
    if not math.isfinite(number) or number <= 0:
        raise OptionError(f"{name}: {value!r} must be a positive number")
    return number


def _boolean(name: str, value) -> bool:
    if isinstance(value, bool):
        return value
    if str(value).lower() in ("true", "1", "yes"):
        return True
    if str(value).lower() in ("false", "0", "no"):
        return False
    raise OptionError(f"{name}: {value!r}; use true or false")


def _origin(value) -> tuple[float, float, float] | None:
    if value is None or value == [] or value == "":
        return None
    if isinstance(value, str):
        value = value.replace("[", " ").replace("]", " ").replace(",", " ").split()
    try:
        lat, lon, alt = (float(v) for v in value)
    except (TypeError, ValueError):
        raise OptionError(f"--origin-geo: {value!r}; give LAT LON ALT (degrees, degrees, metres)") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180 and math.isfinite(alt)):
        raise OptionError(f"--origin-geo: {lat} {lon} {alt}: latitude must be in -90..90, longitude in -180..180")
    return lat, lon, alt
