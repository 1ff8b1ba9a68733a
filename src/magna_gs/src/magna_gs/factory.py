"""The ground station's states: what each mission state does through ROS.

`RosStateFactory` is the factory `magna_gs.mission.build.build_machine` asks for every
leaf of the mission: action states send one goal to a UAV manager's action server
(`/magna/uav_{id}/{action}`), callback states configure the world, wait, spawn the UAVs,
switch algorithms and save data. The ground station node owns the shared services
(`GroundStationServices`): the world node, the simulator, the UAV managers, the pause.
"""
from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable

import numpy as np
import rospy
from geometry_msgs.msg import Vector3
from magna_msgs import msg as actions
from magna_msgs.srv import GetFreeSpacePoseSet

from magna_common import ros_names as names
from magna_gs.mission.model import ACTION_OUTCOMES, CALLBACK_OUTCOMES
from magna_gs.verdict import FailedAction
from magna_sm import State
from magna_sm.simple_action import SimpleActionClient
from magna_uav.commanders import pose_stamped

ACTION_TYPES = {"take_off": "TakeOff", "land": "Land", "basic_move": "BasicMove", "follow_path": "FollowPath",
                "follow_agent_ad": "FollowAgentAD", "follow_agent_ap": "FollowAgentAP", "save_csv": "SaveCSV",
                "set_mission": "SetMission"}
POLL = 0.05  # s of wall time between checks while a state waits


def world_poses(definition: list, timeout: float = 30.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (position, quaternion xyzw) poses of a pose definition [volume, geometry, kind, arg], from the
    world node; ValueError with the world node's reason when it does not resolve."""
    request = [item if isinstance(item, str) else json.dumps(item) for item in definition]
    rospy.wait_for_service(names.WORLD_GET_FSPSET, timeout=timeout)
    answer = rospy.ServiceProxy(names.WORLD_GET_FSPSET, GetFreeSpacePoseSet)(definition=request)
    if not answer.success:
        raise ValueError(f"pose definition {definition}: {answer.message}")
    return [(np.array([p.position.x, p.position.y, p.position.z]),
             np.array([p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w]))
            for p in answer.poses.poses]


def _param(parameters, name: str, default=None):
    """A mission parameter by name, from the loader's typed parameters or a plain mapping."""
    if isinstance(parameters, dict):
        return parameters.get(name, default)
    return getattr(parameters, name, default)


class MissionActionState(State):
    """One goal to one UAV manager; its result's outcome is the state's outcome.

    A mission pause (`services.paused`) cancels the goal and sends it again on resume, so
    the pause costs the UAV its progress within that action, not the mission's flow.
    """

    def __init__(self, services, uav_id: int, action: str, make_goal: Callable[[], object], where: str):
        super().__init__(ACTION_OUTCOMES)
        self.services, self.uav_id, self.action, self.make_goal, self.where = services, uav_id, action, make_goal, where

    def execute(self, ud) -> str:
        with self.services.sim_pause.time_needed():  # no setup state pauses the simulator under a flying goal
            return self._execute()

    def _execute(self) -> str:
        # A lost manager (dead or frozen, see magna_common.liveness) answers nothing: its goals end at once.
        lost = self.services.lost_manager(self.uav_id)
        if lost is not None:
            rospy.logerr(f"{self.where}: UAV {self.uav_id} {self.action} aborted: {lost.describe()}")
            return "aborted"
        client = self.services.action_client(self.uav_id, self.action)
        while True:
            if not self.services.wait_while_paused(self.preempt_requested):
                return "preempted"
            try:
                goal = self.make_goal()
            except ValueError as error:
                rospy.logerr(f"{self.where}: {error}")
                return self._aborted(f"its goal could not be made: {error}")
            client.send_goal(goal)
            while not client.wait_for_result(rospy.Duration(POLL)):
                if self.services.lost_manager(self.uav_id) is not None:  # the critical event of every UAV
                    rospy.logerr(f"{self.where}: UAV {self.uav_id} {self.action}: its manager is lost")
                    return "GS_critical_event"
                if rospy.is_shutdown() or self.preempt_requested():
                    client.cancel_goal()
                    client.wait_for_result(rospy.Duration(2.0))
                    return "preempted"
                if self.services.paused.is_set():
                    client.cancel_goal()
                    client.wait_for_result(rospy.Duration(2.0))
                    break  # sent again after the resume
            else:
                result = client.get_result()
                outcome = getattr(result, "outcome", "") or "aborted"
                message = getattr(result, "message", "") if result is not None else "no result from its UAV manager"
                if outcome not in ACTION_OUTCOMES:
                    rospy.logwarn(f"{self.where}: UAV {self.uav_id} answered {outcome!r}; taken as aborted")
                    message, outcome = f"its manager answered {outcome!r}: {message}", "aborted"
                if outcome != "succeeded":
                    rospy.loginfo(f"{self.where}: UAV {self.uav_id} {self.action} {outcome}: {message}")
                return self._aborted(message) if outcome == "aborted" else outcome

    def _aborted(self, reason: str) -> str:
        """Aborted, and kept for the ground station's verdict: a failed action is never part of a success."""
        self.services.failed_actions.add(FailedAction(self.uav_id, self.action, self.where, reason, rospy.get_time()))
        return "aborted"


class CallbackState(State):
    """A mission callback (world_config, wait, spawn_agents, algorithm_control, save_csv)."""

    def __init__(self, run: Callable[[CallbackState], bool], where: str):
        super().__init__(CALLBACK_OUTCOMES)
        self.run, self.where = run, where

    def execute(self, ud) -> str:
        try:
            return "completed" if self.run(self) else "failed"
        except Exception as error:  # a callback must give an outcome; the mission decides what failure means
            rospy.logerr(f"{self.where}: {error}")
            return "failed"


class RosStateFactory:
    """Builds each mission leaf as a state that acts through the ground station's services."""

    def __init__(self, services):
        self.services = services

    # --- action states -------------------------------------------------------------------
    def action_state(self, uav_id: int, action: str, parameters, json_path: str) -> State:
        builders = {"take_off": self._take_off, "land": self._land, "basic_move": self._basic_move,
                    "follow_path": self._follow_path, "follow_agent_ad": self._follow_ad,
                    "follow_agent_ap": self._follow_ap, "save_csv": self._save_csv_goal,
                    "set_mission": self._set_mission}
        if action not in builders:
            raise ValueError(f"{json_path}: action {action!r} is unknown to the ground station")
        build = builders[action]
        return MissionActionState(self.services, uav_id, action, lambda: build(uav_id, parameters), json_path)

    @staticmethod
    def _take_off(uav_id, p):
        return actions.TakeOffGoal(height=float(_param(p, "height", 2.0)))

    @staticmethod
    def _land(uav_id, p):
        return actions.LandGoal()

    @staticmethod
    def _basic_move(uav_id, p):
        return actions.BasicMoveGoal(move_type=_param(p, "move_type", "translation"),
                                     dynamic=_param(p, "dynamic", "position") or "position",
                                     direction=_param(p, "direction", "up"), value=float(_param(p, "value", 0.0)),
                                     duration=float(_param(p, "duration", 0.0) or 0.0))

    def _follow_path(self, uav_id, p):
        utm = getattr(self.services, "utm", None)
        if _param(p, "from_utm", False):
            if utm is None:
                raise ValueError("follow_path from utm: this ground station runs no UTM")
            positions = list(utm.path_for(uav_id))
        else:
            positions = [position for position, _ in self._resolve_path(p)]
            if positions and utm is not None:
                utm.remember(uav_id, positions)
        if not positions:
            raise ValueError("follow_path: the path resolved to no waypoints")
        return actions.FollowPathGoal(path=[pose_stamped(position) for position in positions],
                                      smooth_path_mode=int(_param(p, "smooth_path_mode", 0) or 0),
                                      dynamic=_param(p, "dynamic", "velocity") or "velocity",
                                      duration=float(_param(p, "duration", 0.0) or 0.0))

    @staticmethod
    def _follow_ad(uav_id, p):
        return actions.FollowAgentADGoal(target_id=int(_param(p, "target_ID", _param(p, "target_id", 0))),
                                         distance=float(_param(p, "distance", 2.0)),
                                         duration=float(_param(p, "duration", 0.0) or 0.0))

    @staticmethod
    def _follow_ap(uav_id, p):
        offset = [float(v) for v in _param(p, "pos", (0.0, 0.0, 0.0))]
        return actions.FollowAgentAPGoal(target_id=int(_param(p, "target_ID", _param(p, "target_id", 0))),
                                         pos=Vector3(*offset), duration=float(_param(p, "duration", 0.0) or 0.0))

    def _save_csv_goal(self, uav_id, p):
        return actions.SaveCSVGoal(path=str(self.services.csv_path(uav_id)))

    def _resolve_path(self, p) -> list:
        waypoints = []
        for definition in _param(p, "path", ()) or ():
            waypoints.extend(self.services.resolve_poses(definition.as_list()[:4]))
        return waypoints

    def _set_mission(self, uav_id, p):
        """The path resolved here, the rest as the UAV manager's set_mission takes it."""
        path = [[float(v) for v in position] for position, _ in self._resolve_path(p)]
        mission = {"path": path, "include_takeoff": bool(_param(p, "include_takeoff", False)),
                   "include_land": bool(_param(p, "include_land", False))}
        return actions.SetMissionGoal(mission_json=json.dumps(mission))

    # --- callback states -----------------------------------------------------------------
    def callback_state(self, state_type: str, ids: list[int], parameters, json_path: str) -> State:
        s = self.services
        if state_type == "world_config":
            return CallbackState(lambda state: s.world_config(parameters.action, parameters.id,
                                                              parameters.world_part_def), json_path)
        if state_type == "wait":
            return CallbackState(lambda state: s.wait(_param(parameters, "exit_type", "time"),
                                                      float(_param(parameters, "duration", 0.0) or 0.0), state),
                                 json_path)
        if state_type == "spawn_agents":
            return CallbackState(lambda state: s.spawn_agents(list(_param(parameters, "initial_poses", []))),
                                 json_path)
        if state_type == "algorithm_control":
            return CallbackState(lambda state: s.algorithm_control(ids, parameters.name, parameters.action,
                                                                   list(parameters.params), list(parameters.values),
                                                                   parameters.text_value), json_path)
        if state_type == "save_csv":
            return CallbackState(lambda state: s.save_csv(ids), json_path)
        raise ValueError(f"{json_path}: callback state {state_type!r} is unknown to the ground station")


def wait_sim_seconds(seconds: float, stop: Callable[[], bool]) -> bool:
    """Sleep `seconds` of ROS time (simulated under /use_sim_time); False when `stop` ended it early.

    Wakes at every /clock message (rospy's time condition), so that at rtf max a wait ends
    within one clock period of simulated time, not one POLL of wall time (hundreds of
    simulated seconds while the simulator is idle); `stop` is looked at least every POLL.
    """
    deadline = rospy.get_time() + seconds
    tick = rospy.rostime.get_rostime_cond()
    while rospy.get_time() < deadline:
        if stop() or rospy.is_shutdown():
            return False
        with tick:
            tick.wait(min(POLL, max(deadline - rospy.get_time(), 0.001)))
    return True


class ActionClients:
    """One SimpleActionClient per (UAV, action), made on first use and kept.

    Clients of different UAVs (or actions) are made at the same time: each waits for its server, and a
    mission's concurrence of 50 take-offs, or the 50 save_csv goals at the end, would otherwise wait for
    each other's connections one after the other. Two threads asking for the same one get the same client.
    """

    def __init__(self, wait: float = 60.0):
        self.wait = wait
        self._clients: dict[tuple[int, str], SimpleActionClient] = {}
        self._making: dict[tuple[int, str], threading.Lock] = {}  # one lock per client being made
        self._lock = threading.Lock()  # guards the two dicts only, never held while waiting for a server
        self._stopped = False

    def get(self, uav_id: int, action: str) -> SimpleActionClient:
        key = (uav_id, action)
        with self._lock:
            client = self._clients.get(key)
            if client is not None:
                return client
            making = self._making.setdefault(key, threading.Lock())
        with making:
            with self._lock:
                client = self._clients.get(key)
            if client is not None:  # made by the thread we waited for
                return client
            client = self._make(uav_id, action)
            with self._lock:
                if self._stopped:  # the mission ended meanwhile: nobody would stop this one
                    client.stop()
                    raise RuntimeError(f"UAV {uav_id}: no {action} client: the ground station is finishing")
                self._clients[key] = client
            return client

    def _make(self, uav_id: int, action: str) -> SimpleActionClient:
        spec = getattr(actions, ACTION_TYPES[action] + "Action")
        client = SimpleActionClient(names.manager(uav_id, action), spec)
        # Wall time: a manager takes seconds to start, and under rtf max a minute of
        # simulated time passes in a few of them.
        deadline = time.monotonic() + self.wait
        while not client.wait_for_server(rospy.Duration(0.05)) and time.monotonic() < deadline:
            if rospy.is_shutdown():
                break
        if not client.wait_for_server(rospy.Duration(0.01)):
            client.stop()
            raise RuntimeError(f"UAV {uav_id}: no action server /magna/uav_{uav_id}/{action} within "
                               f"{self.wait:g} s; did its manager start?")
        return client

    def stop(self) -> None:
        with self._lock:
            self._stopped = True
            clients, self._clients = list(self._clients.values()), {}
        for client in clients:
            client.stop()

