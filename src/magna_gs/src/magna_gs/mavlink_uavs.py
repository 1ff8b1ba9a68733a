"""The mission's hil and real UAVs: each flown through a ual_mavlink bridge the ground station starts.

A `sitl` UAV is spawned in magna_sim and served by its UAL. A `hil` or `real` UAV is wherever its fleet
entry says (magna_mavlink.fleet): the ground station starts `ual_mavlink` for it, which serves the same
UAL API under /uav_{id}/ual/, so the UAV managers, the evaluator, the recorder and the bag treat every
UAV alike. A hil entry with `stand_in: true` first gets magna_sim's PX4-like vehicle, on free UDP ports.

Bring-up refuses, before any take-off, a UAV whose vehicle does not answer, naming its URL. In flight,
a bridge that reports its link lost (/uav_{id}/ual_mavlink/link) becomes the ground station's critical
event: every role ends GS_critical_event and the mission takes its safety branch.
"""
from __future__ import annotations

import subprocess
import tempfile
import threading
import time
import typing
from dataclasses import dataclass

import rospy
from std_msgs.msg import String
from uav_abstraction_layer.msg import State as UalState

from magna_common import ros_names as names
from magna_common.ports import free_udp_ports
from magna_common.processes import end_process_group
from magna_mavlink.fleet import Fleet, FleetUav
from magna_sim.mavlink_telemetry import PX4_SITL_HOME

CONNECT_TIMEOUT = 15.0  # wall s a bridge has to hear its vehicle (ual_mavlink --connect-timeout)
READY_MARGIN = 15.0  # wall s more for the node to start and the vehicle to report a valid position


class MavlinkUavError(RuntimeError):
    """A hil or real UAV that cannot fly this mission; the message says which, where and why."""


@dataclass
class Bridge:
    uav_id: int
    url: str
    process: subprocess.Popen
    stand_in: bool
    errors: typing.IO[str]  # the bridge's stderr


def resolve_origin(fleet: Fleet | None, world_origin) -> tuple[tuple[float, float, float], str]:
    """The map's geo origin and where it came from: the fleet file, else the world, else PX4 SITL's home."""
    if fleet is not None and fleet.origin_geo is not None:
        return fleet.origin_geo, f"origin_geo of {fleet.source}"
    if world_origin:
        lat, lon, alt = (float(v) for v in world_origin)  # the world node sets [lat, lon, alt]
        return (lat, lon, alt), "the world's origin_geo"
    return PX4_SITL_HOME, "PX4 SITL's default home (neither the fleet nor the world has origin_geo)"


def bridge_command(uav: FleetUav, mode: str, url: str, origin) -> list[str]:
    """The ual_mavlink command line for one UAV."""
    return ["rosrun", "magna_mavlink", "ual_mavlink", f"__name:=uav_{uav.id}_ual_mavlink",
            "--id", str(uav.id), "--url", url, "--system-id", str(uav.system_id),
            "--autopilot", uav.autopilot, "--arming", uav.arming_for(mode),
            "--origin-geo", *(repr(float(v)) for v in origin),
            "--connect-timeout", f"{CONNECT_TIMEOUT:g}"]


class MavlinkUavs:
    """Bridges of one mission: start, wait until ready, watch their links, stop."""

    def __init__(self, fleet: Fleet, modes: dict[int, str], output: str = "log"):
        self.fleet, self.modes, self.output = fleet, modes, output
        self.origin: tuple[float, float, float] | None = None  # tied at the first bring-up, once the world is up
        self.bridges: dict[int, Bridge] = {}
        self.proxies: list[subprocess.Popen] = []  # udp_proxy processes of stand-ins with link_faults
        self.lost: dict[int, str] = {}  # UAV id -> what its bridge said when the link went
        self._states: dict[int, int] = {}
        self._lock = threading.Lock()
        self._subscribers: list[rospy.Subscriber] = []
        self.on_link_lost = lambda uav_id, text: None  # set by the ground station

    def flies(self, uav_id: int) -> bool:
        return uav_id in self.fleet.uavs and self.modes.get(uav_id) in ("hil", "real")

    def arms_itself(self, uav_id: int) -> bool:
        """Whether its bridge arms it for a take-off (arming auto), so it may take off from LANDED_DISARMED."""
        return self.flies(uav_id) and self.fleet.uavs[uav_id].arming_for(self.modes[uav_id]) == "auto"

    def bring_up(self, uav_id: int, spawn_stand_in) -> None:
        """Start the bridge of `uav_id` (after `spawn_stand_in(local_port, remote_port)` for a stand-in)
        and wait until its UAL reports a valid state; MavlinkUavError when the vehicle is not there."""
        if self.origin is None:
            self.origin, where = resolve_origin(self.fleet, rospy.get_param(names.WORLD_ORIGIN_GEO, None))
            rospy.loginfo(f"MAVLink UAVs: the map origin is {self.origin} ({where})")
        uav = self.fleet.uavs[uav_id]
        url = uav.url
        if uav.stand_in:
            local, remote, listen = free_udp_ports(3)
            spawn_stand_in(local, remote)
            url = f"udpin:127.0.0.1:{remote}"  # where the stand-in sends, as PX4 SITL sends to 14540+i
            if uav.link_faults is not None:  # the bridge talks to the proxy, the proxy to the vehicle
                self.proxies.append(subprocess.Popen(
                    ["rosrun", "magna_mavlink", "udp_proxy", "--listen", f"127.0.0.1:{listen}",
                     "--to", f"127.0.0.1:{local}", *uav.link_faults.proxy_arguments()],
                    start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
                url = f"udpout:127.0.0.1:{listen}"
        self._subscribers.append(rospy.Subscriber(names.ual(uav_id, "state"), UalState, self._on_state, uav_id,
                                                  queue_size=1))
        self._subscribers.append(rospy.Subscriber(names.mavlink_link(uav_id), String, self._on_link, uav_id,
                                                  queue_size=10))
        # Its errors go to an unnamed file, not a pipe: a pipe nobody reads would block a talkative node.
        errors = tempfile.TemporaryFile("w+")
        on_screen = self.output == "screen"
        process = subprocess.Popen(bridge_command(uav, self.modes[uav_id], url, self.origin), start_new_session=True,
                                   stdout=None if on_screen else subprocess.DEVNULL,
                                   stderr=None if on_screen else errors)
        self.bridges[uav_id] = Bridge(uav_id, url, process, uav.stand_in, errors)
        self._wait_ready(self.bridges[uav_id])

    def _wait_ready(self, bridge: Bridge) -> None:
        uav_id, url, process = bridge.uav_id, bridge.url, bridge.process
        deadline = time.monotonic() + CONNECT_TIMEOUT + READY_MARGIN
        while time.monotonic() < deadline and not rospy.is_shutdown():
            with self._lock:
                state = self._states.get(uav_id, UalState.UNINITIALIZED)
            if state != UalState.UNINITIALIZED:
                rospy.loginfo(f"UAV {uav_id} ({self.modes[uav_id]}): MAVLink vehicle at {url} is ready")
                return
            if process.poll() is not None:
                why = _last_line(bridge.errors) or f"ual_mavlink exited with code {process.returncode}"
                hint = "" if "magna doctor" in why else f". Check the link with: magna doctor --mavlink {url}"
                raise MavlinkUavError(f"UAV {uav_id} ({self.modes[uav_id]}): no vehicle at {url}: {why}{hint}")
            time.sleep(0.05)
        raise MavlinkUavError(f"UAV {uav_id} ({self.modes[uav_id]}): the vehicle at {url} gave no valid position "
                              f"within {CONNECT_TIMEOUT + READY_MARGIN:g} s (its UAL stays UNINITIALIZED); check "
                              f"its GPS/estimator, and the link with: magna doctor --mavlink {url}")

    def _on_state(self, msg, uav_id: int) -> None:
        with self._lock:
            self._states[uav_id] = msg.state

    def _on_link(self, msg, uav_id: int) -> None:
        if not msg.data:
            return
        with self._lock:
            first = uav_id not in self.lost
            self.lost.setdefault(uav_id, msg.data)
        if first:
            self.on_link_lost(uav_id, msg.data)

    def stop(self, grace: float = 10.0) -> None:
        """End every bridge (after the managers: their last hover goes through the bridge)."""
        for subscriber in self._subscribers:
            subscriber.unregister()
        self._subscribers.clear()
        for bridge in self.bridges.values():
            end_process_group(bridge.process, grace)
            bridge.errors.close()
        self.bridges.clear()
        for proxy in self.proxies:
            end_process_group(proxy, grace)
        self.proxies.clear()


def _last_line(errors: typing.IO[str]) -> str:
    """The last line ual_mavlink wrote on stderr (its one-line error)."""
    try:
        errors.seek(0)
        text = errors.read()
    except (OSError, ValueError):
        return ""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else ""
