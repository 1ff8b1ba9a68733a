"""The UAV manager node: one per UAV, on the ground station or on the UAV's companion computer.

`UavManagerNode` is one UAV's manager; `main` runs one in a node of its own (rosrun magna_uav
uav_manager), magna_uav.host_node runs several in one process, each in a thread of its own. A
manager holds nothing node-wide: its names are absolute, its rate, timers and goal ids are its
own, and `close()` unregisters everything it opened.

Its life is a magna_sm state machine: `idle` waits for a goal from the ground station
(watching the UAV with the evaluator meanwhile), the state named after the action flies
the role, and the machine goes back to `idle`, until a die request ends it. Goals arrive
through one SimpleActionServer per action; a goal that arrives while a role runs
preempts it (the UAV does one thing at a time).
"""
from __future__ import annotations

import argparse
import functools
import threading
import time
from pathlib import Path

import numpy as np
import rospy
from geometry_msgs.msg import Point, PoseStamped
from magna_msgs import msg as magna_actions
from magna_msgs.srv import AlgorithmControl, AlgorithmControlResponse, Die, DieResponse, StateActualization
from nav_msgs.msg import Path as PathMsg
from std_msgs.msg import Float64, String

from magna_common import ros_names as names
from magna_common.liveness import BEAT_PERIOD
from magna_sm import CBState, StateMachine
from magna_sm.introspection import IntrospectionServer
from magna_sm.simple_action import SimpleActionServer
from magna_uav.evaluator import Evaluator
from magna_uav.goals import ROLE_ACTIONS, role_from_goal
from magna_uav.manager import ABORTED, PILOT_TAKEOVER, PREEMPTED, RoleResult, UavManager
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.orca import OrcaNavigator
from magna_uav.nai.orca_batch import OrcaBatcher
from magna_uav.order_desk import Order, OrderDesk
from magna_uav.paths import path_msg
from magna_uav.recorder import HeardStamps, Recorder
from magna_uav.reporter import Reporter
from magna_uav.roles import FollowPathRole
from magna_uav.ros_data import RosWorldData, SwarmFeed
from magna_uav.ros_navigation import NavigationPublisher, navigation_msg
from magna_uav.settings import Settings, SettingsError, read_settings
from magna_uav.stepping_clock import SteppingClock
from magna_uav.time_alarms import TimeAlarms
from magna_uav.world_view import WorldView

HELP = """\
The UAV manager of one UAV: receives goals from the ground station and flies them through
the UAL API (magna_sim or a real UAL server), watching every other UAV and obstacle.

Action servers (magna_msgs), under /magna/uav_{id}/:
  take_off, land, basic_move, follow_path, follow_agent_ad, follow_agent_ap   fly a role
  save_csv      write the recorder's rows to a CSV (goal.path, or ~data_dir/uav_{id}.csv)
  set_mission   an on-board mission: optional take-off, a path, optional landing (goal.mission_json)
Services: /magna/uav_{id}/algorithm_control (AlgorithmControl), /magna/uav_{id}/die (Die)
Topics:   /magna/uav_{id}/alive (std_msgs/Float64): its simulated time every 0.2 simulated s, the
          heartbeat the ground station's watchdog listens to (magna_common.liveness);
          /magna/uav_{id}/path/raw, /path/smoothed (nav_msgs/Path), /goal (PoseStamped);
          /magna/uav_{id}/navigation (NavigationStep): every recorded control step, as its CSV row
          (a new subscriber first gets the steps sent so far);
          listens to /magna/gs/critical_event (std_msgs/String; empty clears it) and
          /magna/uav_{id}/utm_new_flightplan (std_msgs/Float64, sim time T of a UTM plan change:
          a follow_path whose goal was sent at or before T ends with utm_new_flightplan)
Reports:  /magna/gs/state_actualization (StateActualization) when the ground station serves it
Machine:  /magna/sm/uav_{id}/structure|status (magna_sm introspection)

Private parameters (defaults):
  ~id (required)            this UAV's id
  ~mission_file ("")        mission JSON: every UAV's model and safety radius from Agents_Config
  ~model (iris)             without a mission file: the airframe of every UAV in ~uav_ids
  ~uav_ids ([~id])          without a mission file: the UAVs of the mission
  ~control_rate (10.0)      control steps per simulated second
  ~data_dir (~/.ros/magna)  where save_csv writes when its goal gives no path
  ~csv_stream ("")          a CSV the rows go to as they are recorded (each flushed when final), so a
                            killed manager leaves its rows; save_csv to it rewrites it whole. "" = none
  ~depth_camera (false)     record the depth image (/uav_{id}/camera/depth/image_raw)
  ~low_battery (0.15)       battery fraction below which a role ends with low_battery
  ~algorithm ("simple")     navigation algorithm at start: simple, orca3, neural_network

Example: rosrun magna_uav uav_manager _id:=1 _uav_ids:=[1,2] _control_rate:=10
"""

ACTION_TYPES = {
    "take_off": "TakeOff", "land": "Land", "basic_move": "BasicMove", "follow_path": "FollowPath",
    "follow_agent_ad": "FollowAgentAD", "follow_agent_ap": "FollowAgentAP", "save_csv": "SaveCSV",
    "set_mission": "SetMission",
}


def ground_station_reporter(uav_id: int) -> Reporter:
    """A Reporter calling the ground station's state_actualization service, when it serves one."""
    proxy = rospy.ServiceProxy(names.GS_STATE_ACTUALIZATION, StateActualization)

    def call(**request):
        rospy.wait_for_service(names.GS_STATE_ACTUALIZATION, timeout=0.2)
        return proxy(**request)

    return Reporter(uav_id, call, running=lambda: not rospy.is_shutdown(),
                    unreachable=(rospy.ROSException, rospy.ServiceException),
                    warn=lambda message: rospy.logwarn_throttle(10, message), debug=rospy.logdebug)


_alarms: TimeAlarms | None = None  # the process's alarms on simulated time, with their watcher thread
_alarms_made = threading.Lock()


def _sim_time_alarms() -> TimeAlarms:
    """The process's alarms; the first call starts their watcher, which wakes at each /clock message."""
    global _alarms
    with _alarms_made:
        if _alarms is None:
            alarms = TimeAlarms(rospy.get_time)
            threading.Thread(target=_watch_sim_time, args=(alarms,), daemon=True, name="sim time alarms").start()
            _alarms = alarms
        return _alarms


def _watch_sim_time(alarms: TimeAlarms) -> None:
    rostime_changed = rospy.rostime.get_rostime_cond()  # notified, under itself, after /clock sets the time
    with rostime_changed:  # held while ringing: a change meanwhile is notified once this waits again
        while not rospy.is_shutdown():
            alarms.ring_due()
            rostime_changed.wait(0.5)


def wait_until_sim_time(target: float, stop: threading.Event | None = None) -> None:
    """Block until ROS time reaches `target` seconds, or `stop` is set: on /clock, woken by the message that reaches
    it (every waiter for the same target wakes on the same one), as rospy.Rate would be, but through the process's
    one watcher of the time instead of at every /clock message; on the wall clock, a sleep."""
    if rospy.rostime.is_wallclock():
        rospy.sleep(target - rospy.get_time())
        return
    alarms = _sim_time_alarms()
    start = rospy.get_time()
    while not rospy.is_shutdown():
        if stop is not None and stop.is_set():
            return
        now = rospy.get_time()
        if now < start:
            raise rospy.exceptions.ROSTimeMovedBackwardsException(start - now)
        alarm = alarms.set(target)
        if alarm is None:
            return
        alarm.wait(0.5)
    raise rospy.ROSInterruptException("ROS shutdown request")


class UavManagerNode:
    """One UAV's manager. `swarm`: the feed of the simulated UAVs' states it shares with the other managers of its
    process (a host's); without one it makes its own, so a standalone manager hears what a hosted one does.
    `orca_batcher`: the ORCA-3D batcher it shares with them (one call per control tick for all, same answers);
    without one, each ORCA-3D step is a call of its own."""

    def __init__(self, settings: Settings, swarm: SwarmFeed | None = None, orca_batcher: OrcaBatcher | None = None):
        self.settings = settings
        own = settings.own
        self.uav_id = own.id
        boundaries = rospy.get_param(names.WORLD_BOUNDARIES, None)
        self.view = WorldView(self.uav_id, boundaries)
        radii = {c.id: c.safety_radius for c in settings.configs}
        self._own_swarm = swarm is None
        self.swarm = SwarmFeed() if swarm is None else swarm
        # magna_sim's swarm message carries the simulated UAVs; those flown by MAVLink are heard on their odom.
        mavlink_flown = [c.id for c in settings.configs if c.mode != "sitl"]
        self.data = RosWorldData(self.view, sorted(radii), radii, depth=settings.depth, swarm=self.swarm,
                                 odom_ids=mavlink_flown)
        self._runner: threading.Thread | None = None  # the thread running run(): the beat lives with it
        # Created here, not earlier: the commander waits for the UAL services of this UAV.
        from magna_uav.commanders import UalCommander

        self.commander = UalCommander(self.uav_id)
        if settings.flies_networks:
            # Importing torch takes seconds. Done here, while the mission's set-up holds the simulator,
            # instead of inside algorithm_control, during which the simulator runs (at rtf max, tens of
            # empty simulated seconds before take-off).
            import torch  # noqa: F401
        orca = None
        if orca_batcher is not None:  # steps on the shared tick go in one call; a role's first step alone
            orca = OrcaNavigator(batcher=orca_batcher, step_key=lambda: self.stepping.tick_key)
        self.nai = NavigationInterface(own.max_speed, own.safety_radius, orca=orca)
        if settings.algorithm != "simple":
            self.nai.control(settings.algorithm, "set")
        self.evaluator = Evaluator(own, settings.low_battery)
        # Every recorded step also goes out as a NavigationStep, so the bag can stand in for the CSV.
        self.navigation = NavigationPublisher(names.manager(self.uav_id, "navigation"))
        self.role_number = 0  # roles flown so far; their steps carry it
        self.recorder = Recorder(self.uav_id, [c.id for c in settings.configs if c.id != self.uav_id],
                                 depth=settings.depth, on_row=self._publish_navigation)
        self.written: set[Path] = set()  # CSVs this node wrote: save_csv may rewrite them
        if settings.csv_stream is not None:
            settings.csv_stream.parent.mkdir(parents=True, exist_ok=True)
            self.recorder.stream_to(settings.csv_stream)  # FileExistsError: the node stops, naming the file
            self.written.add(settings.csv_stream.resolve())
        self._stream_error_told = False
        self.step_pub = rospy.Publisher(names.manager(self.uav_id, "control_step"), Float64, queue_size=1,
                                        tcp_nodelay=True)
        # steps on the ticks of the control period: in a host every manager steps at the same instants
        self.stepping = SteppingClock(rospy.get_time, wait_until_sim_time,
                                      lambda sim_time: self.step_pub.publish(Float64(sim_time)),
                                      1.0 / settings.control_rate)
        self.manager = UavManager(self.view, self.commander, self.nai, self.evaluator, self.recorder,
                                  self.stepping.clock(), lock=self.data.lock)
        self.desk = OrderDesk()
        self.pending: Order | None = None  # the order idle hands to the action's state
        self.reporter = ground_station_reporter(self.uav_id)
        self.alive = rospy.Publisher(names.manager_alive(self.uav_id), Float64, queue_size=1, tcp_nodelay=True)
        self.beat: threading.Thread | None = None
        self._beat_stop = threading.Event()
        self._critical_seen = ""
        self._plan_changed_at = float("-inf")  # sim time of the UTM's latest plan change for this UAV

        name = functools.partial(names.manager, self.uav_id)  # this manager's names: name("goal")
        self.raw_path = rospy.Publisher(name("path/raw"), PathMsg, queue_size=1, latch=True)
        self.smoothed_path = rospy.Publisher(name("path/smoothed"), PathMsg, queue_size=1, latch=True)
        self.goal_pub = rospy.Publisher(name("goal"), PoseStamped, queue_size=1, latch=True)
        self.subscribers = [
            rospy.Subscriber(names.GS_CRITICAL_EVENT, String, self._on_critical_event, queue_size=10),
            rospy.Subscriber(name("utm_new_flightplan"), Float64, self._on_new_flightplan, queue_size=10)]
        self.services = [rospy.Service(name("algorithm_control"), AlgorithmControl, self._on_algorithm_control),
                         rospy.Service(name("die"), Die, self._on_die)]
        self.servers = {}
        for action, type_name in ACTION_TYPES.items():
            spec = getattr(magna_actions, type_name + "Action")
            server = SimpleActionServer(name(action), spec, execute_cb=self._executor(action, type_name),
                                        auto_start=False)
            self.servers[action] = server
        self.machine = self._build_machine()
        self.introspection = IntrospectionServer(f"uav_{self.uav_id}", self.machine)

    # --- the state machine -------------------------------------------------------------
    def _build_machine(self) -> StateMachine:
        machine = StateMachine(["dead"], name=f"UAV_{self.uav_id}")
        with machine:
            StateMachine.add("idle", CBState(self._idle, [*ROLE_ACTIONS, "die"]),
                             transitions={**{a: a for a in ROLE_ACTIONS}, "die": "dead"})
            for action in ROLE_ACTIONS:
                StateMachine.add(action, CBState(self._fly, ["done"], cb_args=(action,)), transitions={"done": "idle"})
        return machine

    def _idle(self, ud) -> str:
        """Hover and watch until a goal (or a die request) arrives."""
        self.reporter.report("idle")
        self.manager.hover()
        idle_event = ""  # the critical event being reported while idle
        while True:
            order = self.desk.take(timeout=1.0 / self.settings.control_rate)
            if self.desk.dying or rospy.is_shutdown():
                return "die"
            if order is not None:
                self.pending = order
                return order.action
            self.manager.keep_hovering()
            with self.data.lock:
                evaluation = self.evaluator.step(self.view, bool(self._critical_seen)) if self.view.has_own else None
            event = ""
            if evaluation is not None and evaluation.outcome in ("collision", "low_battery"):
                event = evaluation.outcome
                if event != idle_event:  # once per episode, not every control step
                    rospy.logwarn(f"UAV {self.uav_id} while idle: {evaluation.reason}")
                    self.reporter.report("idle", event)
            idle_event = event

    def _fly(self, ud, action: str) -> str:
        order = self.pending
        assert order is not None  # idle hands every order over here before it enters this state
        if order.action != action:  # cannot happen: idle returns the order's action
            order.finish(RoleResult(ABORTED, f"internal: state {action} got a {order.action} goal"))
            return "done"
        try:
            role = role_from_goal(action, order.goal, self.settings.own)
        except ValueError as error:
            order.finish(RoleResult(ABORTED, f"{action}: {error}"))
            self.desk.release(order)
            return "done"
        self.reporter.report(action)
        self.role_number += 1
        if isinstance(role, FollowPathRole):
            now = rospy.Time.now()
            self.raw_path.publish(path_msg(role.waypoints, stamp=now))
            self.smoothed_path.publish(path_msg(role.smoothed, stamp=now))
        try:
            result = self.manager.run_role(role, order.preempt_requested, lambda step: self._feedback(order, step),
                                           lambda: action == "follow_path" and order.sent_at <= self._plan_changed_at)
        except rospy.ROSInterruptException:
            result = RoleResult(PREEMPTED, "the node is shutting down")
        except Exception as error:  # a role must end with an outcome, never leave the server hanging
            rospy.logerr(f"UAV {self.uav_id} {action} failed: {error!r}")
            result = RoleResult(ABORTED, f"{action} failed: {error}")
        finally:
            self.stepping.release()
            self.nai.release()  # a shared ORCA-3D batcher no longer waits for this UAV
        self.manager.hover()
        try:
            self.recorder.set_outcome(result.outcome)
        except LookupError:  # the role ended before its first step: no row to mark
            pass
        critical = result.outcome if result.outcome in ("collision", "low_battery", "GS_critical_event") else ""
        if PILOT_TAKEOVER in result.events:
            critical = PILOT_TAKEOVER
            rospy.logwarn(f"UAV {self.uav_id}: {result.message}")
        self.reporter.report(f"{action}_{result.outcome}", critical)
        self.desk.release(order)
        order.finish(result)
        return "done"

    def _feedback(self, order: Order, step) -> None:
        if step.goal is None:
            return
        feedback_type = getattr(magna_actions, ACTION_TYPES[order.action] + "Feedback")
        position = np.asarray(step.goal.position, dtype=float)
        feedback = feedback_type(percent_complete=step.percent, current_target=Point(*position))
        self.servers[order.action].publish_feedback(feedback)
        target = PoseStamped()
        target.header.stamp, target.header.frame_id = rospy.Time.now(), "map"
        target.pose.position = Point(*position)
        target.pose.orientation.w = 1.0
        self.goal_pub.publish(target)

    # --- action servers, services, topics ----------------------------------------------
    def _executor(self, action: str, type_name: str):
        result_type = getattr(magna_actions, type_name + "Result")

        def execute(goal) -> None:
            server = self.servers[action]
            if action == "save_csv":
                outcome, message = self._save_csv(goal.path)
            else:
                order = Order(action, goal, lambda: server.is_preempt_requested() or rospy.is_shutdown())
                status = server.current_goal_status()
                if status is not None and not status.goal_id.stamp.is_zero():
                    order.sent_at = status.goal_id.stamp.to_sec()
                self.desk.submit(order)
                answer = order.wait(rospy.is_shutdown)
                outcome, message = answer.outcome, answer.message
            result = result_type(outcome=outcome, message=message)
            if outcome == "succeeded":
                server.set_succeeded(result, message)
            elif outcome == PREEMPTED:
                server.set_preempted(result, message)
            else:
                server.set_aborted(result, message)

        return execute

    def _save_csv(self, path: str) -> tuple[str, str]:
        target = Path(path).expanduser() if path else self.settings.data_dir / f"uav_{self.uav_id}.csv"
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with self.data.lock:
                written = self.recorder.save_csv(target, overwrite=target.resolve() in self.written)
                rows = self.recorder.rows
        except (OSError, ValueError) as error:
            return ABORTED, f"save_csv: {error}"
        self.written.add(written.resolve())
        return "succeeded", f"{rows} rows written to {written}"

    def _publish_navigation(self, index: int, row: dict, heard: list[HeardStamps]) -> None:
        try:
            self.navigation.publish(navigation_msg(index, row, self.role_number, heard))
        except rospy.ROSException:  # shutting down: the row is recorded all the same
            pass
        stream = self.recorder.stream
        if stream is not None and stream.error and not self._stream_error_told:
            self._stream_error_told = True
            rospy.logerr(f"UAV {self.uav_id}: {stream.error}; the rows stay in memory for save_csv")

    def _beat(self) -> None:
        if self._runner is not None and not self._runner.is_alive():  # the beat says the manager runs, not the timer
            return
        try:
            self.alive.publish(Float64(rospy.get_time()))
        except rospy.ROSException:  # shutting down
            pass

    def _beat_loop(self) -> None:
        """A beat every BEAT_PERIOD simulated seconds until close(), as a rospy.Timer would beat, but woken by the
        process's one watcher of the time instead of by every /clock message."""
        next_beat = rospy.get_time() + BEAT_PERIOD
        while not self._beat_stop.is_set():
            try:
                wait_until_sim_time(next_beat, stop=self._beat_stop)
            except rospy.exceptions.ROSTimeMovedBackwardsException:
                next_beat = rospy.get_time() + BEAT_PERIOD
                continue
            except rospy.ROSInterruptException:
                return
            if self._beat_stop.is_set():
                return
            self._beat()
            next_beat = max(next_beat + BEAT_PERIOD, rospy.get_time())  # a late beat does not make up for lost ones

    def _on_algorithm_control(self, req) -> AlgorithmControlResponse:
        try:
            with self.data.lock:
                message = self.nai.control(req.name, req.action, list(req.params), list(req.values), req.text_value)
        except ValueError as error:
            return AlgorithmControlResponse(success=False, message=str(error))
        return AlgorithmControlResponse(success=True, message=message)

    def _on_die(self, req) -> DieResponse:
        message = "stopping"
        if req.save_data:
            outcome, message = self._save_csv("")
            if outcome != "succeeded":
                return DieResponse(success=False, message=message)
        self.desk.die()
        return DieResponse(success=True, message=f"UAV {self.uav_id} manager: {message}; shutting down")

    def _on_new_flightplan(self, msg: Float64) -> None:
        self._plan_changed_at = max(self._plan_changed_at, msg.data)

    def _on_critical_event(self, msg: String) -> None:
        self._critical_seen = msg.data
        self.manager.gs_critical_event = bool(msg.data)

    # --- life ----------------------------------------------------------------------------
    def wait_for_own_pose(self, limit: float = 30.0) -> bool:
        """Wall-wait until the own UAV's first pose is heard: a goal before it could only fail."""
        deadline = time.monotonic() + limit
        while not rospy.is_shutdown() and time.monotonic() < deadline:
            with self.data.lock:
                if self.view.has_own:
                    return True
            time.sleep(0.01)
        rospy.logwarn(f"UAV {self.uav_id} manager: no pose on {self.view.own_pose_topic} within {limit:g} s; "
                      f"serving anyway, and roles will abort until one comes")
        return False

    def run(self) -> str:
        self._runner = threading.current_thread()
        # The heartbeat runs in simulated time from a timer of its own: a long step does not delay it.
        self.beat = threading.Thread(target=self._beat_loop, daemon=True, name=f"uav_{self.uav_id} beat")
        self.beat.start()
        self.wait_for_own_pose()  # the action servers come up (the manager is "ready") only after it
        for server in self.servers.values():
            server.start()
        self.introspection.start()
        rospy.loginfo(f"UAV {self.uav_id} manager ready: {len(self.servers)} action servers under "
                      f"{names.manager(self.uav_id)}/, control at {self.settings.control_rate:g} Hz")
        try:
            return self.machine.execute()
        finally:
            self.close()

    def close(self) -> None:
        """Stop beating and serving, and unregister every topic and service: in a host the process goes on."""
        self._beat_stop.set()
        if self.recorder.stream is not None:
            self.recorder.stream.close()
        self.introspection.stop()
        for server in self.servers.values():
            server.shutdown()
        for service in self.services:
            service.shutdown()
        self.data.close()
        if self._own_swarm:
            self.swarm.close()
        for subscriber in self.subscribers:
            subscriber.unregister()
        for publisher in (self.alive, self.step_pub, self.raw_path, self.smoothed_path, self.goal_pub,
                          self.navigation.publisher):
            publisher.unregister()
        self.commander.close()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rosrun magna_uav uav_manager", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_known_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node("uav_manager")  # launch files name it uav_{id}_manager
    try:
        settings = read_settings(rospy.get_param)
    except SettingsError as error:
        rospy.logfatal(f"uav_manager: {error}")
        return 2
    try:
        node = UavManagerNode(settings)
    except Exception as error:  # the UAL services never came, or a bad algorithm: say it and stop
        rospy.logfatal(f"uav_manager {settings.uav_id}: {error}")
        return 2
    node.run()
    return 0
