"""The latest telemetry of one autopilot, turned into ROS terms: the map frame (ENU), FLU body, UAL flags.

Fed with the MAVLink messages of the target system (from the link's receive thread) and read as a
`Telemetry` snapshot (from the set-point thread and the ROS publishers). Times are the caller's
clock (ROS time in the node), in seconds.

The map frame. Without a geo origin, `map` is the autopilot's local frame (its EKF origin), turned
from NED to ENU. With `origin_geo` (lat, lon, alt of the map's origin, as a world's origin_geo),
the autopilot's local origin is placed in the map through its geographic position, taken once from
whichever comes first: GPS_GLOBAL_ORIGIN, or a GLOBAL_POSITION_INT and a LOCAL_POSITION_NED of the
same instant (time_boot_ms within 50 ms, the vehicle nearly still). The position is not valid until
that offset is known. Altitudes are in the autopilot's datum (AMSL for PX4 and ArduPilot), so
`origin_geo`'s altitude must be given in it too. Geo waypoints are turned into map positions through
the local origin's geographic position (without `origin_geo` also from HOME_POSITION).
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from magna_common import geo

from . import autopilot as ap
from . import frames
from .pymavlink_types import MavMessage
from .ual_state import LANDED_UNDEFINED

POSITION_TIMEOUT = 1.0  # s without LOCAL_POSITION_NED before the position counts as lost
PAIR_WINDOW_MS = 50  # how close in time_boot_ms a global and a local position must be to place the origin
STILL_SPEED = 0.5  # m/s: faster than this, a global/local pair is not used to place the origin
AUTOPILOT_NUMBERS = {ap.PX4: ap.MAV_AUTOPILOT_PX4, ap.ARDUPILOT: ap.MAV_AUTOPILOT_ARDUPILOTMEGA}


@dataclass(frozen=True)
class Telemetry:
    """What the vehicle last reported, in the map frame (ENU) and the FLU body."""

    heartbeat_time: float | None = None  # the latest HEARTBEAT of the autopilot
    heard_time: float | None = None  # the latest message of any kind from it: the link is alive
    first_heard_time: float | None = None  # its first message of any kind
    landed_state_heard: bool = False  # an EXTENDED_SYS_STATE has come (some autopilots never send one)
    autopilot: str | None = None
    mode: ap.Mode | None = None
    armed: bool = False
    system_status: int = 0
    landed_state: int = LANDED_UNDEFINED
    position_time: float | None = None  # when the latest LOCAL_POSITION_NED came
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))  # map, m
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # map, m/s
    orientation: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))  # FLU in ENU, xyzw
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # body FLU, rad/s
    global_position: tuple[float, float, float] | None = None  # lat, lon, alt (deg, deg, m)
    home_geo: tuple[float, float, float] | None = None  # HOME_POSITION
    local_origin_geo: tuple[float, float, float] | None = None  # where the autopilot's local frame starts
    map_offset: np.ndarray | None = None  # map position of the autopilot's local origin; None: not known yet
    battery: float = math.nan  # remaining, 0..1; NaN when the autopilot does not say
    voltage: float = math.nan  # V

    @property
    def yaw(self) -> float:
        x, y, z, w = self.orientation
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    def position_valid(self, now: float, timeout: float = POSITION_TIMEOUT) -> bool:
        return (self.position_time is not None and self.map_offset is not None
                and -timeout <= now - self.position_time <= timeout)

    @property
    def follows_set_points(self) -> bool:
        return self.mode is not None and self.mode.follows_set_points

    def local_to_map(self, local_enu) -> np.ndarray:
        return np.asarray(local_enu, dtype=float) + (self.map_offset if self.map_offset is not None else 0.0)

    def map_to_local_ned(self, map_enu) -> np.ndarray:
        offset = self.map_offset if self.map_offset is not None else 0.0
        return frames.enu_to_ned(np.asarray(map_enu, dtype=float) - offset)

    def geo_reference(self) -> tuple[tuple[float, float, float], np.ndarray] | None:
        """(a geographic point, its map position) to turn geo waypoints into map positions, or None."""
        if self.local_origin_geo is not None and self.map_offset is not None:
            return self.local_origin_geo, self.map_offset
        return None


class VehicleState:
    """Thread-safe store of one autopilot's telemetry; `update` takes messages, `snapshot` gives Telemetry."""

    def __init__(self, origin_geo=None, autopilot: str | None = None):
        self.origin_geo = None if origin_geo is None else tuple(float(v) for v in origin_geo)
        self.forced_autopilot = autopilot  # px4 / ardupilot, or None to take the HEARTBEAT's word
        self.autopilot_error: str | None = None  # a HEARTBEAT from an autopilot we cannot fly
        self._lock = threading.Lock()
        self._t = Telemetry(map_offset=None if self.origin_geo else np.zeros(3))
        self._local = np.zeros(3)  # local ENU of the latest LOCAL_POSITION_NED
        self._local_boot_ms: int | None = None
        self._global: tuple[float, float, float] | None = None  # the latest GLOBAL_POSITION_INT
        self._global_boot_ms: int | None = None

    def snapshot(self) -> Telemetry:
        with self._lock:
            return self._t

    def update(self, msg: MavMessage, now: float) -> None:
        handler = getattr(self, "_on_" + msg.get_type(), None)
        with self._lock:
            changes = (handler(msg, now) if handler is not None else None) or {}
            first = self._t.first_heard_time if self._t.first_heard_time is not None else now
            self._t = replace(self._t, heard_time=now, first_heard_time=first, **changes)

    # --- one method per message ---------------------------------------------------------------------------------
    def _on_HEARTBEAT(self, msg, now):
        number = AUTOPILOT_NUMBERS[self.forced_autopilot] if self.forced_autopilot else msg.autopilot
        try:
            mode = ap.decode_mode(number, msg.base_mode, msg.custom_mode)
        except ap.UnknownAutopilot as err:
            self.autopilot_error = str(err)
            return {"heartbeat_time": now}
        return {"heartbeat_time": now, "autopilot": mode.autopilot, "mode": mode, "armed": mode.armed,
                "system_status": msg.system_status}

    def _on_EXTENDED_SYS_STATE(self, msg, now):
        return {"landed_state": msg.landed_state, "landed_state_heard": True}

    def _on_LOCAL_POSITION_NED(self, msg, now):
        self._local = frames.ned_to_enu((msg.x, msg.y, msg.z))
        self._local_boot_ms = msg.time_boot_ms
        velocity = frames.ned_to_enu((msg.vx, msg.vy, msg.vz))
        changes = {"position_time": now, "velocity": velocity}
        if self._global is not None and self._pair_ok(velocity):
            changes.update(self._place_origin(geo.enu_to_geodetic(-self._local, self._global)))
        offset = changes.get("map_offset", self._t.map_offset)
        changes["position"] = self._local + (offset if offset is not None else 0.0)
        return changes

    def _on_GLOBAL_POSITION_INT(self, msg, now):
        self._global = (msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3)
        self._global_boot_ms = msg.time_boot_ms
        changes = {"global_position": self._global}
        if self._local_boot_ms is not None and self._pair_ok(self._t.velocity):
            # The local origin is where the vehicle is (its fix) minus its local position.
            changes.update(self._place_origin(geo.enu_to_geodetic(-self._local, self._global)))
            if "map_offset" in changes:
                changes["position"] = self._local + changes["map_offset"]
        return changes

    def _on_GPS_GLOBAL_ORIGIN(self, msg, now):
        return self._place_origin((msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3))

    def _on_HOME_POSITION(self, msg, now):
        home = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3)
        changes = {"home_geo": home}
        if self.origin_geo is None:  # with a map origin, wait for a pair: HOME_POSITION's x, y, z may be unset
            changes.update(self._place_origin(geo.enu_to_geodetic(-frames.ned_to_enu((msg.x, msg.y, msg.z)), home)))
        return changes

    def _on_ATTITUDE(self, msg, now):
        ned = Rotation.from_euler("ZYX", [msg.yaw, msg.pitch, msg.roll]).as_quat()
        return {"orientation": frames.attitude_ned_frd_to_enu_flu(ned),
                "angular_velocity": frames.frd_to_flu((msg.rollspeed, msg.pitchspeed, msg.yawspeed))}

    def _on_SYS_STATUS(self, msg, now):
        remaining = math.nan if msg.battery_remaining < 0 else msg.battery_remaining / 100.0
        voltage = math.nan if msg.voltage_battery == 0xFFFF else msg.voltage_battery / 1000.0
        return {"battery": remaining, "voltage": voltage}

    # --- the map origin -------------------------------------------------------------------------------------------
    def _pair_ok(self, velocity) -> bool:
        """A global and a local position of one instant, taken while the vehicle is nearly still."""
        return (self._global_boot_ms is not None and self._local_boot_ms is not None
                and abs(self._local_boot_ms - self._global_boot_ms) <= PAIR_WINDOW_MS
                and float(np.linalg.norm(velocity)) <= STILL_SPEED)

    def _place_origin(self, local_origin_geo: tuple[float, float, float]) -> dict[str, object]:
        """The geographic position of the autopilot's local origin, the first time it is known (then fixed)."""
        if self._t.local_origin_geo is not None:
            return {}
        changes: dict[str, object] = {"local_origin_geo": tuple(float(v) for v in local_origin_geo)}
        if self.origin_geo is not None:
            changes["map_offset"] = geo.geodetic_to_enu(*local_origin_geo, self.origin_geo)
        return changes


