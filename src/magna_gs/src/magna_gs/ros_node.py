"""The ground station node: runs one mission from its JSON file, start to finish.

It loads and checks the mission, builds its state machine (magna_gs.mission) with the
ROS states of magna_gs.factory, and runs it: the world is configured through the world
node, UAVs are spawned in magna_sim at their initial poses with one UAV manager each,
goals go to the managers' action servers. Operators (keyboard, voice) command the running
mission through /magna/gs/command. At the end comes the finishing sequence: data saved,
managers stopped, models and obstacles deleted, the bag closed, the Master told.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import rospy
from geometry_msgs.msg import PoseStamped
from magna_msgs import msg as actions
from magna_msgs.msg import CriticalEvent as CriticalEventMsg
from magna_msgs.msg import NamedValue
from magna_msgs.srv import (
    AddWorldPart,
    AlgorithmControl,
    DeleteModel,
    DeleteWorldPart,
    Die,
    GroundStationCommand,
    GroundStationCommandResponse,
    SimulationTermination,
    SpawnModel,
    StateActualization,
    StateActualizationResponse,
)
from sensor_msgs.msg import BatteryState
from std_msgs.msg import ColorRGBA, Float64, String, UInt32MultiArray
from std_srvs.srv import Trigger, TriggerResponse
from uav_abstraction_layer.msg import State as UalState

from magna_common.files import write_text_atomically
from magna_common.liveness import CHECK_PERIOD, MANAGER_LOST, LivenessWatchdog, LostManager, describe_process
from magna_common.processes import end_parent_launch, end_process_group
from magna_common.records import Hyperparameters
from magna_common.ros_names import (
    GS_COMMAND,
    GS_CONTINUE,
    GS_CRITICAL_EVENT,
    GS_CRITICAL_EVENTS,
    GS_STATE_ACTUALIZATION,
    GS_STOP,
    HYPERPARAMETERS,
    MASTER_TERMINATION,
    SIM_DELETE_MODEL,
    SIM_SPAWN_MODEL,
    WORLD_ADD,
    WORLD_BOUNDARIES,
    WORLD_DELETE,
    battery,
    manager,
    manager_alive,
    ual,
)
from magna_common.warm_start import WarmStarter
from magna_common.workspace import node_script
from magna_gs.bag_recorder import BagRecorder, mission_topics
from magna_gs.command_goals import CommandGoals, refusal_message
from magna_gs.commands import CommandPlan, CommandRefused, Param, UavStatus, plan_command
from magna_gs.critical_events import CriticalEvent, describe_all
from magna_gs.factory import ActionClients, RosStateFactory, wait_sim_seconds, world_poses
from magna_gs.mavlink_uavs import MavlinkUavError, MavlinkUavs
from magna_gs.mission.build import build_machine
from magna_gs.mission.loader import MissionError, load_mission
from magna_gs.sim_pause import SimulationPause
from magna_gs.utm import choose_plan, mission_uses_utm
from magna_gs.utm_client import UtmLink
from magna_gs.verdict import FailedActions, judge_actions
from magna_mavlink.fleet import FleetError, check_against_mission, load_fleet, mavlink_uavs
from magna_sm.introspection import IntrospectionServer
from magna_uav.host import describe_hosted, ended_topic, host_groups, manager_node_name

HELP = """\
The ground station: runs one mission (ROS-MAGNA mission JSON, current or legacy schema).

Needs magna_sim, the world node (magna_worlds) and, for ORCA-3D, orca3d_server running;
`roslaunch magna_gs simulation.launch mission_file:=... world:=... subworld:=...` starts
them all. UAV managers are started by the mission's spawn_agents state: with ~managers host (the
default), host processes (rosrun magna_uav uav_manager_host, ~managers_per_host each) run the managers
of every UAV whose agent_manager_on_gs is true, a thread each, and a UAV with it false gets a standalone uav_manager
(its companion computer's case); with ~managers process every UAV gets a standalone uav_manager.

Services: /magna/gs/state_actualization (StateActualization, from the UAV managers)
          /magna/gs/command (GroundStationCommand: take_off, land, move, turn, follow, get,
                             set algorithm, mission standby/resume/critical; every request checked)
          /magna/gs/stop (std_srvs/Trigger: end the mission now, then finish as usual)
          /magna/gs/continue (std_srvs/Trigger: the operator's button for `wait` states)
Topics:   /magna/gs/critical_event (std_msgs/String) to every UAV manager
          /magna/gs/critical_events (magna_msgs/CriticalEvent): each critical event as the ground station
          records it (a manager's collision or low battery, a link or a manager lost), for operators' screens
          /magna/uav_{id}/alive (std_msgs/Float64) from each manager: its heartbeat. A manager silent
          for 0.6 simulated s whose process is gone or stopped, or whose host's thread has ended
          (/uav_manager_host[_k]/ended), is lost (magna_common.liveness): a critical event names it, and its
          goals end at once (see magna_gs's README)
Machine:  /magna/sm/mission/structure|status (magna_sm introspection)
At the end: /magna/master/simulation_termination (SimulationTermination) when a Master serves it,
            with the critical events and their simulated times.

Private parameters (defaults):
  ~mission_file (required)   the mission JSON
  ~data_dir ("")             where the simulation's files go (CSVs, mission.json, bag); "" = no files
  ~save_data (true)          CSVs of the UAV managers at the end
  ~bag (true)                record simulation.bag (tf, markers, UAV poses, the machine's status)
  ~control_rate (10.0)       control rate of the UAV managers it starts
  ~manager_output (log)      where the managers' output goes: log or screen
  ~managers (host)           host: the managers of the UAVs with agent_manager_on_gs in host processes, a
                             thread each; process: one process per manager
  ~managers_per_host (10)    at most this many managers per host process, shared out evenly (50 UAVs: five
                             hosts uav_manager_host_1..5 of 10; up to 10: one, uav_manager_host); 0: one host
  ~button_timeout (0)        s of sim time after which a wait for the operator's button goes on; 0: never
  ~utm_plan ("")             a UTM plan file (JSON); with it, or when the mission flies "from utm", the
                             ground station starts the UTM node (rosrun magna_gs utm)
  ~fleet_file ("")           the fleet file (YAML) of the mission's hil and real UAVs: for each, where its
                             autopilot is; the ground station starts one ual_mavlink bridge per UAV (see
                             magna_mavlink's README). Needed when the mission has hil or real UAVs.
  ~teardown (true)           delete the UAVs and the world at the end; false when a batch's persistent
                             stack resets the simulator and the world itself
"""

SUCCESS_OUTCOMES = ("completed", "succeeded", "success", "mission_completed", "finished")
BAG_WAIT = 15.0  # wall seconds for the bag to connect to the UAVs' topics
MANAGER_MODES = ("host", "process")
# Managers per host process: a host's managers share one Python interpreter's lock, so a big swarm's are
# split among several hosts, which the OS runs on every core.
DEFAULT_MANAGERS_PER_HOST = 10
SAVE_WORKERS = 16  # save_csv goals in flight at once at the end
HOST_MODULES = ("magna_uav.host_node",)  # what a warm manager host has imported before it is wanted


def clear_private_params(node_name: str) -> None:
    """Delete the private parameters of a node we are about to start (as roslaunch's clear_params does):
    what an earlier run gave it on this master (a manager's ~data_dir, ...) must not reach this run's."""
    namespace = "/" + node_name.strip("/")
    if rospy.has_param(namespace):
        rospy.delete_param(namespace)


class GroundStationServices:
    """What the mission's states act through: world node, simulator, UAV managers, pause, bag."""

    def __init__(self, mission, mission_file: Path, data_dir: Path | None, save_data: bool, control_rate: float,
                 manager_output: str, button_timeout: float = 0.0, bag: BagRecorder | None = None,
                 managers: str = "host", managers_per_host: int = DEFAULT_MANAGERS_PER_HOST):
        if managers not in MANAGER_MODES:
            raise MissionError(f"~managers is {managers!r}: give host (the managers of the ground station's UAVs in "
                               f"one process) or process (one process each)")
        if managers_per_host < 0:
            raise MissionError(f"~managers_per_host is {managers_per_host}: give a positive number of managers per "
                               f"host process (0: all in one)")
        self.manager_mode, self.managers_per_host = managers, managers_per_host
        self.mission, self.mission_file = mission, mission_file
        self.data_dir, self.save_data = data_dir, save_data
        self.control_rate, self.manager_output = control_rate, manager_output
        self.button_timeout = button_timeout
        self.paused = threading.Event()
        self.resumed = threading.Condition()
        self.button = threading.Event()
        self.clients = ActionClients()
        self.world_parts: list[str] = []
        self.spawned: list[int] = []
        self.managers: dict[int, subprocess.Popen] = {}  # each UAV's manager process (a host's is shared)
        self.hosted: set[int] = set()  # the UAVs whose manager runs in a host
        self._ended_in: dict[str, set[int]] = {}  # by host: its managers whose thread has ended, as it says
        self._host_ended_subs: list[rospy.Subscriber] = []
        self.configs = {c.id: c for c in mission.agents}
        self.sim_pause = SimulationPause()
        self.bag = bag
        self.utm: UtmLink | None = None  # the UTM's flight plans, when the mission flies them
        self.utm_process: subprocess.Popen | None = None
        self.mavlink: MavlinkUavs | None = None  # the bridges of the hil and real UAVs, when there are any
        self.setup_errors: list[str] = []  # why the mission could not start (a MAVLink vehicle not there)
        self.failed_actions = FailedActions()  # every action that ended aborted, with why (the states add them)
        self.liveness = LivenessWatchdog(self._probe_manager)  # the managers' heartbeats
        # The first manager host imports while the mission sets up (the world, the UAVs): one warm process, made
        # for output to the log only (on screen it would have to be ours from the start).
        self.host_starter: WarmStarter | None = None
        if manager_output != "screen" and any(self._hosts(c) for c in mission.agents):
            self.host_starter = WarmStarter(node_script("magna_uav", "uav_manager_host"), HOST_MODULES)
            self.host_starter.prepare()

    def running_wall(self) -> float:
        """A wall clock (s) that stops while we hold the simulator still: a manager's silence while time stands
        still is no silence (a swarm's setup can keep the first UAVs' managers waiting for minutes)."""
        return time.monotonic() - self.sim_pause.still_wall_now()

    @property
    def host_ended(self) -> set[int]:
        """Hosted managers whose thread has ended, as their hosts say."""
        return set().union(*self._ended_in.values())

    def _probe_manager(self, uav_id: int) -> str | None:
        process = self.managers.get(uav_id)
        if process is None:
            return None
        if uav_id in self.hosted:
            return describe_hosted(uav_id, describe_process(process), self.host_ended)
        return describe_process(process)

    def lost_manager(self, uav_id: int) -> LostManager | None:
        """The loss of this UAV's manager, once the watchdog noticed it (its goals then end at once)."""
        return self.liveness.lost(uav_id)

    # --- helpers the states use ------------------------------------------------------------
    def action_client(self, uav_id: int, action: str):
        """The client of one manager's action; simulated time runs from here on (see sim_pause)."""
        self.sim_pause.run()
        return self.clients.get(uav_id, action)

    def wait_while_paused(self, stop) -> bool:
        while self.paused.is_set():
            if stop() or rospy.is_shutdown():
                return False
            time.sleep(0.05)
        return True

    def resolve_poses(self, definition: list) -> list[tuple[np.ndarray, np.ndarray]]:
        return world_poses(definition)

    def csv_path(self, uav_id: int) -> Path | str:
        return self.data_dir / f"uav_{uav_id}.csv" if self.data_dir else ""

    # --- callback states ----------------------------------------------------------------------
    def world_config(self, action: str, world_id, definition) -> bool:
        """spawn: the world node is the world (make sure it is up; add what comes with it);
        add: a part from the hyperparameters' world or inline volumes; delete: every part added."""
        self.sim_pause.stand_still()
        return self._world_config(action, world_id, definition)

    def _world_config(self, action: str, world_id, definition) -> bool:
        rospy.wait_for_service(WORLD_ADD, timeout=30.0)
        if action == "spawn" and definition is None:
            return True
        if action in ("spawn", "add"):
            part = f"world_{world_id or 'main'}_part_{len(self.world_parts)}"
            if definition is None or definition.from_hyperparameters:
                text = "from_hyperparameters"
            else:
                text = json.dumps(list(definition.volumes))  # a bare list of volumes: inline, as missions write it
            answer = rospy.ServiceProxy(WORLD_ADD, AddWorldPart)(id=part, world="", subworld="",
                                                                          definition_json=text)
            if not answer.success:
                rospy.logerr(f"world_config add: {answer.message}")
                return False
            self.world_parts.append(part)
            return True
        if action == "delete":
            return self.delete_world()
        rospy.logerr(f"world_config action {action!r} is unknown: spawn, add or delete")
        return False

    def delete_world(self) -> bool:
        ok = True
        delete = rospy.ServiceProxy(WORLD_DELETE, DeleteWorldPart)
        for part in list(self.world_parts):
            try:
                answer = delete(id=part)
                ok = ok and answer.success
            except rospy.ServiceException as error:
                rospy.logwarn(f"delete world part {part}: {error}")
                ok = False
            self.world_parts.remove(part)
        return ok

    def wait(self, exit_type: str, duration: float, state) -> bool:
        with self.sim_pause.time_needed():
            return self._wait(exit_type, duration, state)

    def _wait(self, exit_type: str, duration: float, state) -> bool:
        if exit_type == "button":
            self.button.clear()
            limit = f", or {self.button_timeout:g} s" if self.button_timeout > 0 else ""
            rospy.loginfo(f"mission waits for the operator: rosservice call /magna/gs/continue{limit}")
            deadline = rospy.get_time() + self.button_timeout if self.button_timeout > 0 else float("inf")
            while not self.button.wait(0.05):
                if state.preempt_requested() or rospy.is_shutdown():
                    return False
                if rospy.get_time() >= deadline:
                    rospy.loginfo("nobody pressed the button: the mission goes on (~button_timeout)")
                    return True
            return True
        return wait_sim_seconds(duration, state.preempt_requested)

    def spawn_agents(self, initial_poses) -> bool:
        """Spawn every UAV at its initial pose and start its manager; time stands still until all are ready."""
        self.sim_pause.stand_still()
        return self._spawn_agents(initial_poses)

    def _spawn_agents(self, initial_poses) -> bool:
        agents = self.mission.agents
        if len(initial_poses) < len(agents):
            rospy.logerr(f"spawn_agents: {len(initial_poses)} initial poses for {len(agents)} agents")
            return False
        rospy.wait_for_service(SIM_SPAWN_MODEL, timeout=30.0)
        spawn = rospy.ServiceProxy(SIM_SPAWN_MODEL, SpawnModel)
        placed = list(zip(agents, initial_poses, strict=False))
        # MAVLink UAVs first: a vehicle that is not there stops the mission before anything flies.
        placed.sort(key=lambda item: not (self.mavlink is not None and self.mavlink.flies(item[0].id)))
        for config, definition in placed:
            yaw = float(definition.yaw or 0.0)
            poses = self.resolve_poses(definition.as_list()[:4])
            position = poses[0][0]
            pose = PoseStamped().pose
            pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
            pose.orientation.z, pose.orientation.w = np.sin(yaw / 2), np.cos(yaw / 2)
            r, g, b, a = config.marker_rgba
            request = {"name": f"uav_{config.id}", "kind": "uav", "pose": pose, "color": ColorRGBA(r, g, b, a),
                       "uav_id": config.id, "airframe": config.model, "flight_model": "light"}
            if self.mavlink is not None and self.mavlink.flies(config.id):
                if not self._bring_up(self.mavlink, config.id, spawn, request):
                    return False
            else:
                answer = spawn(**request)
                if not answer.success:
                    rospy.logerr(f"spawn_agents: UAV {config.id}: {answer.message}")
                    return False
                self.spawned.append(config.id)
            if not self._hosts(config):
                self._start_manager(config.id)
        self._start_host([c.id for c in agents if self._hosts(c)])
        for config in agents:  # each manager is ready when its action servers answer
            self.clients.get(config.id, "take_off")
            self.liveness.watch(config.id, rospy.get_time(), self.running_wall())
        self._wait_for_the_bag()
        return True

    def _bring_up(self, mavlink: MavlinkUavs, uav_id: int, spawn, request: dict) -> bool:
        """Start the bridge of a hil or real UAV (its stand-in first, when it has one); False if it is not there."""
        def spawn_stand_in(local_port: int, remote_port: int) -> None:
            assert mavlink.origin is not None  # bring_up ties the origin before it spawns a stand-in
            answer = spawn(interface="mavlink", mavlink_local_port=local_port, mavlink_remote_port=remote_port,
                           mavlink_origin_geo=list(mavlink.origin), **request)
            if not answer.success:
                raise MavlinkUavError(f"UAV {uav_id}: magna_sim refused its PX4-like stand-in: {answer.message}")
            self.spawned.append(uav_id)

        try:
            with self.sim_pause.time_needed():  # a stand-in's autopilot runs on simulated time
                mavlink.bring_up(uav_id, spawn_stand_in)
        except MavlinkUavError as error:
            self.setup_errors.append(str(error))
            rospy.logerr(f"spawn_agents: {error}")
            return False
        return True

    def stop_bridges(self) -> None:
        if self.mavlink is not None:
            self.mavlink.stop()

    def _wait_for_the_bag(self) -> None:
        """Let the bag connect to the new UAVs' topics while time stands still, so it misses no take-off."""
        if self.bag is None:
            return
        flying = [c.id for c in self.mission.agents]  # spawned in magna_sim or reached through a bridge
        topics = [ual(i, name) for i in flying for name in ("pose", "velocity")]
        missing = self.bag.wait_listening(topics, timeout=BAG_WAIT)
        if missing:
            rospy.logwarn(f"the bag is not recording {', '.join(missing)} after {BAG_WAIT:.0f} s; it will miss "
                          f"their first messages")

    def _hosts(self, config) -> bool:
        """Whether this UAV's manager runs in the host: host mode, and a manager on the ground station."""
        return self.manager_mode == "host" and bool(config.manager_on_gs)

    def _manager_params(self, uav_id: int) -> dict[str, object]:
        """The private parameters of a UAV's manager, standalone or hosted (the host reads them at the same place)."""
        params: dict[str, object] = {"id": uav_id, "mission_file": str(self.mission_file),
                                     "control_rate": float(self.control_rate)}
        if self.data_dir:
            params["data_dir"] = str(self.data_dir)
            if self.save_data:  # its rows reach the CSV as it flies: a manager that dies leaves them
                params["csv_stream"] = str(self.csv_path(uav_id))
        return params

    def _start_manager(self, uav_id: int) -> None:
        node = manager_node_name(uav_id)
        clear_private_params(node)
        params = self._manager_params(uav_id)
        command = ["rosrun", "magna_uav", "uav_manager", f"__name:={node}", *(f"_{k}:={v}" for k, v in params.items())]
        output = self._child_output()
        self.managers[uav_id] = subprocess.Popen(command, start_new_session=True, stdout=output, stderr=output)

    def _start_host(self, ids: list[int]) -> None:
        """Processes for the managers of `ids` (~managers_per_host each), each manager reading the parameters its
        standalone node would have."""
        for host_name, group in host_groups(ids, self.managers_per_host):
            clear_private_params(host_name)
            for uav_id in group:
                node = manager_node_name(uav_id)
                clear_private_params(node)
                for key, value in self._manager_params(uav_id).items():
                    rospy.set_param(f"/{node}/{key}", value)
            rospy.set_param(f"/{host_name}/ids", list(group))
            self.hosted |= set(group)
            self._ended_in[host_name] = set()
            self._host_ended_subs.append(rospy.Subscriber(ended_topic(host_name), UInt32MultiArray,
                                                          self._on_host_ended, callback_args=(host_name, set(group)),
                                                          queue_size=10))
            if self.host_starter is not None:  # warm if it can; the output to the log, which is nowhere
                host = self.host_starter.start([sys.executable, self.host_starter.script, f"__name:={host_name}"],
                                               Path(os.devnull))
                self.host_starter.close()  # one warm host: a swarm's others start cold
                self.host_starter = None
            else:
                output = self._child_output()
                host = subprocess.Popen(["rosrun", "magna_uav", "uav_manager_host", f"__name:={host_name}"],
                                        start_new_session=True, stdout=output, stderr=output)
            for uav_id in group:
                self.managers[uav_id] = host

    def _on_host_ended(self, msg: UInt32MultiArray, host: tuple[str, set[int]]) -> None:
        name, group = host
        self._ended_in[name] = {int(i) for i in msg.data} & group

    def start_utm(self, plan_file: str) -> None:
        """The UTM node for this mission, and the link that hears its plans."""
        self.utm = UtmLink([c.id for c in self.mission.agents])
        clear_private_params("utm")
        command = ["rosrun", "magna_gs", "utm", "__name:=utm", f"_mission_file:={self.mission_file}",
                   f"_plan_file:={plan_file}"]
        output = self._child_output()
        self.utm_process = subprocess.Popen(command, start_new_session=True, stdout=output, stderr=output)

    def _child_output(self) -> int | None:
        """Where a manager's or the UTM's stdout and stderr go: ours (None) on screen, else nowhere."""
        return None if self.manager_output == "screen" else subprocess.DEVNULL

    def stop_utm(self) -> None:
        if self.utm_process is not None:
            end_process_group(self.utm_process)
            self.utm_process = None

    def algorithm_control(self, ids, name, action, params, values, text_value: str = "") -> bool:
        self.sim_pause.run()  # a service call: it needs no time, only managers that are not held
        ok = True
        for uav_id in ids:
            service = manager(uav_id, "algorithm_control")
            rospy.wait_for_service(service, timeout=30.0)
            answer = rospy.ServiceProxy(service, AlgorithmControl)(name=name, action=action, params=params,
                                                                   values=[float(v) for v in values],
                                                                   text_value=text_value)
            if not answer.success:
                rospy.logerr(f"algorithm_control UAV {uav_id}: {answer.message}")
                ok = False
        return ok

    def save_csv(self, ids) -> bool:
        with self.sim_pause.time_needed():  # the managers' save_csv actions run in simulated time
            return self._save_csv(ids)

    def _save_csv(self, ids) -> bool:
        """Every UAV's manager saves its CSV, all at once (50 one after the other took most of a minute)."""
        if not self.save_data or not self.data_dir:
            return True
        ids = list(ids)
        if not ids:
            return True
        with ThreadPoolExecutor(max_workers=min(SAVE_WORKERS, len(ids)), thread_name_prefix="save_csv") as pool:
            return all(list(pool.map(self._save_one_csv, ids)))

    def _save_one_csv(self, uav_id: int) -> bool:
        if self.lost_manager(uav_id) is not None:
            rospy.logerr(f"save_csv UAV {uav_id}: its manager is lost; {self.csv_path(uav_id)} holds the rows it "
                         f"streamed until then")
            return False
        client = self.clients.get(uav_id, "save_csv")
        client.send_goal(actions.SaveCSVGoal(path=str(self.csv_path(uav_id))))
        client.wait_for_result(rospy.Duration(30.0))
        result = client.get_result()
        if result is None or result.outcome != "succeeded":
            rospy.logerr(f"save_csv UAV {uav_id}: {getattr(result, 'message', 'no answer')}")
            return False
        return True

    # --- the end --------------------------------------------------------------------------
    def stop_managers(self, grace: float = 10.0) -> None:
        self.liveness.stop()  # they stop on purpose now
        if self.host_starter is not None:  # prepared for a host that never started
            self.host_starter.close()
            self.host_starter = None
        lost_ids = {uav_id for uav_id in self.managers if self.lost_manager(uav_id) is not None}
        running = {process.pid for uav_id, process in self.managers.items() if uav_id not in lost_ids}
        ended: set[int] = set()  # processes ended here (a host's pid once)
        for uav_id, process in list(self.managers.items()):
            lost = uav_id in lost_ids
            if lost and uav_id in self.hosted and process.pid in running:  # its thread has ended; the others run on
                continue
            if lost:  # dead or frozen (a host whose managers are all lost, the same): nothing to ask it
                if process.pid not in ended:
                    end_process_group(process, grace=0.2)
                    ended.add(process.pid)
                continue
            try:
                rospy.wait_for_service(manager(uav_id, "die"), timeout=2.0)
                rospy.ServiceProxy(manager(uav_id, "die"), Die)(save_data=False)
            except (rospy.ROSException, rospy.ServiceException):
                pass
        deadline = time.monotonic() + grace
        for process in {p.pid: p for p in self.managers.values()}.values():  # the host once
            try:
                process.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                end_process_group(process)
        self.managers.clear()
        for subscriber in self._host_ended_subs:
            subscriber.unregister()
        self._host_ended_subs = []
        self.clients.stop()

    def delete_uavs(self) -> None:
        try:
            rospy.wait_for_service(SIM_DELETE_MODEL, timeout=2.0)
        except rospy.ROSException:
            return
        delete = rospy.ServiceProxy(SIM_DELETE_MODEL, DeleteModel)
        for uav_id in self.spawned:
            try:
                delete(name=f"uav_{uav_id}")
            except rospy.ServiceException as error:
                rospy.logwarn(f"delete uav_{uav_id}: {error}")
        self.spawned.clear()


class GroundStation:
    def __init__(self):
        hyper = Hyperparameters.from_param(rospy.get_param(HYPERPARAMETERS, None))
        mission_file = rospy.get_param("~mission_file", "")
        if not mission_file:
            raise MissionError("~mission_file is missing: give the mission JSON, e.g. _mission_file:=missions/x.json")
        self.mission_file = Path(mission_file).expanduser().resolve()
        loaded = load_mission(self.mission_file)
        self.mission, self.changes = loaded.mission, loaded.changes
        for change in self.changes:
            rospy.loginfo(f"mission migrated: {change}")
        data_dir = rospy.get_param("~data_dir", "")  # the Master's simulation folder (simulation.launch data_dir)
        self.data_dir = Path(data_dir).expanduser() if data_dir else None
        if self.data_dir:
            self.data_dir.mkdir(parents=True, exist_ok=True)
        self.save_data = bool(rospy.get_param("~save_data", hyper.save_data))
        # false when a persistent stack (the batch's) resets the simulator and the world after the mission
        self.teardown = bool(rospy.get_param("~teardown", True))
        record = self.data_dir and rospy.get_param("~bag", hyper.save_bag)
        self.bag = (BagRecorder(self.data_dir / "simulation.bag", mission_topics(c.id for c in self.mission.agents))
                    if record else None)
        self.services = GroundStationServices(self.mission, self.mission_file, self.data_dir, self.save_data,
                                              float(rospy.get_param("~control_rate", 10.0)),
                                              rospy.get_param("~manager_output", "log"),
                                              float(rospy.get_param("~button_timeout", 0.0)), self.bag,
                                              str(rospy.get_param("~managers", "host")),
                                              int(rospy.get_param("~managers_per_host", DEFAULT_MANAGERS_PER_HOST)))
        # What a link-lost callback of the fleet's bridges touches exists before the fleet is loaded.
        self.statuses: dict[int, dict] = {c.id: {} for c in self.mission.agents}
        self.critical_events: list[CriticalEvent] = []
        self.lock = threading.Lock()
        self.critical = rospy.Publisher(GS_CRITICAL_EVENT, String, queue_size=1, latch=True)
        self.events = rospy.Publisher(GS_CRITICAL_EVENTS, CriticalEventMsg, queue_size=100)
        self._start_utm()
        self._load_fleet()
        self.machine = build_machine(self.mission, RosStateFactory(self.services))
        self.introspection = IntrospectionServer("mission", self.machine)
        for config in self.mission.agents:
            rospy.Subscriber(ual(config.id, "pose"), PoseStamped, self._on_pose, config.id, queue_size=1)
            rospy.Subscriber(ual(config.id, "state"), UalState, self._on_ual_state, config.id, queue_size=1)
            rospy.Subscriber(battery(config.id), BatteryState, self._on_battery, config.id,
                             queue_size=1)
            rospy.Subscriber(manager_alive(config.id), Float64, self._on_beat, config.id, queue_size=1,
                             tcp_nodelay=True)
        self.liveness_timer = rospy.Timer(rospy.Duration(CHECK_PERIOD), self._check_liveness)
        self.service_handles = [
            rospy.Service(GS_STATE_ACTUALIZATION, StateActualization, self._on_state),
            rospy.Service(GS_COMMAND, GroundStationCommand, self._on_command),
            rospy.Service(GS_STOP, Trigger, self._on_stop),
            rospy.Service(GS_CONTINUE, Trigger, self._on_continue),
        ]

    def _load_fleet(self) -> None:
        """The fleet of the hil and real UAVs; a missing or unfitting fleet stops us here (exit 2)."""
        modes = {c.id: c.mode for c in self.mission.agents}
        flown = mavlink_uavs(modes)
        fleet_file = rospy.get_param("~fleet_file", "")
        if not flown:
            if fleet_file:
                rospy.logwarn(f"{fleet_file}: not used: every UAV of {self.mission_file.name} is sitl")
            return
        if not fleet_file:
            raise MissionError(f"{self.mission_file}: Agents_Config: UAVs {flown} are hil or real; say where their "
                               f"autopilots are in a fleet file: magna run --fleet FILE (or _fleet_file:=FILE), "
                               f"see magna_mavlink's README, 'The fleet file'")
        try:
            fleet = load_fleet(Path(fleet_file).expanduser())
        except FleetError as error:
            raise MissionError(str(error)) from None
        problems = check_against_mission(fleet, modes)
        if problems:
            raise MissionError("; ".join(problems))
        rospy.loginfo(f"MAVLink UAVs {flown} from {fleet.source}")
        mavlink = MavlinkUavs(fleet, modes, rospy.get_param("~manager_output", "log"))
        mavlink.on_link_lost = self._on_link_lost
        self.services.mavlink = mavlink

    def _on_link_lost(self, uav_id: int, text: str) -> None:
        """A bridge lost its vehicle in flight: a critical event for every UAV, so the mission takes its safety
        branch (the lost UAV's own autopilot holds or lands by its failsafe)."""
        rospy.logerr(f"UAV {uav_id}: MAVLink link lost: {text}")
        self._record(CriticalEvent(uav_id, "link_lost", rospy.get_time(), text))
        self.critical.publish(String(f"UAV {uav_id} MAVLink link lost: {text}"))

    def _on_beat(self, msg: Float64, uav_id: int) -> None:
        self.services.liveness.heard(uav_id, msg.data, self.services.running_wall())

    def _check_liveness(self, _event) -> None:
        for lost in self.services.liveness.check(rospy.get_time(), self.services.running_wall()):
            self._on_manager_lost(lost)

    def _on_manager_lost(self, lost: LostManager) -> None:
        """A manager died or froze: a critical event for every UAV, so the mission takes its safety branch; the
        lost UAV's goals end at once (factory.MissionActionState) instead of waiting for an answer."""
        rospy.logerr(lost.describe())
        self._record(CriticalEvent(lost.uav_id, MANAGER_LOST, lost.noticed_at, lost.cause))
        self.critical.publish(String(lost.describe()))

    def _start_utm(self) -> None:
        """Start the UTM when the run names a plan or the mission flies UTM plans; a bad plan stops us here."""
        plan_file = rospy.get_param("~utm_plan", "")
        plan_file = str(Path(plan_file).expanduser().resolve()) if plan_file else ""
        data = json.loads(self.mission_file.read_text())
        if not plan_file and not mission_uses_utm(data):
            return
        plan, warning = choose_plan(plan_file, data, self.mission_file)  # UtmPlanError: the node exits with 2
        if warning:
            rospy.logwarn(warning)
        rospy.loginfo(f"UTM: {len(plan.issues)} flight plans from {plan.source}")
        self.services.start_utm(plan_file)

    # --- what the ground station hears -----------------------------------------------------
    def _on_pose(self, msg, uav_id):
        p, q = msg.pose.position, msg.pose.orientation
        with self.lock:
            self.statuses[uav_id]["position"] = np.array([p.x, p.y, p.z])
            self.statuses[uav_id]["yaw"] = float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y ** 2 + q.z ** 2)))

    def _on_ual_state(self, msg, uav_id):
        with self.lock:
            self.statuses[uav_id]["ual_state"] = msg.state

    def _on_battery(self, msg, uav_id):
        with self.lock:
            self.statuses[uav_id]["battery"] = msg.percentage

    def _on_state(self, req):
        with self.lock:
            if req.id not in self.statuses:
                return StateActualizationResponse(False, f"UAV {req.id} is not in this mission")
            self.statuses[req.id]["state"] = req.state
        if req.critical_event:
            self._record(CriticalEvent(req.id, req.critical_event, rospy.get_time(), req.state))
            rospy.logwarn(f"UAV {req.id}: {req.critical_event} ({req.state})")
        return StateActualizationResponse(True, "")

    def _record(self, event: CriticalEvent) -> None:
        """Keep a critical event for result.json, and say it at once on /magna/gs/critical_events (the studio)."""
        with self.lock:
            self.critical_events.append(event)
        self.events.publish(CriticalEventMsg(uav_id=event.uav_id, event=event.event, sim_time=event.sim_time,
                                             detail=event.detail))

    def uav_statuses(self) -> dict[int, UavStatus]:
        mavlink = self.services.mavlink
        with self.lock:
            return {i: UavStatus(i, s.get("position"), s.get("yaw", 0.0), s.get("state", ""), s.get("ual_state", 0),
                                 s.get("battery", float("nan")), mavlink is not None and mavlink.arms_itself(i))
                    for i, s in self.statuses.items()}

    # --- operators ------------------------------------------------------------------------
    def _on_command(self, req):
        """Plan the command (refused with the reason when the ground station sees it cannot be done), carry it out,
        and give the action goals a moment (command_goals.WAIT wall s at most): one a manager ends at once makes
        the answer a refusal with the manager's reason."""
        params = [Param(p.name, p.number, p.text, p.unit) for p in req.parameters]
        boundaries = rospy.get_param(WORLD_BOUNDARIES, None)
        try:
            plan = plan_command(req.intent, req.action, req.agent, params, self.uav_statuses(),
                                None if boundaries is None else np.asarray(boundaries, dtype=float),
                                locked=self.mission.operator_locked_ids)
            goals = self._execute(plan)
            refused = goals.refusals()
        except CommandRefused as refusal:
            rospy.logwarn(f"command refused: {refusal}")
            return GroundStationCommandResponse(False, str(refusal), [])
        except (RuntimeError, rospy.ServiceException, rospy.ROSException) as error:
            return GroundStationCommandResponse(False, f"could not carry it out: {error}", [])
        if refused:
            ended = {w.uav_id for w in refused}
            message = refusal_message(refused, [o.sentence for o in plan.orders if o.uav_id not in ended])
            rospy.logwarn(f"command refused by its UAV managers: {message}")
            return GroundStationCommandResponse(False, message, [])
        values = [NamedValue(a.name, a.number, a.text, a.unit) for a in plan.answers]
        return GroundStationCommandResponse(True, plan.message, values)

    def _execute(self, plan: CommandPlan) -> CommandGoals:
        if plan.mission == "standby":
            self.services.paused.set()
        elif plan.mission == "critical":
            self.critical.publish(String("operator"))
        elif plan.mission == "resume":
            self.critical.publish(String(""))
            self.services.paused.clear()
            self.services.button.set()
        if plan.algorithm:
            name, ids = plan.algorithm
            if not self.services.algorithm_control(ids, name, "set", [], []):
                raise CommandRefused(f"a UAV manager refused algorithm {name}; see its log")
        goals = CommandGoals()
        for order in plan.orders:
            goal_type = getattr(actions, {"take_off": "TakeOff", "land": "Land", "basic_move": "BasicMove",
                                          "follow_agent_ad": "FollowAgentAD"}[order.action] + "Goal")
            goals.send(self.services.action_client(order.uav_id, order.action), goal_type(**order.fields),
                       order.uav_id, order.verb)
        return goals

    def _on_stop(self, req):
        self.machine.request_preempt()
        return TriggerResponse(True, "the mission is being stopped; the finishing sequence follows")

    def _on_continue(self, req):
        self.services.button.set()
        return TriggerResponse(True, "continuing")

    # --- life --------------------------------------------------------------------------------
    def run(self) -> int:
        self.introspection.start()
        start, wall_start = rospy.get_time(), time.monotonic()
        rospy.loginfo(f"mission {self.mission_file.name}: {len(self.mission.agents)} UAVs, starting")
        try:
            outcome = self.machine.execute()
            message = f"mission ended {outcome}"
        except Exception as error:  # the finishing sequence must run whatever happened
            rospy.logerr(f"mission failed: {error!r}")
            outcome, message = "aborted", f"the mission failed: {error}"
        duration = rospy.get_time() - start
        wall = (time.monotonic() - wall_start, self.services.sim_pause.still_wall_now())
        self.finish(outcome, message, duration, wall)
        return 0

    def finish(self, outcome: str, message: str, duration: float, wall: tuple[float, float] = (0.0, 0.0)) -> None:
        """Save, stop the managers, delete models and obstacles, close the bag, tell the Master.

        `wall`: wall seconds of the mission and, of those, of setup with simulated time standing still.
        """
        rospy.loginfo(f"finishing: {message} after {duration:.1f} s of sim time, {wall[0]:.1f} s of wall time "
                      f"({wall[1]:.1f} s of it setting up)")
        services = self.services
        services.sim_pause.run()  # the managers save and stop in simulated time
        steps = []
        if self.save_data and self.data_dir and services.spawned:
            steps.append(("saving the CSVs", lambda: services.save_csv(list(services.spawned))))
        if self.data_dir:
            steps.append(("copying the mission", lambda: write_text_atomically(
                self.data_dir / "mission.json", self.mission_file.read_text(), overwrite=True)))
        steps += [("stopping the UAV managers", services.stop_managers),
                  ("stopping the MAVLink bridges", services.stop_bridges)]
        if self.teardown:  # a persistent stack resets the simulator and the world itself, all at once
            steps += [("deleting the UAVs", services.delete_uavs), ("deleting the world", services.delete_world)]
        steps += [("stopping the UTM", services.stop_utm), ("closing the bag", self._close_bag)]
        for what, step in steps:  # every step runs, and the Master hears of the end whatever fails
            try:
                step()
            except Exception as error:
                rospy.logerr(f"finishing: {what} failed: {error}")
                message += f"; {what} failed: {error}"
        with self.lock:
            # one report per UAV per contact: two UAVs touching once count 2
            collisions = sum(1 for e in self.critical_events if e.event == "collision")
            events = list(self.critical_events)
        success = outcome in SUCCESS_OUTCOMES and not events and not services.setup_errors
        if services.setup_errors:
            message += "; could not start: " + "; ".join(services.setup_errors)
        if events:
            message += "; critical events: " + describe_all(events)
        success, message = judge_actions(success, message, services.failed_actions.all())
        self._report(success, outcome, message, duration, collisions, wall, events)
        self.introspection.stop()

    def _close_bag(self) -> None:
        if self.bag is not None:
            self.bag.close(grace=10.0)

    def _report(self, success, outcome, message, duration, collisions, wall, events) -> None:
        try:
            rospy.wait_for_service(MASTER_TERMINATION, timeout=2.0)
        except rospy.ROSException:
            rospy.loginfo(f"no Master to report to: {outcome}, {message}")
            return
        try:
            report = rospy.ServiceProxy(MASTER_TERMINATION, SimulationTermination)
            report(success=success, outcome=outcome, message=message, sim_duration=duration, collisions=collisions,
                   wall_duration=wall[0], setup_wall_duration=wall[1],
                   critical_events=[CriticalEventMsg(uav_id=e.uav_id, event=e.event, sim_time=e.sim_time,
                                                     detail=e.detail) for e in events])
        except rospy.ServiceException as error:
            rospy.logwarn(f"the Master did not take the result: {error}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rosrun magna_gs ground_station", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_known_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node("ground_station")
    try:
        station = GroundStation()
    except (MissionError, ValueError) as error:
        rospy.logfatal(str(error))
        return 2
    status = station.run()
    if status == 0 and not rospy.is_shutdown():
        # simulation.launch requires this node; ending normally, it ends the launch as Ctrl-C does, without
        # roslaunch's red "REQUIRED process has died" (kept for crashes and errors). Not after a SIGINT: the
        # launch is ending already, and asking it again would wait for its SIGTERM (--sigint-timeout, 5 s).
        end_parent_launch()
    return status
