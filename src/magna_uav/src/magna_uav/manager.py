"""The UAV manager's control loop: one role at a time, evaluated, flown and recorded each step.

Pure orchestration over injected parts, so it runs the same against magna_sim through
ROS (the node) and against a kinematic stand-in in unit tests:
  view        WorldView kept current by the data side (ros_data.RosWorldData)
  commander   the UAL calls (commanders.UalCommander): take_off, land, go_to_waypoint,
              set_velocity, hold_pose
  nai         NavigationInterface: the velocity towards a goal (simple, ORCA-3D, network)
  evaluator   collisions, boundaries, battery, ground-station events
  recorder    one row per control step
  clock       now() in sim seconds, and sleep() for one control period
  lock        held while a step reads the view (the data side writes it from callbacks)
"""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from magna_common.ual_commands import CommandRefused
from magna_uav.roles import FLY, FLYING_AUTO, FLYING_MANUAL, HOVER, LAND, TAKE_OFF, WAIT, WAYPOINT, Role, RoleStep

PREEMPTED = "preempted"
ABORTED = "aborted"
UTM_NEW_FLIGHTPLAN = "utm_new_flightplan"
# A safety pilot took the UAV (its UAL is FLYING_MANUAL: the autopilot left OFFBOARD/GUIDED). The role
# ends aborted with this event, whether or not it began so: nobody may command a UAV a pilot flies.
PILOT_TAKEOVER = "pilot_takeover"

# What ends a role when it newly appears, by priority, as the evaluator orders its outcomes.
_TROUBLES = (("collision", "collision"), ("out_of_bounds", ABORTED), ("GS_critical_event", "GS_critical_event"),
             ("low_battery", "low_battery"))

# How often (s of sim time) a waypoint is sent again while a role flies to it. The held pose goes
# out on the set_pose topic and the waypoint through a service; a hold published just before the
# role began can reach the UAL after the waypoint and replace it (seen under load: the UAV hovered
# until its battery ran low). Sent again, the waypoint wins within this period.
WAYPOINT_RESEND_PERIOD = 1.0

log = logging.getLogger("magna_uav.manager")


class Executed(NamedTuple):
    """One step as carried out, for the recorder."""

    velocity: np.ndarray  # commanded (zeros when the UAL autopilot flies)
    algorithm: str  # who chose it: a navigation algorithm, or "ual"
    feasible: bool | None = None  # ORCA's feasibility, when it said
    teacher_velocity: np.ndarray | None = None  # the teacher's answer while a network flies
    fallback: bool | None = None  # the teacher's answer was sent instead (None: no network flew)


@dataclass
class Clock:
    now: Callable[[], float]
    sleep: Callable[[], None]  # until the next control step


def troubles(evaluation) -> set[str]:
    """The evaluation's conditions as names: "collision:<what>" per open contact episode, and the flags.

    A contact lasts until its gap opens past the evaluator's release gap, so a gap that flickers
    around zero at the start of a role stays the contact the role started in, not a new one."""
    contacts = set(evaluation.collided_with) | set(getattr(evaluation, "in_contact", ()))
    found = {f"collision:{name}" for name in contacts}
    for flag, name in (("out_of_bounds", "out_of_bounds"), ("gs_critical", "GS_critical_event"),
                       ("low_battery", "low_battery")):
        if getattr(evaluation, flag):
            found.add(name)
    return found


def new_trouble(evaluation, standing: set[str]) -> str | None:
    """The outcome for conditions that appeared after the role started (None when there are none).

    Conditions already there when a role starts do not end it: the ground station sent that role
    knowing them (to separate two UAVs in contact, to land on a low battery, a safety branch).
    `standing` forgets a condition once it clears, so it ends the role if it comes back."""
    now = troubles(evaluation)
    standing &= now
    fresh = now - standing
    for prefix, outcome in _TROUBLES:
        if any(name.split(":")[0] == prefix for name in fresh):
            return outcome
    return None


@dataclass
class RoleResult:
    outcome: str
    message: str
    steps: int = 0
    events: list[str] = field(default_factory=list)  # critical events seen (collision, low_battery, ...)


class UavManager:
    def __init__(self, view, commander, nai, evaluator, recorder, clock: Clock, lock=None):
        self.view, self.commander, self.nai = view, commander, nai
        self.evaluator, self.recorder, self.clock = evaluator, recorder, clock
        self.lock = lock if lock is not None else contextlib.nullcontext()
        self.gs_critical_event = False  # set by the ground station (critical event) between steps
        self.role_name = "idle"
        self._hold: tuple[np.ndarray, float] | None = None  # pose held while hovering
        self._sent_waypoint: tuple[np.ndarray, float] | None = None  # (target, sim time sent)

    def run_role(self, role: Role, preempt_requested: Callable[[], bool] = lambda: False,
                 feedback: Callable[[RoleStep], None] = lambda step: None,
                 superseded: Callable[[], bool] = lambda: False) -> RoleResult:
        """Fly `role` until it ends, the evaluator stops it, or the ground station preempts it.

        `superseded()` true ends it with utm_new_flightplan: the UTM changed the plan it flies."""
        self.role_name, self._hold, self._sent_waypoint = role.name, None, None
        steps = 0
        standing: set[str] | None = None  # conditions present when the role started
        try:
            while True:
                if preempt_requested():
                    self._hover()
                    return RoleResult(PREEMPTED, f"{role.name} preempted by the ground station", steps)
                if superseded():
                    self._hover()
                    return RoleResult(UTM_NEW_FLIGHTPLAN, "the UTM issued a new flight plan", steps)
                now = self.clock.now()
                if self._pilot_flies():
                    return RoleResult(ABORTED, f"{role.name}: UAV {self.view.own_id} is out of MAGNA's hands: its UAL "
                                               f"is FLYING_MANUAL (a safety pilot took it over, or its autopilot "
                                               f"left OFFBOARD/GUIDED on a failsafe); MAGNA no longer commands it",
                                      steps, [PILOT_TAKEOVER])
                with self.lock:
                    evaluation = self.evaluator.step(self.view, self.gs_critical_event)
                    if standing is None:
                        standing = troubles(evaluation)
                    outcome = new_trouble(evaluation, standing)
                    if outcome is not None:
                        self._hover()
                        self._record(now, None, Executed(np.zeros(3), "ual"), evaluation, outcome)
                        return RoleResult(outcome, evaluation.reason, steps + 1, [outcome])
                    step = role.step(self.view, now)
                    try:
                        executed = self._execute(step, now)
                        if step.action in (TAKE_OFF, LAND):  # the UAL's time to show it runs from its answer
                            role.ual_answered(self.clock.now())
                    except CommandRefused as refusal:  # never a success: the action ends aborted, saying why
                        step.outcome, step.message = ABORTED, f"{role.name}: UAL refused: {refusal}"
                        self._hover()
                        executed = Executed(np.zeros(3), "ual")
                    self._record(now, step.goal, executed, evaluation, step.outcome or "")
                steps += 1
                feedback(step)
                if step.outcome is not None:
                    return RoleResult(step.outcome, step.message, steps)
                self.clock.sleep()
        finally:
            self.role_name = "idle"

    def _pilot_flies(self) -> bool:
        with self.lock:
            return self.view.has_own and self.view.own.ual_state == FLYING_MANUAL

    def hover(self) -> None:
        """Hold the current pose (between roles, and after one ends)."""
        self._hold = None
        self._hover()

    def _execute(self, step: RoleStep, now: float) -> Executed:
        """Carry out one step; what was commanded, for the recorder."""
        if step.action == FLY:
            command = self.nai.velocity(self.view, step.goal)
            self._hold = None
            self.commander.set_velocity(command.velocity, command.yaw_rate)
            teacher = command.teacher_velocity
            return Executed(np.asarray(command.velocity, dtype=float), command.algorithm, command.feasible,
                            teacher, None if teacher is None else command.fallback)
        if step.action == WAYPOINT:
            assert step.goal is not None, "a waypoint step without its waypoint"  # every role gives one
            target = np.asarray(step.goal.position, dtype=float)
            self._hold = None  # a later hover holds where the UAV is then, not where it was before
            sent = self._sent_waypoint
            if sent is None or not np.allclose(target, sent[0]) or now - sent[1] >= WAYPOINT_RESEND_PERIOD:
                self.commander.go_to_waypoint(target, step.goal.yaw if step.goal.yaw is not None else self.view.own.yaw)
                self._sent_waypoint = (target, now)
        elif step.action == TAKE_OFF:
            self.commander.take_off(step.height)
        elif step.action == LAND:
            self.commander.land()
        elif step.action == HOVER:
            self._hover()
        elif step.action != WAIT:
            raise ValueError(f"role step action {step.action!r} is unknown")
        return Executed(np.zeros(3), "ual")

    def keep_hovering(self) -> None:
        """Send the held pose again: a velocity command still in flight on another topic when the
        hover began would otherwise carry the UAV away for its timeout."""
        if self._hold is not None and self.view.has_own and self.view.own.ual_state == FLYING_AUTO:
            self.commander.hold_pose(*self._hold)

    def _hover(self) -> None:
        # Only a flying UAV can hold a pose (UAL refuses set_pose on the ground, during take-off or landing).
        if not self.view.has_own or self.view.own.ual_state != FLYING_AUTO:
            return
        if self._hold is None:
            own = self.view.own
            self._hold = (own.position.copy(), own.yaw)
        self._sent_waypoint = None
        self.commander.hold_pose(*self._hold)

    def _record(self, now, goal, executed: Executed, evaluation, outcome) -> None:
        if self.recorder is None or not self.view.has_own:
            return
        goal_position = goal.position if goal is not None else np.full(3, np.nan)
        self.recorder.record(now, self.role_name, executed.algorithm, goal_position, executed.velocity, self.view,
                             evaluation=evaluation, feasible=executed.feasible, outcome=outcome,
                             teacher_velocity=executed.teacher_velocity, fallback=executed.fallback,
                             goal_velocity=None if goal is None else goal.velocity,
                             goal_distance=None if goal is None else goal.distance)
