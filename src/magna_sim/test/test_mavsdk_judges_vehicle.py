"""MAVSDK judges magna_sim's PX4-like vehicle (issue 24's done-when).

MAVSDK is the PyPI `mavsdk` package, pinned in requirements.txt and used unmodified: since 4.0 it is
the native binding, with MAVSDK's C++ core inside the wheel (no mavsdk_server process to start).
Its core runs in threads of this process and ends with `Mavsdk.destroy()`; the simulator is a node of
a private master, ended by pid with it.

The simulation runs at RTF times real time. MAVSDK streams its set-points at 20 Hz of wall time and
the vehicle, like PX4, drops OFFBOARD after COM_OF_LOSS_T (1 s) of *simulated* time without one: at
2x that is a set-point every 0.1 s, and the node's lockstep keeps the simulation within 0.15 s of the
latest one when a loaded machine delays MAVSDK's thread. Every wait is on a condition with a generous
deadline; the offboard-loss delay is measured in simulated time, from the vehicle's own time stamps.
"""
import json
import subprocess
import threading

import pytest
import rosgraph
from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.action import Action
from mavsdk.plugins.mavlink_direct import MavlinkDirect, MavlinkMessage
from mavsdk.plugins.offboard import Offboard, OffboardError, OffboardResult, PositionNedYaw, VelocityNedYaw
from mavsdk.plugins.telemetry import FlightMode, LandedState, Telemetry

from magna_common.ports import free_port
from magna_mavlink import autopilot
from tests.support import wait_until

RTF = 2.0
WAIT = 60.0  # wall s: a guard against hangs, never a performance expectation
MAV_RESULT_TEMPORARILY_REJECTED = 1


@pytest.fixture
def vehicle_ports(fresh_ros_master):
    """magna_sim with UAV 1 as a MAVLink vehicle on free ports: (local port, remote port)."""
    local, remote = free_port(udp=True), free_port(udp=True)
    fresh_ros_master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    node = fresh_ros_master.spawn(
        ["rosrun", "magna_sim", "sim", "_uavs:=1", "_mavlink:=true", f"_real_time_factor:={RTF}",
         f"_mavlink_local_port_base:={local}", f"_mavlink_remote_port_base:={remote}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ros = rosgraph.Master("/test", master_uri=fresh_ros_master.uri)
    wait_until(lambda: ros.hasParam("/ual_ids") and ros.getParam("/ual_ids") == [1], "magna_sim's UAV 1", timeout=60)
    yield local, remote
    assert node.poll() is None, "magna_sim died during the flight"


class SimClock:
    """The vehicle's simulated time (time_boot_ms of its LOCAL_POSITION_NED) and the flight mode of each
    HEARTBEAT with the simulated time it was sent at, both read through MAVSDK's MavlinkDirect plugin."""

    def __init__(self, direct: MavlinkDirect):
        self._lock = threading.Lock()
        self.now_ms = 0
        self.modes: list[tuple[int, str]] = []  # (sim time ms, PX4 mode name), in arrival order
        direct.subscribe_message("LOCAL_POSITION_NED", self._on_position)
        direct.subscribe_message("HEARTBEAT", self._on_heartbeat)

    def _on_position(self, message, _user_data=None) -> None:
        with self._lock:
            self.now_ms = max(self.now_ms, json.loads(message.fields_json)["time_boot_ms"])

    def _on_heartbeat(self, message, _user_data=None) -> None:
        if message.component_id != 1:
            return
        fields = json.loads(message.fields_json)
        mode = autopilot.decode_mode(fields["autopilot"], fields["base_mode"], fields["custom_mode"]).name
        with self._lock:
            self.modes.append((self.now_ms, mode))

    def heard(self) -> int:
        """How many HEARTBEATs have come so far: a mark for first_mode_after."""
        with self._lock:
            return len(self.modes)

    def first_mode_after(self, mark: int, unlike: str) -> tuple[int, str] | None:
        """The first HEARTBEAT after `mark` whose mode is not `unlike`, with its simulated time. Arrival order,
        not time stamps: while the simulation stands still several heartbeats carry the same time."""
        with self._lock:
            return next(((t, m) for t, m in self.modes[mark:] if m != unlike), None)


@pytest.fixture
def mavsdk_system(vehicle_ports):
    """MAVSDK as a ground station listening where the vehicle sends (as for PX4 SITL's 14540)."""
    _, remote = vehicle_ports
    mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        mavsdk.add_any_connection(f"udpin://127.0.0.1:{remote}")
        system = mavsdk.first_autopilot(WAIT)
        assert system is not None, f"MAVSDK found no autopilot on udpin://127.0.0.1:{remote} within {WAIT} s"
        yield system
    finally:
        mavsdk.destroy()  # ends MAVSDK's threads and sockets


def near(a, b, tolerance):
    return abs(a - b) <= tolerance


def test_mavsdk_flies_the_simulated_vehicle_and_its_offboard_rules_hold(mavsdk_system):
    system = mavsdk_system
    telemetry, action, direct = Telemetry(system), Action(system), MavlinkDirect(system)
    clock = SimClock(direct)

    def ned():
        return telemetry.position_velocity_ned().position

    def wait(condition, what, timeout=WAIT):
        wait_until(condition, what, timeout=timeout, poll=0.02)

    # Connected, and healthy as MAVSDK judges a PX4: gyro, accelerometer, magnetometer, local and global
    # position, home position.
    wait(telemetry.health_all_ok, f"health_all_ok (health now: {telemetry.health()})")
    assert system.autopilot_type().name == "PX4"

    # OFFBOARD without set-points: MAVSDK's own check, then the vehicle's answer to the mode command itself.
    offboard = Offboard(system)
    with pytest.raises(OffboardError) as refused:
        offboard.start()
    assert refused.value.result == OffboardResult.NO_SETPOINT_SET
    _, offboard_mode = autopilot.encode_mode(autopilot.PX4, "OFFBOARD")
    ack = direct.send_command(MavlinkMessage(
        message_name="COMMAND_LONG", target_system_id=1, target_component_id=1, fields_json=json.dumps(
            {"target_system": 1, "target_component": 1, "command": 176, "confirmation": 0, "param1": 1.0,
             "param2": float(offboard_mode >> 16), "param3": 0.0, "param4": 0.0, "param5": 0.0, "param6": 0.0,
             "param7": 0.0})))
    assert json.loads(ack.fields_json)["result"] == MAV_RESULT_TEMPORARILY_REJECTED
    assert telemetry.flight_mode() != FlightMode.OFFBOARD

    # Parameters: the take-off altitude is PX4's MIS_TAKEOFF_ALT, read and written over the protocol.
    assert near(action.get_takeoff_altitude(), 2.5, 1e-6)
    action.set_takeoff_altitude(3.0)
    assert near(action.get_takeoff_altitude(), 3.0, 1e-6)

    # Arm and take off to the take-off altitude, then hold.
    action.arm()
    wait(telemetry.armed, "armed")
    action.takeoff()
    wait(lambda: telemetry.flight_mode() == FlightMode.HOLD and near(-ned().down_m, 3.0, 0.2)
         and telemetry.landed_state() == LandedState.IN_AIR, "take-off to 3 m, then HOLD")

    # goto_location: 5 m north of home, 4 m above it, facing east.
    home = telemetry.home()
    start = ned()
    action.goto_location(home.latitude_deg + 5.0 / 111_200.0, home.longitude_deg, home.absolute_altitude_m + 4.0, 90.0)
    wait(lambda: near(ned().north_m, home.local_north_m + 5.0, 0.3) and near(ned().east_m, start.east_m, 0.3)
         and near(-ned().down_m, 4.0, 0.2), f"goto_location (at {ned()})")
    assert telemetry.flight_mode() == FlightMode.HOLD
    wait(lambda: near(telemetry.heading().heading_deg % 360.0, 90.0, 10.0), "heading east")

    # Offboard velocity: 1 m/s east (NED y) moves the vehicle east only.
    start = ned()
    offboard.set_velocity_ned(VelocityNedYaw(0.0, 1.0, 0.0, 90.0))
    offboard.start()
    wait(lambda: telemetry.flight_mode() == FlightMode.OFFBOARD, "OFFBOARD")
    wait(lambda: ned().east_m > start.east_m + 2.0, "2 m east under a velocity set-point")
    assert near(ned().north_m, start.north_m, 0.3) and near(ned().down_m, start.down_m, 0.3)
    assert near(telemetry.velocity_ned().east_m_s, 1.0, 0.15)

    # Then offboard position.
    target = (start.north_m - 2.0, start.east_m + 1.0, -5.0)
    offboard.set_position_ned(PositionNedYaw(*target, 0.0))
    wait(lambda: near(ned().north_m, target[0], 0.2) and near(ned().east_m, target[1], 0.2)
         and near(ned().down_m, target[2], 0.2), f"offboard position {target} (at {ned()})")
    assert telemetry.flight_mode() == FlightMode.OFFBOARD

    # Stop offboard: HOLD where it is.
    offboard.stop()
    wait(lambda: telemetry.flight_mode() == FlightMode.HOLD, "HOLD after offboard.stop()")

    # The stream stops without a word (its plugin goes away): the vehicle leaves OFFBOARD after about
    # COM_OF_LOSS_T = 1 s of simulated time, and holds.
    offboard.set_position_ned(PositionNedYaw(*target, 0.0))
    offboard.start()
    wait(lambda: telemetry.flight_mode() == FlightMode.OFFBOARD, "OFFBOARD again")
    # The stream stops somewhere while destroy() runs, which may take a while on a busy machine: between the
    # simulated times before and after it. The vehicle must leave OFFBOARD about 1 s after that moment.
    mark, before_ms = clock.heard(), clock.now_ms
    offboard.destroy()
    after_ms = clock.now_ms
    wait(lambda: clock.first_mode_after(mark, "OFFBOARD") is not None, "leaving OFFBOARD after the stream stopped")
    left_ms, mode = clock.first_mode_after(mark, "OFFBOARD")
    assert mode == "AUTO.LOITER"
    earliest, latest = (left_ms - after_ms) / 1000.0, (left_ms - before_ms) / 1000.0
    assert latest >= 0.5 and earliest <= 1.6, (f"left OFFBOARD {earliest:.2f} to {latest:.2f} s of simulated time "
                                               f"after the stream stopped (COM_OF_LOSS_T is 1 s)")
    wait(lambda: telemetry.flight_mode() == FlightMode.HOLD, "HOLD as MAVSDK sees it")

    # Land, and the vehicle disarms by itself (COM_DISARM_LAND).
    action.land()
    wait(lambda: telemetry.landed_state() == LandedState.ON_GROUND, "on the ground")
    assert telemetry.armed()
    wait(lambda: not telemetry.armed(), "auto-disarm after landing")
    assert abs(ned().down_m) < 0.1
