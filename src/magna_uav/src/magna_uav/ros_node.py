"""The UAV manager node: one per UAV, on the ground station or on the UAV's companion computer.

Its life is a magna_sm state machine: `idle` waits for a goal from the ground station
(watching the UAV with the evaluator meanwhile), the state named after the action flies
the role, and the machine goes back to `idle`, until a die request ends it. Goals arrive
through one SimpleActionServer per action; a goal that arrives while a role runs
preempts it (the UAV does one thing at a time).
"""
from __future__ import annotations

import argparse
import collections
import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rospy
from geometry_msgs.msg import Point, PoseStamped, Vector3
from magna_msgs import msg as magna_actions
from magna_msgs.msg import NavigationStep
from magna_msgs.srv import AlgorithmControl, AlgorithmControlResponse, Die, DieResponse, StateActualization
from nav_msgs.msg import Path as PathMsg
from std_msgs.msg import Float64, String

from magna_sm import CBState, StateMachine
from magna_sm.introspection import IntrospectionServer
from magna_sm.simple_action import SimpleActionServer
from magna_uav.config import ConfigError, UavConfig, configs_from_mission, configs_from_mission_file
from magna_uav.evaluator import Evaluator
from magna_uav.goals import ROLE_ACTIONS, role_from_goal
from magna_uav.manager import ABORTED, PILOT_TAKEOVER, PREEMPTED, Clock, RoleResult, UavManager
from magna_uav.nai.interface import NavigationInterface
from magna_uav.paths import path_msg
from magna_uav.recorder import Recorder
from magna_uav.roles import FollowPathRole
from magna_uav.ros_data import RosWorldData
from magna_uav.world_view import WorldView

HELP = """\
The UAV manager of one UAV: receives goals from the ground station and flies them through
the UAL API (magna_sim or a real UAL server), watching every other UAV and obstacle.

Action servers (magna_msgs), under /magna/uav_{id}/:
  take_off, land, basic_move, follow_path, follow_agent_ad, follow_agent_ap   fly a role
  save_csv      write the recorder's rows to a CSV (goal.path, or ~data_dir/uav_{id}.csv)
  set_mission   an on-board mission: optional take-off, a path, optional landing (goal.mission_json)
Services: /magna/uav_{id}/algorithm_control (AlgorithmControl), /magna/uav_{id}/die (Die)
Topics:   /magna/uav_{id}/path/raw, /path/smoothed (nav_msgs/Path), /goal (PoseStamped);
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
STATE_SERVICE = "/magna/gs/state_actualization"
CRITICAL_TOPIC = "/magna/gs/critical_event"


def navigation_msg(index: int, row: dict, role_number: int) -> NavigationStep:
    """The NavigationStep of the recorder's row `index` (`Recorder.row`): the very numbers its CSV row gets."""
    msg = NavigationStep(row=index, role_number=role_number, role=row["role"], algorithm=row["algorithm"],
                         goal=Point(*(row[f"goal.{a}"] for a in "xyz")),
                         goal_velocity=Vector3(*(row[f"goal_vel.{a}"] for a in "xyz")),
                         goal_distance=row["goal_dist"],
                         selected_velocity=Vector3(*(row[f"sel_vel.{a}"] for a in "xyz")),
                         feasible=NavigationStep.FEASIBILITY_UNKNOWN if row["feasible"] is None else row["feasible"])
    # rounded to the nanosecond, not truncated as Time.from_sec does: a bag reader compares it
    # with the UAL stamps of the same simulated instant
    nanoseconds = round(row["time"] * 1e9)
    msg.header.stamp = rospy.Time(nanoseconds // 10**9, nanoseconds % 10**9)
    msg.header.frame_id = "map"
    return msg


class NavigationPublisher(rospy.SubscribeListener):
    """Publishes the NavigationSteps, and replays those sent so far to every new subscriber.

    rosbag record finds a topic by polling the master about once a wall second, so at a high
    real-time factor the first steps would be flown before the bag listens. A new subscriber
    first gets the last `backlog` steps, oldest first; a step published while it was joining
    may reach it twice, so readers drop repeats (same `row`: mlr.bags does).
    """

    def __init__(self, topic: str, backlog: int = 10000):
        self._sent: collections.deque[NavigationStep] = collections.deque(maxlen=backlog)
        self._lock = threading.Lock()  # a replay and a new step never interleave on one connection
        # The queue holds a whole replay: a shorter one would drop its oldest steps.
        self.publisher = rospy.Publisher(topic, NavigationStep, queue_size=backlog, subscriber_listener=self)

    def publish(self, msg: NavigationStep) -> None:
        with self._lock:
            self._sent.append(msg)
            self.publisher.publish(msg)

    def peer_subscribe(self, topic_name, topic_publish, peer_publish) -> None:
        with self._lock:
            for msg in self._sent:
                peer_publish(msg)


class SettingsError(ValueError):
    """A bad private parameter; the message names it."""


@dataclass
class Settings:
    uav_id: int
    configs: list[UavConfig]
    control_rate: float = 10.0
    data_dir: Path = field(default_factory=lambda: Path.home() / ".ros" / "magna")
    depth: bool = False
    low_battery: float = 0.15
    algorithm: str = "simple"
    flies_networks: bool = False  # the mission names neural_network: torch is imported at start-up

    @property
    def own(self) -> UavConfig:
        return next(c for c in self.configs if c.id == self.uav_id)


def read_settings(param=rospy.get_param) -> Settings:
    """The node's private parameters, checked; SettingsError names the bad one."""
    raw_id = param("~id", None)
    if raw_id is None:
        raise SettingsError("~id is missing: give this UAV's id, e.g. _id:=1")
    uav_id = int(raw_id)
    mission_file = param("~mission_file", "")
    try:
        if mission_file:
            configs = configs_from_mission_file(mission_file)
        else:
            ids = [int(i) for i in param("~uav_ids", [uav_id])]
            model = param("~model", "iris")
            entries = [{"ID": i, "model": model, "mode": "sitl", "marker_color": [255, 255, 255, 1.0]} for i in ids]
            configs = configs_from_mission(entries, "~uav_ids/~model")
    except ConfigError as error:
        raise SettingsError(str(error)) from None
    if uav_id not in [c.id for c in configs]:
        raise SettingsError(f"~id is {uav_id} but the mission's UAVs are {[c.id for c in configs]}")
    rate = float(param("~control_rate", 10.0))
    if not 0.5 <= rate <= 200.0:
        raise SettingsError(f"~control_rate is {rate}: give 0.5 to 200 steps per second")
    low = float(param("~low_battery", 0.15))
    if not 0.0 <= low < 1.0:
        raise SettingsError(f"~low_battery is {low}: give a battery fraction in [0, 1)")
    flies_networks = bool(mission_file) and "neural_network" in Path(mission_file).read_text(errors="replace")
    return Settings(uav_id, configs, rate, Path(param("~data_dir", str(Path.home() / ".ros" / "magna"))).expanduser(),
                    bool(param("~depth_camera", False)), low, str(param("~algorithm", "simple")), flies_networks)


@dataclass
class Order:
    """A goal waiting for, or flown by, the state machine."""

    action: str
    goal: object
    server: SimpleActionServer | None = None
    preempt: threading.Event = field(default_factory=threading.Event)
    sent_at: float = float("inf")  # sim time the ground station sent the goal (its goal id's stamp)
    done: threading.Event = field(default_factory=threading.Event)
    result: RoleResult | None = None

    def finish(self, result: RoleResult) -> None:
        self.result = result
        self.done.set()

    def preempt_requested(self) -> bool:
        return self.preempt.is_set() or (self.server is not None and self.server.is_preempt_requested()) \
            or rospy.is_shutdown()


class OrderDesk:
    """Goals wait here for the machine; a new goal preempts the one flying and any still waiting."""

    def __init__(self):
        self._cond = threading.Condition()
        self._waiting: collections.deque[Order] = collections.deque()
        self.current: Order | None = None
        self.dying = False

    def submit(self, order: Order) -> None:
        with self._cond:
            if self.dying:
                order.finish(RoleResult(ABORTED, "the UAV manager is shutting down"))
                return
            for older in [self.current, *self._waiting]:
                if older is not None:
                    older.preempt.set()
            self._waiting.append(order)
            self._cond.notify_all()

    def take(self, timeout: float) -> Order | None:
        with self._cond:
            if not self._waiting:
                self._cond.wait(timeout)
            while self._waiting:
                order = self._waiting.popleft()
                if not order.preempt.is_set():
                    self.current = order
                    return order
                order.finish(RoleResult(PREEMPTED, f"{order.action} replaced by a newer goal before it started"))
            return None

    def release(self, order: Order) -> None:
        with self._cond:
            if self.current is order:
                self.current = None

    def die(self) -> None:
        with self._cond:
            self.dying = True
            for order in [self.current, *self._waiting]:
                if order is not None:
                    order.preempt.set()
            self._cond.notify_all()


class Reporter:
    """State actualizations to the ground station, sent from a thread so the control loop never waits."""

    def __init__(self, uav_id: int):
        self.uav_id = uav_id
        self._queue: queue.Queue = queue.Queue()
        self._proxy = rospy.ServiceProxy(STATE_SERVICE, StateActualization)
        self._thread = threading.Thread(target=self._run, name=f"uav_{uav_id}_reporter", daemon=True)
        self._thread.start()

    def report(self, state: str, critical_event: str = "") -> None:
        self._queue.put((state, critical_event))

    def _run(self) -> None:
        while not rospy.is_shutdown():
            try:
                state, event = self._queue.get(timeout=0.5)
            except queue.Empty:
                continue
            try:
                rospy.wait_for_service(STATE_SERVICE, timeout=0.2)
                answer = self._proxy(id=self.uav_id, state=state, critical_event=event)
                if not answer.success:
                    rospy.logwarn_throttle(10, f"ground station refused the state of UAV {self.uav_id}: "
                                               f"{answer.message}")
            except (rospy.ROSException, rospy.ServiceException):
                rospy.logdebug("no ground station to report %r to", state)


class SteppingClock:
    """The control loop's clock, announcing each control step to the simulator (its lockstep).

    While a role flies, every step's simulated time goes out on /magna/uav_{id}/control_step
    (std_msgs/Float64) before the loop sleeps; `release()` sends -1 when the loop stops
    stepping (idle hovers on a held setpoint and needs no pacing). magna_sim then never runs
    more than its ~lockstep_lead ahead of a manager that is flying, however loaded the
    machine. Nothing listens on a real UAV, and the announcement costs one small message.
    """

    def __init__(self, rate, topic: str):
        self.rate = rate
        self.last = -1.0
        self.publisher = rospy.Publisher(topic, Float64, queue_size=1, tcp_nodelay=True)

    def now(self) -> float:
        self.last = rospy.get_time()
        return self.last

    def sleep(self) -> None:
        self.publisher.publish(Float64(self.last))
        self.rate.sleep()

    def release(self) -> None:
        self.publisher.publish(Float64(-1.0))


class UavManagerNode:
    def __init__(self, settings: Settings):
        self.settings = settings
        own = settings.own
        self.uav_id = own.id
        ns = f"/magna/uav_{self.uav_id}/"
        boundaries = rospy.get_param("/magna/world/boundaries", None)
        self.view = WorldView(self.uav_id, boundaries)
        radii = {c.id: c.safety_radius for c in settings.configs}
        self.data = RosWorldData(self.view, sorted(radii), radii, depth=settings.depth)
        # Created here, not earlier: the commander waits for the UAL services of this UAV.
        from magna_uav.commanders import UalCommander

        self.commander = UalCommander(self.uav_id)
        if settings.flies_networks:
            # Importing torch takes seconds. Done here, while the mission's set-up holds the simulator,
            # instead of inside algorithm_control, during which the simulator runs (at rtf max, tens of
            # empty simulated seconds before take-off).
            import torch  # noqa: F401
        self.nai = NavigationInterface(own.max_speed, own.safety_radius)
        if settings.algorithm != "simple":
            self.nai.control(settings.algorithm, "set")
        self.evaluator = Evaluator(own, settings.low_battery)
        # Every recorded step also goes out as a NavigationStep, so the bag can stand in for the CSV.
        self.navigation = NavigationPublisher(ns + "navigation")
        self.role_number = 0  # roles flown so far; their steps carry it
        self.recorder = Recorder(self.uav_id, [c.id for c in settings.configs if c.id != self.uav_id],
                                 depth=settings.depth, on_row=self._publish_navigation)
        self.stepping = SteppingClock(rospy.Rate(settings.control_rate), ns + "control_step")
        self.manager = UavManager(self.view, self.commander, self.nai, self.evaluator, self.recorder,
                                  Clock(self.stepping.now, self.stepping.sleep), lock=self.data.lock)
        self.desk = OrderDesk()
        self.pending: Order | None = None  # the order idle hands to the action's state
        self.reporter = Reporter(self.uav_id)
        self.written: set[Path] = set()  # CSVs this node wrote: save_csv may rewrite them
        self._critical_seen = ""
        self._plan_changed_at = float("-inf")  # sim time of the UTM's latest plan change for this UAV

        self.raw_path = rospy.Publisher(ns + "path/raw", PathMsg, queue_size=1, latch=True)
        self.smoothed_path = rospy.Publisher(ns + "path/smoothed", PathMsg, queue_size=1, latch=True)
        self.goal_pub = rospy.Publisher(ns + "goal", PoseStamped, queue_size=1, latch=True)
        rospy.Subscriber(CRITICAL_TOPIC, String, self._on_critical_event, queue_size=10)
        rospy.Subscriber(ns + "utm_new_flightplan", Float64, self._on_new_flightplan, queue_size=10)
        self.services = [rospy.Service(ns + "algorithm_control", AlgorithmControl, self._on_algorithm_control),
                         rospy.Service(ns + "die", Die, self._on_die)]
        self.servers = {}
        for action, type_name in ACTION_TYPES.items():
            spec = getattr(magna_actions, type_name + "Action")
            server = SimpleActionServer(ns + action, spec, execute_cb=self._executor(action, type_name),
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
            event = evaluation.outcome if evaluation is not None and evaluation.outcome in ("collision",
                                                                                              "low_battery") else ""
            if event and event != idle_event:  # once per episode, not every control step
                rospy.logwarn(f"UAV {self.uav_id} while idle: {evaluation.reason}")
                self.reporter.report("idle", event)
            idle_event = event

    def _fly(self, ud, action: str) -> str:
        order = self.pending
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
        if order.server is None or step.goal is None:
            return
        feedback_type = getattr(magna_actions, ACTION_TYPES[order.action] + "Feedback")
        position = np.asarray(step.goal.position, dtype=float)
        order.server.publish_feedback(feedback_type(percent_complete=step.percent, current_target=Point(*position)))
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
                order = Order(action, goal, server)
                status = server.current_goal_status()
                if status is not None and not status.goal_id.stamp.is_zero():
                    order.sent_at = status.goal_id.stamp.to_sec()
                self.desk.submit(order)
                while not order.done.wait(0.1):
                    if rospy.is_shutdown():
                        order.finish(RoleResult(ABORTED, "the node is shutting down"))
                outcome, message = order.result.outcome, order.result.message
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

    def _publish_navigation(self, index: int, row: dict) -> None:
        try:
            self.navigation.publish(navigation_msg(index, row, self.role_number))
        except rospy.ROSException:  # shutting down: the row is recorded all the same
            pass

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
        rospy.logwarn(f"UAV {self.uav_id} manager: no pose on /uav_{self.uav_id}/ual/pose within {limit:g} s; "
                      f"serving anyway, and roles will abort until one comes")
        return False

    def run(self) -> str:
        self.wait_for_own_pose()  # the action servers come up (the manager is "ready") only after it
        for server in self.servers.values():
            server.start()
        self.introspection.start()
        rospy.loginfo(f"UAV {self.uav_id} manager ready: {len(self.servers)} action servers under "
                      f"/magna/uav_{self.uav_id}/, control at {self.settings.control_rate:g} Hz")
        try:
            return self.machine.execute()
        finally:
            self.close()

    def close(self) -> None:
        self.introspection.stop()
        for server in self.servers.values():
            server.shutdown()
        for service in self.services:
            service.shutdown()
        self.data.close()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rosrun magna_uav uav_manager", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_known_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node("uav_manager")  # launch files name it uav_{id}_manager
    try:
        settings = read_settings()
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
