"""The magna_sim node: owns the world, /clock and one UAL server per UAV.

One loop thread steps the world at a fixed rate, paced by the real-time
factor; ROS callbacks only queue work for it (see command_queue). Messages are
stamped with simulated time.
"""
from __future__ import annotations

import argparse
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import rospy
from geometry_msgs.msg import TransformStamped
from magna_msgs.msg import CollisionEvent, SwarmState
from magna_msgs.srv import (
    DeleteModel,
    DeleteModelResponse,
    ResetSimulation,
    ResetSimulationResponse,
    SpawnModel,
    SpawnModelResponse,
)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, CameraInfo, Image
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, SetBoolResponse
from tf2_msgs.msg import TFMessage

from magna_common import ros_names as names

from .command_queue import CommandQueue
from .depth_camera import DepthCamera
from .mavlink_endpoint import EndpointError, MavlinkEndpoint
from .mavlink_telemetry import PX4_SITL_HOME
from .mavlink_vehicle import MavlinkVehicle
from .pacing import Hold, Lockstep, Pacer, parse_real_time_factor
from .ros_ual import MAP_FRAME, UalServer, quaternion_yaw, swarm_state
from .streams import stream_publisher
from .ual_logic import UalSettings
from .world import SimWorld, SpawnError

HELP = """\
magna_sim: the pybullet world node. Every UAV is served with the GRVC UAL v3 API
under /uav_{id}/ual/ (pose, velocity, odom, state; set_pose, set_velocity; take_off,
land, go_to_waypoint, go_to_waypoint_geo, set_home, recover_from_manual).

Also: /clock, tf map -> uav_{id}/base_link, /magna/sim/collisions (magna_msgs/CollisionEvent),
/magna/sim/swarm_state (magna_msgs/SwarmState: every simulated UAV's pose and velocity once per
UAL period, the values and stamp of their odom), /uav_{id}/mavros/battery (sensor_msgs/BatteryState),
optional depth images on /uav_{id}/camera/depth/image_raw, and the services /magna/sim/spawn_model,
/magna/sim/delete_model and /magna/sim/pause (std_srvs/SetBool: true pauses, false resumes).
While paused, simulated time stands still; spawning and deleting still work, and /clock
and the UAL topics are re-sent pub_rate times per wall second with the time frozen, so
that nodes starting meanwhile learn the time and the poses.
/magna/sim/reset (magna_msgs/ResetSimulation, a seed) makes the node as it was just started
with ~seed:=seed: every UAV (with its UAL topics and services) and obstacle gone, time back
to 0, paused if ~start_paused, the ~uavs of the start spawned again. For a batch of
simulations on one running simulator.

Private parameters (defaults):
  ~uavs (0)              UAVs 1..N spawned at start, side by side along y near the origin
  ~model (iris)          their airframe (src/magna_common/airframes/<model>.json)
  ~flight_model (light)  light (kinematic) or dynamic (rotor forces); a fixed-wing airframe
                         (plane) always flies fixed_wing (it cannot hover)
  ~spacing (2.0)         metres between the initial UAVs
  ~physics_rate (240)    physics steps per simulated second
  ~real_time_factor (1)  1 = real time, 10 = ten times faster, max (or 0) = as fast as possible
  ~pub_rate (30)         UAL topics and tf per simulated second
  ~clock_rate (100)      /clock messages per simulated second
  ~start_paused (false)  start with simulated time standing still until /magna/sim/pause false
  ~lockstep (true)       never run more than ~lockstep_lead (0.15) simulated s ahead of a UAV
                         manager flying a role (it announces each control step on
                         /magna/uav_{id}/control_step, std_msgs/Float64), nor of a MAVLink client
                         streaming OFFBOARD set-points; one silent for ~lockstep_timeout (1.0) wall s
                         is let go
  ~seed (none)           seed for wind and sensor noise: same seed, same run
  ~noise/position_std (0), ~noise/velocity_std (0), ~wind_std (0, N, dynamic model only)
  ~map_origin_geo ([])   [lat, lon, alt] of the map origin, for go_to_waypoint_geo
  ~battery_rate (1)      BatteryState messages per simulated second
  ~battery_floor (0)     % of charge a battery never falls below (PX4 SITL's SIM_BAT_MIN_PCT; 0: runs empty)
  ~depth_camera/enabled (false), ~depth_camera/width (64), /height (48), /rate (10), /fov (90)
  ~position_th (0.33), ~orientation_th (0.65), ~velocity_timeout (1.0)   UAL thresholds
  ~hold_pose_time (1.0)  s of sim time a UAV must stay within the arrival radius (half of ~position_th,
                         at most the airframe's accepted_target_radius) and half of ~orientation_th of
                         a take-off or waypoint target: then the take-off is FLYING_AUTO and a
                         blocking take_off or go_to_waypoint returns
  ~stuck_time (10)       s of sim time a target may come no nearer before a blocking take_off or
                         go_to_waypoint fails as not reached (0: wait for ever, as a real UAL)
  ~ground_impact_speed (1.0)   ground contacts faster than this (m/s) are collisions
  ~mavlink (false)       the UAVs spawned at start also fly as PX4-like MAVLink vehicles (interface
                         "ual+mavlink"); /magna/sim/spawn_model chooses per UAV (interface "ual",
                         "mavlink" or "ual+mavlink")
  ~mavlink_local_port_base (14580)    UAV i binds UDP base+i-1 and answers whoever sends to it
                                      (a ground station: udpout:127.0.0.1:14580)
  ~mavlink_remote_port_base (14540)   UAV i also sends to 127.0.0.1:base+i-1, where an offboard
                                      API listens (MAVSDK udpin://0.0.0.0:14540), as PX4 SITL

Example: roslaunch magna_sim sim.launch uavs:=3 model:=iris flight_model:=light rtf:=1.0
"""


def parse_cli(argv) -> None:
    """Only --help: everything else comes from ROS parameters."""
    parser = argparse.ArgumentParser(prog="rosrun magna_sim sim", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(argv)


@dataclass
class NodeSettings:
    uavs: int
    model: str
    flight_model: str
    spacing: float
    physics_rate: float
    real_time_factor: float
    pub_rate: float
    clock_rate: float
    battery_rate: float
    seed: int | None
    position_std: float
    velocity_std: float
    wind_std: float
    map_origin_geo: list | None
    camera: dict
    ual: UalSettings
    ground_impact_speed: float
    start_paused: bool = False
    lockstep: bool = True
    lockstep_lead: float = 0.15
    lockstep_timeout: float = 1.0
    battery_floor: float = 0.0  # percent
    mavlink: bool = False  # UAVs spawned at start also expose a PX4-like MAVLink vehicle
    mavlink_local_port_base: int = 14580  # PX4 SITL's ports: UAV i binds base + i - 1 ...
    mavlink_remote_port_base: int = 14540  # ... and sends to 127.0.0.1:base + i - 1

    @classmethod
    def from_params(cls) -> NodeSettings:
        seed = rospy.get_param("~seed", None)
        origin = rospy.get_param("~map_origin_geo", [])
        if origin and (len(origin) != 3 or not all(isinstance(v, (int, float)) for v in origin)):
            raise ValueError(f"~map_origin_geo: {origin!r} must be [lat, lon, alt]")
        settings = cls(
            uavs=int(rospy.get_param("~uavs", 0)), model=rospy.get_param("~model", "iris"),
            flight_model=rospy.get_param("~flight_model", "light"),
            spacing=float(rospy.get_param("~spacing", 2.0)),
            physics_rate=float(rospy.get_param("~physics_rate", 240.0)),
            real_time_factor=parse_real_time_factor(rospy.get_param("~real_time_factor", 1.0)),
            pub_rate=float(rospy.get_param("~pub_rate", 30.0)),
            clock_rate=float(rospy.get_param("~clock_rate", 100.0)),
            battery_rate=float(rospy.get_param("~battery_rate", 1.0)),
            seed=None if seed in (None, "", "none") else int(seed),
            position_std=float(rospy.get_param("~noise/position_std", 0.0)),
            velocity_std=float(rospy.get_param("~noise/velocity_std", 0.0)),
            wind_std=float(rospy.get_param("~wind_std", 0.0)),
            map_origin_geo=[float(v) for v in origin] or None,
            camera={"enabled": bool(rospy.get_param("~depth_camera/enabled", False)),
                    "width": int(rospy.get_param("~depth_camera/width", 64)),
                    "height": int(rospy.get_param("~depth_camera/height", 48)),
                    "rate": float(rospy.get_param("~depth_camera/rate", 10.0)),
                    "fov": float(rospy.get_param("~depth_camera/fov", 90.0))},
            ual=UalSettings(position_th=float(rospy.get_param("~position_th", 0.33)),
                            orientation_th=float(rospy.get_param("~orientation_th", 0.65)),
                            velocity_timeout=float(rospy.get_param("~velocity_timeout", 1.0)),
                            hold_time=float(rospy.get_param("~hold_pose_time", 1.0)),
                            stuck_time=float(rospy.get_param("~stuck_time", 10.0))),
            ground_impact_speed=float(rospy.get_param("~ground_impact_speed", 1.0)),
            start_paused=_as_bool("~start_paused", rospy.get_param("~start_paused", False)),
            lockstep=_as_bool("~lockstep", rospy.get_param("~lockstep", True)),
            lockstep_lead=float(rospy.get_param("~lockstep_lead", 0.15)),
            lockstep_timeout=float(rospy.get_param("~lockstep_timeout", 1.0)),
            battery_floor=float(rospy.get_param("~battery_floor", 0.0)),
            mavlink=_as_bool("~mavlink", rospy.get_param("~mavlink", False)),
            mavlink_local_port_base=int(rospy.get_param("~mavlink_local_port_base", 14580)),
            mavlink_remote_port_base=int(rospy.get_param("~mavlink_remote_port_base", 14540)))
        for name in ("mavlink_local_port_base", "mavlink_remote_port_base"):
            if not 1 <= getattr(settings, name) <= 65535:
                raise ValueError(f"~{name}: {getattr(settings, name)} must be a UDP port (1 to 65535)")
        if not (math.isfinite(settings.battery_floor) and 0.0 <= settings.battery_floor < 100.0):
            raise ValueError(f"~battery_floor: {settings.battery_floor} must be a percentage from 0 to below 100")
        for name in ("physics_rate", "pub_rate", "clock_rate", "battery_rate"):
            value = getattr(settings, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"~{name}: {value} must be a positive rate (per simulated second)")
        for name, value in (("hold_pose_time", settings.ual.hold_time), ("stuck_time", settings.ual.stuck_time)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"~{name}: {value} must be 0 or more seconds of simulated time")
        if settings.uavs < 0:
            raise ValueError(f"~uavs: {settings.uavs} must be 0 or more")
        return settings


INTERFACES = ("ual", "mavlink", "ual+mavlink")
# While time stands still the UAL topics are re-sent so that late subscribers hear them, at ~pub_rate per wall
# second but at most this many UAV readings per wall second in all: ten UAVs keep the full rate, a swarm of 50
# is re-sent at 6 Hz, so its setup (every manager and the ground station connecting) is not drowned in copies.
PAUSED_READINGS_PER_SECOND = 300.0


def _as_bool(name: str, value) -> bool:
    """A boolean parameter given as a bool or as the text true/false (launch files may pass either)."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("true", "1", "yes"):
        return True
    if text in ("false", "0", "no", ""):
        return False
    raise ValueError(f"{name}: {value!r} must be true or false")


def _own_the_clock() -> Callable[[rospy.Time], None] | None:
    """Stop this node from listening to the /clock it publishes; return the setter for its own rospy time.

    With /use_sim_time, rospy subscribes every node to /clock. For the node that publishes it, that
    round trip costs about a fifth of the loop, so it sets rospy's time directly instead.
    Uses rospy internals (rospy.impl.simtime); if they ever change, it keeps the subscription.
    """
    try:
        from rospy.impl import simtime
        from rospy.rostime import _set_rostime
    except ImportError:
        return None
    subscriber = getattr(simtime, "_clock_sub", None)
    if subscriber is None:
        return None
    subscriber.unregister()
    simtime._clock_sub = None
    return _set_rostime


def _ual_served(uav_id: int) -> bool:
    """Whether some node serves the UAL of `uav_id` now (its take_off service is registered)."""
    code, _, _ = rospy.get_master().lookupService(names.ual(uav_id, "take_off"))
    return code == 1  # the master answers -1 when no node provides it


def initial_positions(count: int, spacing: float) -> list[np.ndarray]:
    """UAVs 1..N on a line along y, centred on the origin."""
    return [np.array([0.0, (i - (count - 1) / 2.0) * spacing, 0.0]) for i in range(count)]


class _Schedule:
    """Fires every `period` of simulated time."""

    def __init__(self, rate: float):
        self.period = 1.0 / rate
        self.next = 0.0

    def due(self, now: float) -> bool:
        if now + 1e-9 < self.next:
            return False
        self.next = max(self.next + self.period, now)
        return True


class _Schedules:
    """When each stream of the loop is next due, counted from simulated time 0."""

    def __init__(self, settings: NodeSettings):
        self.clock = _Schedule(settings.clock_rate)
        self.publish = _Schedule(settings.pub_rate)
        self.battery = _Schedule(settings.battery_rate)
        self.camera = _Schedule(settings.camera["rate"]) if settings.camera["enabled"] else None


class SimNode:
    def __init__(self, settings: NodeSettings):
        self.settings = settings
        self.world = SimWorld(settings.physics_rate, settings.seed, settings.wind_std, settings.ual,
                              settings.ground_impact_speed, settings.battery_floor / 100.0)
        self.queue = CommandQueue()
        self.servers: dict[int, UalServer] = {}
        self.cameras: dict[int, tuple[rospy.Publisher, rospy.Publisher]] = {}
        self._clock_pub = stream_publisher("/clock", Clock)
        self._tf_pub = stream_publisher("/tf", TFMessage)
        self._swarm_pub = stream_publisher(names.SIM_SWARM_STATE, SwarmState)
        self._collision_pub = rospy.Publisher(names.SIM_COLLISIONS, CollisionEvent, queue_size=100)
        self._battery_pubs: dict[int, rospy.Publisher] = {}
        self._step_heard = threading.Event()
        self._step_subs: dict[int, rospy.Subscriber] = {}
        self.mavlink: dict[int, tuple[MavlinkEndpoint, MavlinkVehicle]] = {}  # UAVs that speak MAVLink
        self._start_over()
        self._spawn_initial_uavs()
        self._services = [rospy.Service(names.SIM_SPAWN_MODEL, SpawnModel, self._on_spawn),
                          rospy.Service(names.SIM_DELETE_MODEL, DeleteModel, self._on_delete),
                          rospy.Service(names.SIM_PAUSE, SetBool, self._on_pause),
                          rospy.Service(names.SIM_RESET, ResetSimulation, self._on_reset)]

    def _start_over(self) -> None:
        """Everything of a simulation's start besides the world and the UAVs: at start, and again at each reset."""
        settings = self.settings
        self._camera = DepthCamera(self.world.client, settings.camera["width"], settings.camera["height"],
                                   settings.camera["fov"]) if settings.camera["enabled"] else None
        self.lockstep = Lockstep(settings.lockstep_lead, settings.lockstep_timeout) if settings.lockstep else None
        # MAVLink clients streaming OFFBOARD set-points are controllers too: the vehicle drops OFFBOARD after
        # COM_OF_LOSS_T of simulated time, so a simulation far ahead of their wall-clock stream would drop it.
        self._offboard_lockstep = (Lockstep(settings.lockstep_lead, settings.lockstep_timeout)
                                   if settings.lockstep else None)
        self._offboard_heard: dict[int, float | None] = {}  # the set-point time last told to it, per UAV
        self._step_heard.clear()
        self._paused_heartbeat = 0.0  # wall time of the last HEARTBEAT sent while paused
        self.hold = Hold(settings.start_paused)
        self._hold_changes_seen = self.hold.changes  # the loop restarts its pacing when this falls behind
        self._pacer = Pacer(settings.real_time_factor)
        self._schedules = _Schedules(settings)

    def _spawn_initial_uavs(self) -> None:
        settings = self.settings
        interface = "ual+mavlink" if settings.mavlink else "ual"
        for i, position in enumerate(initial_positions(settings.uavs, settings.spacing), start=1):
            self.spawn_uav(f"uav_{i}", i, settings.model, settings.flight_model, position, 0.0, interface=interface)

    def reset(self, seed: int) -> str:
        """Become what a node just started with ~seed:=seed is (run in the loop, between two steps).

        Every UAV goes with its ROS side (UAL server, publishers, subscribers, MAVLink port) so the master keeps
        nothing stale; the world is a new one, not this one cleared (SimWorld.renewed); time, hold, lockstep,
        schedules and pacing start over, and the ~uavs of the start are spawned again."""
        world = self.world.renewed(seed)
        uavs, obstacles = len(self.world.vehicles), len(self.world.obstacles)
        self._forget_every_uav()
        self.queue.release_waiters("interrupted: the simulation was reset")
        old, self.world = self.world, world
        old.close()
        self._start_over()
        try:
            self._spawn_initial_uavs()
        except SpawnError as err:
            raise SpawnError(f"the world was reset, but the UAVs of the start were not spawned again: {err}") from None
        return (f"reset with seed {seed}: {uavs} UAV(s) and {obstacles} obstacle(s) removed, simulated time 0"
                f"{', paused' if self.hold.paused else ''}"
                f"{f', {self.settings.uavs} UAV(s) spawned as at start' if self.settings.uavs else ''}")

    # --- models (simulation thread) --------------------------------------------------------------------------
    def spawn_uav(self, name, uav_id, airframe, flight_model, position, yaw, rgba=(0.2, 0.2, 0.25, 1.0),
                  interface="ual", mavlink_local_port=0, mavlink_remote_port=0, mavlink_origin_geo=()):
        """interface: "ual" (a UAL server), "mavlink" (only the PX4-like MAVLink vehicle: the stand-in for a
        hardware-in-the-loop autopilot, not in /ual_ids) or "ual+mavlink" (both). mavlink_origin_geo: where the
        map origin is on the Earth for the MAVLink vehicle's GPS, when the caller ties the map to it."""
        origin = tuple(float(v) for v in mavlink_origin_geo)
        if origin and (len(origin) != 3 or not all(math.isfinite(v) for v in origin)
                       or not (-90 <= origin[0] <= 90 and -180 <= origin[1] <= 180)):
            raise SpawnError(f"mavlink_origin_geo: {list(origin)} must be [lat, lon, alt] (degrees, degrees, m)")
        interface = interface or "ual"
        if interface not in INTERFACES:
            raise SpawnError(f"interface: '{interface}' must be one of {', '.join(INTERFACES)} (or empty for ual)")
        with_ual, with_mavlink = interface != "mavlink", interface != "ual"
        ids = list(rospy.get_param(names.UAL_IDS, []))
        if with_ual and uav_id in ids and uav_id not in self.servers:
            if _ual_served(uav_id):
                raise SpawnError(f"uav_id: {uav_id} is already in {names.UAL_IDS} (another UAL server has it); "
                                 "pick a free id")
            # Listed by a UAL server that ended without cleaning up (killed): nobody serves it, take it over.
            rospy.logwarn(f"magna_sim: {names.UAL_IDS} lists {uav_id} but no UAL server serves it (one was killed?); "
                          "taking it over")
        if uav_id < 1:
            raise SpawnError(f"uav_id: {uav_id} must be 1 or more (UAL namespaces are /uav_{{id}})")
        vehicle = self.world.spawn_uav(name, uav_id, airframe, flight_model, position, yaw, rgba)
        if with_mavlink:
            try:
                if vehicle.airframe.is_fixed_wing:
                    raise SpawnError(f"interface: '{interface}' flies a multirotor (PX4 QUADROTOR); '{airframe}' is "
                                     "a fixed wing: use interface 'ual'")
                endpoint = self._open_mavlink(uav_id, mavlink_local_port, mavlink_remote_port)
            except SpawnError:
                self.world.delete(name)
                raise
            self.mavlink[uav_id] = (endpoint, self._mavlink_vehicle(vehicle, with_ual, origin))
            rospy.loginfo(f"magna_sim: UAV {uav_id} speaks MAVLink (system {uav_id}) on UDP {endpoint.local_port}, "
                          f"sending to 127.0.0.1:{endpoint.remote[1]}")
        if self.lockstep is not None:
            self._step_subs[uav_id] = rospy.Subscriber(names.manager(uav_id, "control_step"), Float64,
                                                       self._on_control_step, uav_id, queue_size=1, tcp_nodelay=True)
        if not with_ual:  # a stand-in for an autopilot outside the simulator: no UAL, battery or camera topics
            rospy.loginfo(f"magna_sim: spawned {name} (MAVLink only, {airframe}, {flight_model}) "
                          f"at {np.round(vehicle.position, 2).tolist()}")
            return vehicle
        self.servers[uav_id] = UalServer(uav_id, self.world.ual[uav_id], self.queue, self.settings.map_origin_geo)
        self._battery_pubs[uav_id] = rospy.Publisher(names.battery(uav_id), BatteryState, queue_size=1)
        if self._camera is not None:
            self.cameras[uav_id] = (rospy.Publisher(names.depth_camera(uav_id, "image_raw"), Image, queue_size=1),
                                    rospy.Publisher(names.depth_camera(uav_id, "camera_info"), CameraInfo,
                                                    queue_size=1))
        rospy.set_param(names.UAL_IDS, sorted(set(ids) | {uav_id}))
        rospy.loginfo(f"magna_sim: spawned {name} (UAL id {uav_id}, {airframe}, {flight_model}) "
                      f"at {np.round(vehicle.position, 2).tolist()}")
        return vehicle

    def _open_mavlink(self, uav_id: int, local_port: int, remote_port: int) -> MavlinkEndpoint:
        """Bind the UAV's UDP port (PX4 SITL's numbering unless the request names ports)."""
        local = local_port or self.settings.mavlink_local_port_base + uav_id - 1
        remote = remote_port or self.settings.mavlink_remote_port_base + uav_id - 1
        for field, port in (("mavlink_local_port", local), ("mavlink_remote_port", remote)):
            if not 1 <= port <= 65535:
                raise SpawnError(f"{field}: {port} (base + uav_id - 1) is not a UDP port; give the port in the request")
        if uav_id > 255:
            raise SpawnError(f"uav_id: {uav_id} is no MAVLink system id (1 to 255); use interface 'ual'")
        try:
            return MavlinkEndpoint(uav_id, local, remote)
        except EndpointError as err:
            raise SpawnError(str(err)) from None

    def _mavlink_vehicle(self, vehicle, with_ual: bool, origin=()) -> MavlinkVehicle:
        battery = self.world.batteries[vehicle.uav_id]
        origin = origin or self.settings.map_origin_geo or PX4_SITL_HOME
        return MavlinkVehicle(vehicle, vehicle.uav_id, tuple(origin), self.world.time,
                              ual=self.world.ual[vehicle.uav_id] if with_ual else None,
                              battery=lambda: (battery.voltage, battery.percentage))

    def delete(self, name: str) -> str:
        uav_id = next((i for i, v in self.world.vehicles.items() if v.name == name), None)
        kind = self.world.delete(name)
        if uav_id is not None:
            self._forget_uav(uav_id)
        return kind

    def _forget_uav(self, uav_id: int, update_ids: bool = True) -> None:
        if uav_id in self.mavlink:
            self.mavlink.pop(uav_id)[0].close()
            self._offboard_heard.pop(uav_id, None)
            if self._offboard_lockstep is not None:
                self._offboard_lockstep.forget(uav_id)
        if uav_id in self._step_subs:
            self._step_subs.pop(uav_id).unregister()
            assert self.lockstep is not None  # control steps are listened to only for the lockstep
            self.lockstep.forget(uav_id)
        if uav_id not in self.servers:
            return  # MAVLink only: it had no UAL server and was never in /ual_ids
        self.servers.pop(uav_id).shutdown()
        self._battery_pubs.pop(uav_id).unregister()
        for publisher in self.cameras.pop(uav_id, ()):
            publisher.unregister()
        if update_ids:
            rospy.set_param(names.UAL_IDS, [i for i in rospy.get_param(names.UAL_IDS, []) if i != uav_id])

    # --- services (callback threads) -------------------------------------------------------------------------
    def _on_spawn(self, req):
        def spawn():
            pose = req.pose
            position = [pose.position.x, pose.position.y, pose.position.z]
            rgba = (req.color.r, req.color.g, req.color.b, req.color.a or 1.0)
            if req.kind == "uav":
                self.spawn_uav(req.name, int(req.uav_id), req.airframe or self.settings.model,
                               req.flight_model or self.settings.flight_model, position,
                               quaternion_yaw(pose.orientation), rgba, req.interface, req.mavlink_local_port,
                               req.mavlink_remote_port, req.mavlink_origin_geo)
                return f"spawned UAV '{req.name}' as {self._served_as(int(req.uav_id))}"
            if req.kind == "obstacle":
                q = pose.orientation
                orientation = [q.x, q.y, q.z, q.w] if (q.x, q.y, q.z, q.w) != (0, 0, 0, 0) else [0, 0, 0, 1]
                vertices = [[v.x, v.y, v.z] for v in req.vertices] or None
                self.world.spawn_obstacle(req.name, req.shape, list(req.dimensions), vertices, position,
                                          orientation, rgba)
                return f"spawned {req.shape} '{req.name}'"
            raise SpawnError(f"kind: '{req.kind}' must be 'uav' or 'obstacle'")

        return SpawnModelResponse(*self._answer(names.SIM_SPAWN_MODEL, spawn))

    def _served_as(self, uav_id: int) -> str:
        """How clients reach a UAV, for the spawn service's answer."""
        ways = [names.ual(uav_id)] if uav_id in self.servers else []
        if uav_id in self.mavlink:
            endpoint = self.mavlink[uav_id][0]
            ways.append(f"MAVLink system {uav_id} on UDP {endpoint.local_port} "
                        f"(sending to 127.0.0.1:{endpoint.remote[1]})")
        return " and ".join(ways)

    def _on_delete(self, req):
        return DeleteModelResponse(*self._answer(names.SIM_DELETE_MODEL,
                                                 lambda: f"deleted {self.delete(req.name)} '{req.name}'"))

    def _on_control_step(self, msg: Float64, uav_id: int) -> None:
        assert self.lockstep is not None  # subscribed only for the lockstep
        self.lockstep.heard(uav_id, msg.data)
        self._step_heard.set()

    def _on_reset(self, req):
        seed = int(req.seed)
        if seed < 0:
            message = f"seed: {seed} must be 0 or more (as ~seed); nothing was reset"
            rospy.logerr(f"{names.SIM_RESET}: {message}")
            return ResetSimulationResponse(success=False, message=message)
        success, message = self._answer(names.SIM_RESET, lambda: self.reset(seed))
        return ResetSimulationResponse(success=success, message=message if success else f"reset failed: {message}")

    def _on_pause(self, req):
        message = self.hold.set(req.data, self.world.time)
        rospy.loginfo(f"{names.SIM_PAUSE}: {message}")
        return SetBoolResponse(success=True, message=message)

    def _answer(self, service: str, action) -> tuple[bool, str]:
        """Run `action` in the simulation loop; (success, message) for the service's answer, logged under its name."""
        try:
            message = self.queue.run(action)
        except (ValueError, RuntimeError) as err:  # SpawnError, ShapeError, LoopStopped
            rospy.logerr(f"{service}: {err}")
            return False, str(err)
        rospy.loginfo(f"{service}: {message}")
        return True, message

    # --- the loop --------------------------------------------------------------------------------------------
    def spin(self) -> None:
        clock_msg = Clock()
        set_own_time = _own_the_clock()
        try:
            while not rospy.is_shutdown():
                self.queue.run_pending()  # a reset runs here (or in _stand_still): reread everything below
                if self.mavlink:
                    self._serve_mavlink()
                if self.hold.paused:
                    self._stand_still(clock_msg, set_own_time)
                    continue
                if self._hold_changes_seen != self.hold.changes:  # resumed: pace from here, not from before
                    self._hold_changes_seen = self.hold.changes
                    self._pacer.restart()
                if self._behind_a_controller():
                    continue
                contacts = self.world.step()
                self.queue.check_waiters()
                now = self.world.time
                if self.mavlink:
                    self._tick_mavlink(now)
                stamp = rospy.Time.from_sec(now)
                due = self._schedules
                if due.clock.due(now):
                    clock_msg.clock = stamp
                    self._clock_pub.publish(clock_msg)
                    if set_own_time is not None:
                        set_own_time(stamp)
                if due.publish.due(now):
                    self._publish_ual(stamp)
                if due.battery.due(now):
                    self.world.drain_batteries(due.battery.period)
                    self._publish_batteries(stamp)
                if due.camera is not None and due.camera.due(now):
                    self._publish_depth(stamp)
                for contact in contacts:
                    self._publish_contact(contact, stamp)
                self._pacer.wait(now)
        finally:
            self.shutdown()

    def _behind_a_controller(self) -> bool:
        """Wait a little (up to 10 ms) while a UAV manager has not caught up with the next physics step."""
        lockstep, offboard = self.lockstep, self._offboard_lockstep
        if lockstep is None or offboard is None:  # both exist (settings.lockstep) or neither
            return False
        self._step_heard.clear()  # before looking: a step heard after the look still ends the wait
        next_time = self.world.time + self.world.dt
        holding = lockstep.holds(next_time)
        if lockstep.let_go:
            ids, lockstep.let_go = lockstep.let_go, []
            rospy.logwarn(f"magna_sim: the UAV manager(s) of UAV {', '.join(map(str, ids))} went silent for "
                          f"{lockstep.timeout:g} wall s while flying; the simulation goes on without "
                          f"waiting for them")
        if self.mavlink and offboard.holds(next_time):
            holding = True
        if offboard.let_go:
            ids, offboard.let_go = offboard.let_go, []
            rospy.loginfo(f"magna_sim: the OFFBOARD set-points of MAVLink UAV {', '.join(map(str, ids))} stopped "
                          f"for {lockstep.timeout:g} wall s; the simulation goes on without waiting for them")
        if holding:
            self._step_heard.wait(0.01)
        return holding

    def _stand_still(self, clock_msg: Clock, set_own_time) -> None:
        """One wall period of a pause: re-send the frozen time and the poses, carry out commands meanwhile."""
        stamp = rospy.Time.from_sec(self.world.time)
        clock_msg.clock = stamp
        self._clock_pub.publish(clock_msg)
        if set_own_time is not None:
            set_own_time(stamp)
        self._publish_ual(stamp, tf=False)  # tf listeners complain about repeated stamps
        deadline = time.monotonic() + max(1.0 / self.settings.pub_rate,
                                          len(self.servers) / PAUSED_READINGS_PER_SECOND)
        if self.mavlink and time.monotonic() - self._paused_heartbeat >= 1.0:
            self._paused_heartbeat = time.monotonic()  # clients drop a vehicle silent for a few seconds
            for endpoint, vehicle in self.mavlink.values():
                endpoint.send([vehicle.heartbeat()])
        while self.hold.paused and not rospy.is_shutdown() and time.monotonic() < deadline:
            self.queue.run_pending()
            if self.mavlink:
                self._serve_mavlink()
            time.sleep(0.002)

    def _serve_mavlink(self) -> None:
        """Hand what MAVLink clients sent to their vehicles and send the answers (never blocks)."""
        now = self.world.time
        for endpoint, vehicle in self.mavlink.values():
            messages = endpoint.receive()
            if messages:
                answers = []
                for message in messages:
                    answers.extend(vehicle.handle(message, now))
                endpoint.send(answers)
        self._pace_to_offboard_streams()

    def _tick_mavlink(self, now: float) -> None:
        """After a physics step: each MAVLink vehicle flies its mode and sends the telemetry that is due."""
        for endpoint, vehicle in self.mavlink.values():
            endpoint.send(vehicle.tick(now))
        self._pace_to_offboard_streams()

    def _pace_to_offboard_streams(self) -> None:
        """Tell the lockstep about each new OFFBOARD set-point (only new ones: a repeat would look like life)."""
        if self._offboard_lockstep is None:
            return
        for uav_id, (_, vehicle) in self.mavlink.items():
            stamp = vehicle.offboard_set_point_time
            if stamp != self._offboard_heard.get(uav_id):
                self._offboard_heard[uav_id] = stamp
                self._offboard_lockstep.heard(uav_id, -1.0 if stamp is None else stamp)

    def shutdown(self) -> None:
        self.queue.stop("magna_sim is shutting down")
        try:
            self._forget_every_uav()
        except (ConnectionError, OSError):  # the master may already be gone
            pass
        self.world.close()

    def _forget_every_uav(self) -> None:
        served = set(self.servers)
        for uav_id in list(self.servers) + [i for i in self.mavlink if i not in self.servers]:
            self._forget_uav(uav_id, update_ids=False)
        if served:  # once for all: a master round trip each would add up with 50 UAVs
            rospy.set_param(names.UAL_IDS, [i for i in rospy.get_param(names.UAL_IDS, []) if i not in served])

    # --- publishing ------------------------------------------------------------------------------------------
    def _publish_ual(self, stamp, tf: bool = True) -> None:
        """Each UAV's UAL topics and tf, and the swarm's state: the same noisy readings (drawn once) in both."""
        transforms = []
        with_tf = tf and self._tf_pub.get_num_connections() > 0
        readings = self.world.sensor_readings(self.servers, self.settings.position_std, self.settings.velocity_std)
        for uav_id, server in self.servers.items():
            vehicle = self.world.vehicles[uav_id]
            position, velocity = readings[uav_id]
            server.publish(stamp, position, velocity)
            if not with_tf:
                continue
            transform = TransformStamped()
            transform.header.stamp = stamp
            transform.header.frame_id = MAP_FRAME
            transform.child_frame_id = server.base_frame
            t, r = transform.transform.translation, transform.transform.rotation
            t.x, t.y, t.z = vehicle.position
            r.x, r.y, r.z, r.w = vehicle.orientation
            transforms.append(transform)
        if transforms:
            self._tf_pub.publish(TFMessage(transforms=transforms))
        if self._swarm_pub.get_num_connections():
            vehicles = self.world.vehicles
            self._swarm_pub.publish(swarm_state(stamp, [
                (uav_id, position, vehicles[uav_id].orientation, velocity, vehicles[uav_id].angular_velocity,
                 self.servers[uav_id].logic.state)
                for uav_id, (position, velocity) in readings.items()]))

    def _publish_batteries(self, stamp) -> None:
        for uav_id, publisher in self._battery_pubs.items():
            model = self.world.batteries[uav_id]
            msg = BatteryState()
            msg.header.stamp = stamp
            msg.voltage = model.voltage
            msg.current = -model.current  # BatteryState: negative while discharging
            msg.charge = model.charge_ah
            msg.capacity = msg.design_capacity = model.capacity_ah
            msg.percentage = model.percentage
            msg.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
            msg.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LIPO
            msg.present = True
            publisher.publish(msg)

    def _publish_depth(self, stamp) -> None:
        camera = self._camera
        assert camera is not None  # spin publishes depth images only with a camera
        for uav_id, (image_pub, info_pub) in self.cameras.items():
            if image_pub.get_num_connections() == 0 and info_pub.get_num_connections() == 0:
                continue  # rendering is the costly part: skip it when nobody looks
            vehicle = self.world.vehicles[uav_id]
            depth = camera.render(vehicle.position, vehicle.orientation)
            frame = f"uav_{uav_id}/camera_depth_optical_frame"
            image = Image(height=depth.shape[0], width=depth.shape[1], encoding="32FC1", is_bigendian=0,
                          step=depth.shape[1] * 4, data=depth.astype("<f4").tobytes())
            image.header.stamp, image.header.frame_id = stamp, frame
            image_pub.publish(image)
            info = CameraInfo(height=depth.shape[0], width=depth.shape[1], distortion_model="plumb_bob")
            info.header = image.header
            fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
            info.K = [fx, 0, cx, 0, fy, cy, 0, 0, 1]
            info.P = [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]
            info.R = [1, 0, 0, 0, 1, 0, 0, 0, 1]
            info.D = [0.0] * 5
            info_pub.publish(info)

    def _publish_contact(self, contact, stamp) -> None:
        msg = CollisionEvent(agent_id=contact.uav_id, other_kind=contact.other_kind, other_name=contact.other_name,
                             distance=contact.distance, threshold=0.0)
        msg.header.stamp, msg.header.frame_id = stamp, MAP_FRAME
        msg.position.x, msg.position.y, msg.position.z = contact.position
        self._collision_pub.publish(msg)
        rospy.logwarn(f"magna_sim: UAV {contact.uav_id} hit {contact.other_kind} {contact.other_name} "
                      f"at {contact.speed:.2f} m/s")


def main(argv=None) -> int:
    parse_cli(rospy.myargv()[1:] if argv is None else argv)
    rospy.init_node("magna_sim")
    try:
        settings = NodeSettings.from_params()
        node = SimNode(settings)
    except (ValueError, SpawnError) as err:
        rospy.logfatal(f"magna_sim: {err}")
        return 2
    node.spin()
    return 0
