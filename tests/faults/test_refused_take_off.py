"""A refused or failed take-off is never a success, nor is any other action the UAL refuses or fails (issue 26,
item 7).

Without ROS: every action of the UAV manager that calls the UAL, flown by the real manager loop and roles
against a UAL stand-in that refuses as a UAL server does (state guards, CommandRefused with the reason) and
that can fail what it accepted (a take-off given up or blocked, a landing given up or on a roof). Each ends
`aborted` with the reason, never `succeeded`, and never waits for ever. Then the ground station's side: its
real action states, fed a manager's aborted result, keep the reason, and a mission whose Concurrence ends
`completed` (the original's default for mixed outcomes) is still not a success and says why.

Live (one `magna run` of a one-UAV mission, under umask 027): the UAL refuses a waypoint for a landed UAV;
the action ends aborted, result.json and summary.csv say not a success and why, and every file and folder
the simulation wrote honours the umask.
"""
from __future__ import annotations

import csv
import json
import os
import stat
import subprocess
import threading
from contextlib import nullcontext
from types import SimpleNamespace

import numpy as np
import pytest
import rospy
from geometry_msgs.msg import Vector3

from magna_common.ual_commands import CommandRefused
from magna_gs.factory import RosStateFactory
from magna_gs.mission.build import build_machine
from magna_gs.mission.loader import mission_from_data
from magna_gs.verdict import FailedAction, FailedActions, judge_actions
from magna_uav.config import configs_from_mission
from magna_uav.evaluator import Evaluator
from magna_uav.goals import role_from_goal
from magna_uav.manager import Clock, UavManager
from magna_uav.nai.interface import NavigationInterface
from magna_uav.recorder import Recorder
from magna_uav.roles import (
    FLYING_AUTO,
    LANDED_ARMED,
    LANDING,
    STALL_TIME,
    TAKING_OFF,
    UAL_ACCEPT_TIME,
    UNINITIALIZED,
    state_name,
)
from magna_uav.world_view import AgentState, WorldView
from tests.support import ROOT

AGENTS = [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]},
          {"ID": 2, "model": "iris", "mode": "sitl", "marker_color": [0, 0, 255, 0.5]}]
DT = 0.05  # s of simulated time per control step
LIMIT = 3 * STALL_TIME  # s of simulated time: no role may run longer in these tests (a guard against hangs)


class Ual:
    """One UAV's UAL as the manager's commander sees it: the guards of magna_sim and ual_mavlink (take_off from
    LANDED_ARMED, land and go_to_waypoint only FLYING_AUTO; set-points ignored unless FLYING_AUTO), and kinematics.

    `gives_up_take_off_at` (z): the UAL drops the take-off there (state LANDED_ARMED again, as ual_mavlink after a
    disarm); `ceiling` (z): the UAV climbs or flies no higher (a blocked take-off stays TAKING_OFF, as magna_sim
    keeps it); `floor` (z): it comes down no lower (a roof); `gives_up_landing_at` (z): FLYING_AUTO again.
    `ready_at` (s): UNINITIALIZED until then. `silent_take_off`: accepts a take-off and never starts it."""

    def __init__(self, position=(0.0, 0.0, 0.0), state=LANDED_ARMED, speed=1.0):
        self.position, self.state, self.speed = np.array(position, dtype=float), state, speed
        self.target, self.velocity, self.t = self.position.copy(), np.zeros(3), 0.0
        self.calls: list[str] = []
        self.refusals: list[str] = []
        self.gives_up_take_off_at = self.gives_up_landing_at = None
        self.ceiling, self.floor, self.ready_at, self.silent_take_off = np.inf, 0.0, 0.0, False

    def _require(self, state: int, command: str) -> None:
        if self.state != state:
            reason = (f"/uav_1/ual/{command}: {command} refused: UAV 1 is {state_name(self.state)}; {command} needs "
                      f"{state_name(state)}")
            self.refusals.append(reason)
            raise CommandRefused(reason)

    # --- the commander interface (magna_uav.commanders.UalCommander) ---
    def take_off(self, height):
        self.calls.append("take_off")
        self._require(LANDED_ARMED, "take_off")
        self.state = TAKING_OFF
        if not self.silent_take_off:
            self.target = self.position + [0, 0, height]

    def land(self):
        self.calls.append("land")
        self._require(FLYING_AUTO, "land")
        self.state, self.target = LANDING, self.position * [1, 1, 0]

    def go_to_waypoint(self, position, yaw=0.0):
        self.calls.append("go_to_waypoint")
        self._require(FLYING_AUTO, "go_to_waypoint")
        self.target, self.velocity = np.asarray(position, dtype=float), np.zeros(3)

    def set_velocity(self, velocity, yaw_rate=0.0):
        self.calls.append("set_velocity")
        if self.state == FLYING_AUTO:  # a UAL ignores a set-point in any other state, and says nothing
            self.velocity, self.target = np.asarray(velocity, dtype=float), None

    def hold_pose(self, position, yaw):
        self.calls.append("hold_pose")
        if self.state == FLYING_AUTO:
            self.target, self.velocity = np.asarray(position, dtype=float), np.zeros(3)

    # --- the physics, one step ---
    def advance(self) -> None:
        self.t += DT
        if self.state == UNINITIALIZED and self.t >= self.ready_at:
            self.state = LANDED_ARMED
        if self.target is not None:
            gap = self.target - self.position
            distance = float(np.linalg.norm(gap))
            self.position = self.position + (gap / distance * min(distance, self.speed * DT) if distance > 0 else 0)
        else:
            self.position = self.position + self.velocity * DT
        self.position[2] = min(max(self.position[2], self.floor), self.ceiling)
        z = self.position[2]
        arrived = self.target is not None and np.linalg.norm(self.target - self.position) < 1e-9
        if self.state == TAKING_OFF:
            if self.gives_up_take_off_at is not None and z >= self.gives_up_take_off_at:
                self.state, self.target = LANDED_ARMED, self.position * [1, 1, 0]
            elif arrived:
                self.state = FLYING_AUTO
        elif self.state == LANDING:
            if self.gives_up_landing_at is not None and z <= self.gives_up_landing_at:
                self.state, self.target = FLYING_AUTO, self.position.copy()
            elif z <= 1e-9:
                self.state = LANDED_ARMED


def manager_for(ual: Ual, with_uav_2: bool = False):
    """The real UavManager (roles, NAI, evaluator, recorder) of UAV 1 flying `ual`, in simulated time."""
    configs = configs_from_mission(AGENTS[:2 if with_uav_2 else 1], "test")
    view = WorldView(1, boundaries=[[-50, 50], [-50, 50], [0, 30]])

    def publish():
        view.update_agent(AgentState(1, ual.position.copy(), velocity=ual.velocity.copy(), ual_state=ual.state,
                                     battery=0.9, stamp=ual.t))
        if with_uav_2:
            view.update_agent(AgentState(2, np.array([5.0, 0.0, 3.0]), ual_state=FLYING_AUTO, battery=0.9,
                                         stamp=ual.t))

    def sleep():
        if ual.t > LIMIT:
            raise AssertionError(f"the role still runs after {LIMIT:g} s of simulated time")
        ual.advance()
        publish()

    publish()
    recorder = Recorder(1, [2] if with_uav_2 else [])
    manager = UavManager(view, ual, NavigationInterface(configs[0].max_speed, configs[0].safety_radius),
                         Evaluator(configs[0]), recorder, Clock(lambda: ual.t, sleep))
    return manager, configs[0], recorder


def flying_at(z: float = 3.0) -> Ual:
    ual = Ual((0.0, 0.0, z), FLYING_AUTO)
    ual.target = ual.position.copy()
    return ual


def path_goal(points, dynamic):
    path = [SimpleNamespace(pose=SimpleNamespace(position=SimpleNamespace(x=x, y=y, z=z))) for x, y, z in points]
    return SimpleNamespace(path=path, smooth_path_mode=0, dynamic=dynamic, duration=0.0)


def move_goal(move_type, dynamic="position", value=1.0, direction="up"):
    return SimpleNamespace(move_type=move_type, direction=direction, value=value, dynamic=dynamic, duration=0.0)


# (action, goal, the UAL's state when the goal comes, what the reason must say)
REFUSED = [
    ("take_off", SimpleNamespace(height=2.0), LANDING, "take_off refused: UAV 1 is LANDING"),
    ("take_off", SimpleNamespace(height=2.0), TAKING_OFF, "take_off refused: UAV 1 is TAKING_OFF"),
    ("land", SimpleNamespace(), TAKING_OFF, "land refused: UAV 1 is TAKING_OFF"),
    ("basic_move", move_goal("translation"), LANDED_ARMED, "go_to_waypoint refused: UAV 1 is LANDED_ARMED"),
    ("basic_move", move_goal("rotation", direction="left", value=90.0), LANDED_ARMED, "go_to_waypoint refused"),
    ("basic_move", move_goal("translation", "velocity"), LANDED_ARMED, "landed (LANDED_ARMED): a translation by "
                                                                      "velocity needs it flying"),
    ("basic_move", move_goal("takeoff", value=2.0), LANDING, "take_off refused: UAV 1 is LANDING"),
    ("basic_move", move_goal("land"), TAKING_OFF, "land refused: UAV 1 is TAKING_OFF"),
    ("follow_path", path_goal([(3, 0, 3)], "position"), LANDED_ARMED, "landed (LANDED_ARMED): a path needs it"),
    ("follow_path", path_goal([(3, 0, 3)], "velocity"), LANDING, "the UAL is LANDING: a path needs it FLYING_AUTO"),
    ("follow_agent_ad", SimpleNamespace(target_id=2, distance=2.0, duration=5.0), LANDED_ARMED,
     "following UAV 2 needs it flying"),
    ("follow_agent_ap", SimpleNamespace(target_id=2, pos=Vector3(1, 0, 0), duration=5.0), LANDED_ARMED,
     "following UAV 2 needs it flying"),
    ("set_mission", SimpleNamespace(mission_json=json.dumps({"path": [[3, 0, 3]], "include_takeoff": True})),
     TAKING_OFF, "set_mission: UAL refused: /uav_1/ual/take_off: take_off refused: UAV 1 is TAKING_OFF"),
]


@pytest.mark.parametrize(("action", "goal", "state", "reason"), REFUSED,
                         ids=[f"{a}-{state_name(s)}-{i}" for i, (a, _, s, _) in enumerate(REFUSED)])
def test_an_action_the_ual_refuses_or_cannot_fly_ends_aborted_with_the_reason(action, goal, state, reason):
    ual = Ual((0.0, 0.0, 0.0 if state in (LANDED_ARMED,) else 1.0), state)
    manager, config, recorder = manager_for(ual, with_uav_2=action.startswith("follow_agent"))
    result = manager.run_role(role_from_goal(action, goal, config))
    assert result.outcome == "aborted", result
    assert reason in result.message, result.message
    assert recorder.rows >= 1 and recorder.row(-1)["outcome"] == "aborted"
    if "refused" in reason:  # the UAL itself said no: the message carries its very words
        assert any(refusal in result.message for refusal in ual.refusals), (ual.refusals, result.message)


def test_a_waypoint_the_ual_refuses_in_mid_path_ends_the_path_aborted():
    """A path by position resends its waypoint every second: once the UAL refuses it (a failsafe landing began),
    the path ends with the UAL's reason instead of claiming the waypoints later."""
    ual = flying_at(3.0)
    manager, config, _ = manager_for(ual)

    def failsafe_landing_after_2_s():
        if ual.t >= 2.0 and ual.state == FLYING_AUTO:
            ual.state, ual.target = LANDING, ual.position * [1, 1, 0]
        return False

    result = manager.run_role(role_from_goal("follow_path", path_goal([(20, 0, 3)], "position"), config),
                              preempt_requested=failsafe_landing_after_2_s)
    assert result.outcome == "aborted", result
    assert "path: UAL refused: /uav_1/ual/go_to_waypoint: go_to_waypoint refused: UAV 1 is LANDING" in result.message


@pytest.mark.parametrize(("setup", "reason"), [
    (lambda ual: setattr(ual, "gives_up_take_off_at", 0.5), "take-off failed: the UAL reports LANDED_ARMED again"),
    (lambda ual: setattr(ual, "silent_take_off", True) or setattr(ual, "gives_up_take_off_at", -1.0),
     f"still reports LANDED_ARMED {UAL_ACCEPT_TIME:.1f} s after it accepted the take-off"),
    (lambda ual: setattr(ual, "ceiling", 0.8), "take-off stuck: climbed no nearer than 1.20 m below 2.00 m"),
], ids=["given-up", "never-started", "blocked-above"])
def test_a_take_off_the_ual_accepts_and_then_fails_ends_aborted(setup, reason):
    ual = Ual()
    setup(ual)
    if ual.silent_take_off:  # accepted, TAKING_OFF never shown: the UAL at once back to its landed state
        take_off = ual.take_off

        def take_off_that_does_nothing(height):
            take_off(height)
            ual.state = LANDED_ARMED
        ual.take_off = take_off_that_does_nothing
    manager, config, _ = manager_for(ual)
    result = manager.run_role(role_from_goal("take_off", SimpleNamespace(height=2.0), config))
    assert result.outcome == "aborted", result
    assert reason in result.message, result.message
    assert ual.calls.count("take_off") == 1


def test_a_take_off_waits_for_the_ual_to_be_ready_instead_of_being_refused():
    """At rtf max a take-off reached magna_sim before its first step after the spawn: refused, UNINITIALIZED."""
    ual = Ual(state=UNINITIALIZED)
    ual.ready_at = 1.0
    manager, config, _ = manager_for(ual)
    result = manager.run_role(role_from_goal("take_off", SimpleNamespace(height=2.0), config))
    assert result.outcome == "succeeded", result
    assert ual.refusals == [] and ual.calls.count("take_off") == 1


def test_a_take_off_from_a_ual_that_never_gets_ready_ends_aborted_with_the_uals_reason():
    ual = Ual(state=UNINITIALIZED)
    ual.ready_at = np.inf
    manager, config, _ = manager_for(ual)
    result = manager.run_role(role_from_goal("take_off", SimpleNamespace(height=2.0), config))
    assert result.outcome == "aborted"
    assert "take_off refused: UAV 1 is UNINITIALIZED; take_off needs LANDED_ARMED" in result.message


@pytest.mark.parametrize(("setup", "reason"), [
    (lambda ual: setattr(ual, "gives_up_landing_at", 2.0), "landing failed: the UAL reports FLYING_AUTO again"),
    (lambda ual: setattr(ual, "floor", 1.5), "landing stuck: came no lower than z = 1.50 m"),
], ids=["given-up", "on-a-roof"])
def test_a_landing_the_ual_accepts_and_then_fails_ends_aborted(setup, reason):
    ual = flying_at(3.0)
    setup(ual)
    manager, config, _ = manager_for(ual)
    result = manager.run_role(role_from_goal("land", SimpleNamespace(), config))
    assert result.outcome == "aborted", result
    assert reason in result.message, result.message


def test_a_move_the_uav_cannot_make_ends_aborted_as_stuck_instead_of_waiting():
    ual = flying_at(3.0)
    ual.ceiling = 3.2  # something above it
    manager, config, _ = manager_for(ual)
    result = manager.run_role(role_from_goal("basic_move", move_goal("translation", value=2.0), config))
    assert result.outcome == "aborted", result
    assert result.message.startswith("translation stuck: 1.8") and "short of its goal for 120 s" in result.message


def test_the_same_actions_succeed_when_the_ual_lets_them():
    """The stand-in is no stricter than a UAL: the actions above fly to success from the right states."""
    ual = Ual()
    manager, config, _ = manager_for(ual, with_uav_2=True)
    for action, goal in [("take_off", SimpleNamespace(height=2.0)),
                         ("basic_move", move_goal("translation", value=1.0)),
                         ("basic_move", move_goal("translation", "velocity", value=1.0, direction="left")),
                         ("follow_path", path_goal([(2, 2, 3)], "position")),
                         ("follow_path", path_goal([(0, 2, 3)], "velocity")),
                         ("follow_agent_ad", SimpleNamespace(target_id=2, distance=2.0, duration=3.0)),
                         ("land", SimpleNamespace())]:
        result = manager.run_role(role_from_goal(action, goal, config))
        assert result.outcome == "succeeded", (action, result)
    assert ual.refusals == []


# --- the ground station ------------------------------------------------------------------------------------------

class ScriptedManagers:
    """The ground station's services as its action states use them, with each UAV manager's answer scripted:
    {(uav, action): (outcome, message)}; unscripted goals succeed."""

    def __init__(self, answers):
        self.answers = answers
        self.failed_actions = FailedActions()
        self.paused = threading.Event()
        self.sim_pause = SimpleNamespace(time_needed=nullcontext, run=lambda: None)
        self.sent: list[tuple[int, str]] = []

    def action_client(self, uav_id, action):
        outcome, message = self.answers.get((uav_id, action), ("succeeded", "done"))
        services = self

        class Client:
            def send_goal(self, goal):
                services.sent.append((uav_id, action))

            def wait_for_result(self, timeout):
                return True

            def get_result(self):
                return SimpleNamespace(outcome=outcome, message=message)

            def cancel_goal(self):
                pass

        return Client()

    def wait_while_paused(self, stop):
        return True

    def lost_manager(self, uav_id):  # the liveness watchdog's question: no manager is lost here
        return None


TAKE_OFF_THEN_LAND = {
    "Agents_Config": AGENTS,
    "State_Machine": [
        {"type": "Concurrence", "name": "take_off", "ids": 1, "occurrencies": [
            {"type": "SimpleActionState", "state_type": "take_off", "name": "take_off", "ids": "all",
             "ids_var": "agent", "parameters": {"height": 2.0}}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "failed": {"all": "aborted"}},
         "outcomes": {"completed": "1_land", "failed": "failed"}},
        {"type": "Concurrence", "name": "land", "ids": 1, "occurrencies": [
            {"type": "SimpleActionState", "state_type": "land", "name": "land", "ids": "all", "ids_var": "agent"}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "failed": {"all": "aborted"}},
         "outcomes": {"completed": "completed", "failed": "failed"}},
    ],
}
REFUSAL = "take_off: UAL refused: /uav_1/ual/take_off: take_off refused: UAV 1 is UNINITIALIZED; take_off needs " \
          "LANDED_ARMED"


def test_a_refused_take_off_in_a_mission_that_ends_completed_is_not_a_success_and_says_why(monkeypatch):
    """The fault seen at rtf max: UAV 1's take-off refused, UAV 2's done; the Concurrence's outcome map matches
    neither 'all succeeded' nor 'all aborted', so it ends 'completed' (the original's default) and the mission
    flies on to 'completed'. The ground station's real action states keep the manager's reason, and the verdict
    is not a success, naming the UAV, the action, the state and the UAL's words."""
    monkeypatch.setattr(rospy, "get_time", lambda: 12.5)
    services = ScriptedManagers({(1, "take_off"): ("aborted", REFUSAL)})
    mission = mission_from_data(TAKE_OFF_THEN_LAND, "take_off_then_land.json").mission
    outcome = build_machine(mission, RosStateFactory(services)).execute()
    assert outcome == "completed"
    assert sorted(services.sent) == [(1, "land"), (1, "take_off"), (2, "land"), (2, "take_off")]
    failed = services.failed_actions.all()
    assert failed == [FailedAction(1, "take_off", "State_Machine[0].occurrencies[0]", REFUSAL, 12.5)]
    success, message = judge_actions(True, f"mission ended {outcome}", failed)
    assert success is False
    assert message == ("mission ended completed; aborted actions: UAV 1 take_off aborted at 12.5 s "
                       f"(State_Machine[0].occurrencies[0]): {REFUSAL}")


@pytest.mark.parametrize(("answer", "kept"), [
    (("aborted", "landing failed: the UAL reports FLYING_AUTO again"), "landing failed: the UAL reports FLYING_AUTO"),
    (("no_such_outcome", "what"), "its manager answered 'no_such_outcome': what"),
])
def test_every_aborted_action_state_keeps_its_reason_for_the_verdict(monkeypatch, answer, kept):
    monkeypatch.setattr(rospy, "get_time", lambda: 3.0)
    services = ScriptedManagers({(2, "land"): answer})
    state = RosStateFactory(services).action_state(2, "land", {}, "State_Machine[4]")
    assert state.execute({}) == "aborted"
    [failed] = services.failed_actions.all()
    assert (failed.uav_id, failed.action, failed.where) == (2, "land", "State_Machine[4]")
    assert kept in failed.reason


def test_actions_that_succeed_or_end_otherwise_leave_the_verdict_alone(monkeypatch):
    monkeypatch.setattr(rospy, "get_time", lambda: 3.0)
    for answer in [("succeeded", "landed"), ("preempted", "by the ground station"), ("collision", "uav_2")]:
        services = ScriptedManagers({(1, "land"): answer})
        assert RosStateFactory(services).action_state(1, "land", {}, "x").execute({}) == answer[0]
        assert services.failed_actions.all() == []
    assert judge_actions(True, "mission ended completed", []) == (True, "mission ended completed")


# --- live: one whole simulation ------------------------------------------------------------------------------------

LIVE_MISSION = ROOT / "tests" / "missions" / "Test" / "1UAV_Refused_Waypoint.json"
UMASK = 0o027


@pytest.mark.timeout(600)
def test_live_a_refused_waypoint_is_no_success_in_result_json_and_every_file_honours_the_umask(tmp_path):
    command = [str(ROOT / "magna"), "run", "--data-root", str(tmp_path), "--world", "Gym/Central_Obstacle_Torus",
               "--mission", str(LIVE_MISSION), "--n-iter", "1", "--rtf", "max", "--time-limit", "300"]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, stdin=subprocess.DEVNULL,
                          preexec_fn=lambda: os.umask(UMASK))
    assert done.returncode == 0, f"{done.stdout}\n{done.stderr}"
    [folder] = sorted(tmp_path.glob("Simulations/*/*/*/*/default/dataset_1/simulation_1"))
    result = json.loads((folder / "result.json").read_text())
    assert result["termination"] == "ground_station", result["message"]
    assert result["outcome"] == "completed" and result["success"] is False, result["message"]
    assert "aborted actions: UAV 1 basic_move aborted at" in result["message"], result["message"]
    assert "go_to_waypoint refused: UAV 1 is LANDED_ARMED; go_to_waypoint needs FLYING_AUTO" in result["message"]
    with (folder.parent / "summary.csv").open() as handle:
        [row] = list(csv.DictReader(handle))
    assert (row["success"], row["outcome"]) == ("False", "completed")
    assert result["leftover_processes_killed"] == []
    # every file and folder of the run, the bag and the logs too, as a plain open() or mkdir() gives them
    written = [p for p in tmp_path.rglob("*")]
    assert {"result.json", "summary.csv", "world.json", "mission.json", "uav_1.csv", "simulation.bag"} <= \
        {p.name for p in written}
    wrong = {str(p.relative_to(tmp_path)): oct(stat.S_IMODE(p.stat().st_mode)) for p in written
             if not p.is_symlink() and stat.S_IMODE(p.stat().st_mode) != (0o777 if p.is_dir() else 0o666) & ~UMASK}
    assert not wrong, f"not {0o640:o}/{0o750:o} under umask {UMASK:03o}: {wrong}"

