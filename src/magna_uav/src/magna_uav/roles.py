"""Roles: what a UAV does between a goal from the ground station and its outcome.

A role is pure logic. Each control step the manager hands it the WorldView and the
time; the role answers with a `RoleStep`: what to do now (fly to a goal through the
navigation algorithm, send a UAL waypoint, ask for a take-off or landing, wait while
the UAL manoeuvre runs, hover), how far along it is, and, when it ends, its outcome.
Collisions, low battery and ground-station events are the evaluator's business: the
manager ends the role with those outcomes.

A UAL command the server refuses ends the role `aborted` with the server's reason (the manager
catches the refusal). What the UAL accepts and then fails, or set-points it ignores (it takes them
only FLYING_AUTO), only the UAL state and the UAV's motion show; each role watches them and ends
`aborted` saying what it saw, never `succeeded`, and never waits for ever.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from magna_uav.nai.goal import Goal
from magna_uav.paths import WaypointTracker, smooth_path
from magna_uav.vocabulary import DIRECTIONS, DYNAMICS, direction_vector
from magna_uav.world_view import WorldView

# uav_abstraction_layer/State constants (kept here so the roles need no ROS)
UNINITIALIZED, LANDED_DISARMED, LANDED_ARMED, TAKING_OFF, FLYING_AUTO, FLYING_MANUAL, LANDING = 0, 1, 2, 3, 4, 5, 6
UAL_STATE_NAMES = ("UNINITIALIZED", "LANDED_DISARMED", "LANDED_ARMED", "TAKING_OFF", "FLYING_AUTO", "FLYING_MANUAL",
                   "LANDING")
LANDED = (LANDED_ARMED, LANDED_DISARMED)
# A UAL that has not yet got the UAV's position (UNINITIALIZED: magna_sim before its first step after a spawn,
# a real autopilot without a fix) refuses a take-off: the role waits this long (s of sim time) for it first.
UAL_READY_TIME = 10.0
# A take-off or landing the UAL accepted shows as TAKING_OFF or LANDING within this time (s of sim time); a
# state that is still the one before means the UAL gave the manoeuvre up. Seen again after TAKING_OFF or
# LANDING, it means so at once. Generous: a state message may come late on a loaded machine.
UAL_ACCEPT_TIME = 5.0
# A path whose current waypoint comes no nearer by STALL_PROGRESS metres in STALL_TIME seconds is stuck (an
# unreachable waypoint: inside an obstacle, or beyond what the airframe can turn into); it ends aborted.
STALL_TIME, STALL_PROGRESS = 120.0, 0.1

SUCCEEDED, ABORTED = "succeeded", "aborted"

# What the manager does with a step
FLY, WAYPOINT, TAKE_OFF, LAND, WAIT, HOVER = "fly", "waypoint", "take_off", "land", "wait", "hover"


def state_name(state: int) -> str:
    return UAL_STATE_NAMES[state] if 0 <= state < len(UAL_STATE_NAMES) else f"state {state}"


class Stall:
    """Watches a distance that should shrink (to a waypoint, to a height): stuck when it has come no nearer
    by STALL_PROGRESS for STALL_TIME. Every role that waits on motion ends with a reason, never flies on for ever.
    A new `leg` (the next waypoint) starts the watch again."""

    def __init__(self) -> None:
        self.leg: object = None
        self.best, self.since = math.inf, 0.0

    def stuck(self, leg: object, distance: float, elapsed: float) -> bool:
        if leg != self.leg or distance < self.best - STALL_PROGRESS:
            self.leg, self.best, self.since = leg, distance, elapsed
            return False
        return elapsed - self.since >= STALL_TIME


def not_flying(own, what: str) -> str:
    """Why `what` cannot be flown by set-points now ("" when it can): the UAL takes them only FLYING_AUTO and
    says nothing when it ignores one, so a role flying by set-points would wait for ever (or, following for a
    duration, claim success while the UAV sat on the ground). FLYING_MANUAL is the manager's business."""
    if own.ual_state in (FLYING_AUTO, FLYING_MANUAL):
        return ""
    if own.ual_state in LANDED:
        return f"the UAV is landed ({state_name(own.ual_state)}): {what} needs it flying (take off first)"
    return f"the UAL is {state_name(own.ual_state)}: {what} needs it FLYING_AUTO, and the UAL ignores set-points now"


class UalManoeuvre:
    """A take-off or landing the UAL accepted, watched through the UAL state (the only report the UAL gives):
    `failure` says why it failed ("" while it goes on). Shared, so both manoeuvres fail in the same cases.

    noun: "take-off" or "landing", for the messages; during: the state while it runs (TAKING_OFF, LANDING);
    before: the states it leaves (seen again after `during`, the UAL gave it up); interrupting: states that
    end it; blocked_from: where an obstacle would stop it ("above", "under"). `stuck` makes the message, from the
    nearest distance reached, when the distance left stops shrinking (Stall); called only then, so a control step
    formats no message it does not use."""

    def __init__(self, noun: str, during: int, before: tuple[int, ...], interrupting: tuple[int, ...],
                 blocked_from: str):
        self.noun, self.during, self.before, self.interrupting = noun, during, before, interrupting
        self.blocked_from = blocked_from
        self.asked_at = 0.0  # the role's elapsed time when it asked; moved to the answer's by `answered`
        self.accepted = False  # the UAL showed `during` since it was asked
        self.stall = Stall()

    def answered(self, elapsed: float) -> None:
        """The UAL's service answered at `elapsed`: its time to show the manoeuvre counts from here. A call
        that took long while simulated time ran on (a loaded machine) must not eat it."""
        self.asked_at = max(self.asked_at, elapsed)

    def failure(self, state: int, z: float, elapsed: float, distance_left: float, stuck: Callable[[float], str]) -> str:
        self.accepted = self.accepted or state == self.during
        if state in self.before:
            if self.accepted:
                return (f"{self.noun} failed: the UAL reports {state_name(state)} again at z = {z:.2f} m: it gave "
                        f"the {self.noun} up (its log says why)")
            if elapsed - self.asked_at >= UAL_ACCEPT_TIME:
                return (f"{self.noun} failed: the UAL still reports {state_name(state)} "
                        f"{elapsed - self.asked_at:.1f} s after it accepted the {self.noun}")
        elif state in self.interrupting:
            return f"{self.noun} interrupted: the UAL reports {state_name(state)} at z = {z:.2f} m"
        if self.stall.stuck(None, distance_left, elapsed):
            return (f"{stuck(self.stall.best)} in {STALL_TIME:g} s (UAL state {state_name(state)}): something "
                    f"{self.blocked_from} it, or the UAL holds it")
        return ""


@dataclass
class RoleStep:
    action: str  # FLY (NAI velocity to goal), WAYPOINT (UAL go_to_waypoint), TAKE_OFF, LAND, WAIT, HOVER
    goal: Goal | None = None
    percent: float = 0.0  # 0..100, for the action feedback
    outcome: str | None = None  # set on the last step: succeeded or aborted
    message: str = ""
    height: float = 0.0  # for TAKE_OFF


class Role(ABC):
    name = "role"

    def __init__(self, duration: float = 0.0):
        self.duration = float(duration)  # s; 0 = no limit (or: until preempted, for following roles)
        self.started: float | None = None

    def step(self, view: WorldView, now: float) -> RoleStep:
        if self.started is None:
            self.started = now
        return self._step(view, now, now - self.started)

    def timed_out(self, elapsed: float) -> bool:
        return self.duration > 0 and elapsed >= self.duration

    def ual_answered(self, now: float) -> None:  # noqa: B027 -- a hook: only the manoeuvring roles need it
        """The UAL's service answered this role's last request (a take-off, a landing) at simulated time `now`."""

    @abstractmethod
    def _step(self, view: WorldView, now: float, elapsed: float) -> RoleStep: ...


class ManoeuvreRole(Role):
    """A role that asks the UAL for a manoeuvre (`self.manoeuvre`) and gives it its time from the UAL's answer."""

    manoeuvre: UalManoeuvre

    def ual_answered(self, now: float) -> None:
        if self.started is not None:
            self.manoeuvre.answered(now - self.started)


class TakeOffRole(ManoeuvreRole):
    """Ask UAL for a take-off to `height` above the UAV, then wait for FLYING_AUTO at that height.

    It ends aborted, never succeeded, when the UAL refuses (the manager), gives the take-off up (the state is
    landed again, or never became TAKING_OFF), is interrupted (LANDING, UNINITIALIZED), or the UAV climbs no
    more (Stall: magna_sim keeps a blocked take-off TAKING_OFF for ever)."""

    name = "take_off"

    def __init__(self, height: float, tolerance: float = 0.3, duration: float = 0.0):
        super().__init__(duration)
        if not math.isfinite(height) or height <= 0:
            raise ValueError(f"take_off height is {height}: give a positive height in metres")
        self.height, self.tolerance = float(height), tolerance
        self.target_z: float | None = None
        self.manoeuvre = UalManoeuvre("take-off", TAKING_OFF, LANDED, (LANDING, UNINITIALIZED), "above")

    def _step(self, view, now, elapsed):
        own = view.own
        if self.target_z is None:
            if own.ual_state == FLYING_AUTO:
                return RoleStep(HOVER, percent=100.0, outcome=SUCCEEDED, message="already flying")
            if own.ual_state == UNINITIALIZED and elapsed < UAL_READY_TIME:
                return RoleStep(WAIT)  # asked now, the UAL would refuse; after UAL_READY_TIME it says why itself
            self.target_z, self.manoeuvre.asked_at = float(own.position[2]) + self.height, elapsed
            return RoleStep(TAKE_OFF, height=self.height, goal=Goal(position=own.position + [0, 0, self.height]))
        climbed = 100.0 * min(1.0, max(0.0, 1.0 - (self.target_z - own.position[2]) / self.height))
        if own.ual_state == FLYING_AUTO and abs(own.position[2] - self.target_z) <= self.tolerance:
            return RoleStep(HOVER, percent=100.0, outcome=SUCCEEDED, message=f"flying at {own.position[2]:.2f} m")
        failure = self._failure(own, elapsed)
        if failure:
            return RoleStep(HOVER, percent=climbed, outcome=ABORTED, message=failure)
        if self.timed_out(elapsed):
            return RoleStep(HOVER, percent=climbed, outcome=ABORTED, message=f"not up within {self.duration:g} s")
        return RoleStep(WAIT, percent=climbed)

    def _failure(self, own, elapsed: float) -> str:
        """Why the take-off the UAL accepted has failed ("" while it goes on)."""
        target_z = self.target_z
        assert target_z is not None  # asked before any failure is looked for
        z = float(own.position[2])
        # "something above it": magna_sim keeps a blocked take-off TAKING_OFF for ever
        return self.manoeuvre.failure(own.ual_state, z, elapsed, target_z - z,
                                      lambda best: f"take-off stuck: climbed no nearer than {best:.2f} m "
                                                   f"below {target_z:.2f} m")


class LandRole(ManoeuvreRole):
    """Ask UAL to land, then wait for a landed state. Aborted, never succeeded, when the UAL refuses (the
    manager), gives the landing up (FLYING_AUTO again, or never LANDING), is interrupted (TAKING_OFF,
    UNINITIALIZED), or the UAV comes down no more (Stall: a roof under it, the UAL holding it)."""

    name = "land"

    def __init__(self, duration: float = 0.0):
        super().__init__(duration)
        self.asked = False
        self.manoeuvre = UalManoeuvre("landing", LANDING, (FLYING_AUTO,), (TAKING_OFF, UNINITIALIZED), "under")

    def _step(self, view, now, elapsed):
        own = view.own
        if own.ual_state in LANDED:
            return RoleStep(WAIT, percent=100.0, outcome=SUCCEEDED, message="landed")
        if not self.asked:
            self.asked, self.manoeuvre.asked_at = True, elapsed
            return RoleStep(LAND)
        failure = self._failure(own, elapsed)
        if failure:
            return RoleStep(HOVER, outcome=ABORTED, message=failure)
        if self.timed_out(elapsed):
            return RoleStep(HOVER, outcome=ABORTED, message=f"not landed within {self.duration:g} s")
        return RoleStep(WAIT, percent=50.0 if own.ual_state == LANDING else 0.0)

    def _failure(self, own, elapsed: float) -> str:
        z = float(own.position[2])
        return self.manoeuvre.failure(own.ual_state, z, elapsed, z,
                                      lambda best: f"landing stuck: came no lower than z = {best:.2f} m")


class FollowPathRole(Role):
    """Waypoint by waypoint, each reached within the accepted radius on the UAV's own position.

    With smooth_path_mode n > 0 the UAV flies a spline of order n through the waypoints
    (velocity dynamic) and the waypoints are still checked one by one.
    """

    name = "path"

    def __init__(self, waypoints, accepted_radius: float, smooth_path_mode: int = 0, dynamic: str = "velocity",
                 duration: float = 0.0, lookahead: float = 1.0):
        super().__init__(duration)
        self.waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 3)
        if len(self.waypoints) == 0:
            raise ValueError("follow_path: the path has no waypoints")
        if dynamic not in ("velocity", "position"):
            raise ValueError(f"follow_path dynamic is {dynamic!r}: give 'position' or 'velocity'")
        self.dynamic = dynamic
        self.tracker = WaypointTracker(self.waypoints, accepted_radius)
        self.smoothed = smooth_path(self.waypoints, smooth_path_mode) if smooth_path_mode else self.waypoints
        self.smooth = bool(smooth_path_mode) and len(self.smoothed) > len(self.waypoints)
        self.lookahead = lookahead  # m along the smoothed path ahead of the UAV
        self.on_path = 0  # the smoothed sample the UAV was last placed at: it only moves forward
        self.sent_waypoint: int | None = None
        self.stall = Stall()  # on the current waypoint

    def _step(self, view, now, elapsed):
        own = view.own
        # By velocity the UAL ignores set-points unless FLYING_AUTO; by position it refuses the waypoint itself
        not_up = not_flying(own, "a path")
        if not_up and (elapsed == 0.0 or self.dynamic == "velocity"):
            return RoleStep(WAIT if elapsed == 0.0 else HOVER, outcome=ABORTED, message=not_up)
        self.tracker.update(own.position)
        percent = 100.0 * self.tracker.index / len(self.waypoints)
        if self.tracker.done:
            return RoleStep(HOVER, percent=100.0, outcome=SUCCEEDED,
                            message=f"{len(self.waypoints)} waypoints reached")
        if self.timed_out(elapsed):
            reached = f"{self.tracker.index} of {len(self.waypoints)} waypoints"
            return RoleStep(HOVER, percent=percent, outcome=ABORTED, message=f"{reached} within {self.duration:g} s")
        target = self.waypoints[self.tracker.index]
        stalled = self._stalled(float(np.linalg.norm(target - own.position)), elapsed)
        if stalled:
            return RoleStep(HOVER, percent=percent, outcome=ABORTED, message=stalled)
        if self.dynamic == "position":
            return RoleStep(WAYPOINT, goal=Goal(position=target), percent=percent)
        carrot = self._carrot(own.position, target) if self.smooth else target
        return RoleStep(FLY, goal=Goal(position=carrot), percent=percent)

    def _stalled(self, distance: float, elapsed: float) -> str:
        """Why the role is stuck ("" while it is not): no waypoint reached and the current one come no nearer
        than before for STALL_TIME. A mission must end with a reason, never fly on for ever."""
        if not self.stall.stuck(self.tracker.index, distance, elapsed):
            return ""
        return (f"stuck: waypoint {self.tracker.index + 1} of {len(self.waypoints)} came no nearer than "
                f"{self.stall.best:.2f} m in {STALL_TIME:g} s (accepted radius {self.tracker.accepted_radius:g} m)")

    def _carrot(self, position, target):
        """A point `lookahead` metres along the smoothed path past the point nearest the UAV,
        never past the current waypoint's sample (so no waypoint is skipped).

        Both are searched only from where the UAV was last placed on the path onwards (the original's path
        follower searched near its last place too): a path that turns back on itself, down to a delivery point
        and up again, passes twice by the same points, and the nearest sample of the whole path then swaps legs
        with millimetres of sideways drift, sending the UAV back down after each climb until the path ends stuck."""
        here = self.on_path
        # the waypoint's visit still to come: a path may visit the same point twice (before and after a delivery)
        limit = here + int(np.argmin(np.linalg.norm(self.smoothed[here:] - target, axis=1)))
        start = here + int(np.argmin(np.linalg.norm(self.smoothed[here:limit + 1] - position, axis=1)))
        self.on_path = start
        steps = np.linalg.norm(np.diff(self.smoothed[start:limit + 1], axis=0), axis=1)
        ahead = int(np.searchsorted(np.cumsum(steps), self.lookahead))
        if start + ahead >= limit:
            # the last stretch goes to the waypoint itself: the spline's nearest sample may lie farther from it
            # than the accepted radius, and aiming there the UAV would never reach it (seen circling for hours)
            return target
        return self.smoothed[start + ahead]


class FollowAgentAtDistanceRole(Role):
    """Keep `distance` metres from UAV `target_id`, on the line from it to us."""

    name = "agent_ad"

    def __init__(self, target_id: int, distance: float, duration: float = 0.0, lost_after: float = 2.0):
        super().__init__(duration)
        self.target_id, self.distance, self.lost_after = int(target_id), float(distance), lost_after

    def _step(self, view, now, elapsed):
        if self.target_id == view.own_id:
            return RoleStep(HOVER, outcome=ABORTED, message=f"UAV {self.target_id} cannot follow itself")
        not_up = not_flying(view.own, f"following UAV {self.target_id}")
        if not_up:  # followed "for its duration" on the ground would pass as a success
            return RoleStep(HOVER, outcome=ABORTED, message=not_up)
        target = view.agent(self.target_id)
        if target is None:
            if elapsed > self.lost_after:
                return RoleStep(HOVER, outcome=ABORTED, message=f"nothing heard from UAV {self.target_id}")
            return RoleStep(HOVER)
        if self.timed_out(elapsed):
            return RoleStep(HOVER, percent=100.0, outcome=SUCCEEDED, message=f"followed for {self.duration:g} s")
        away = view.own.position - target.position
        norm = float(np.linalg.norm(away))
        direction = away / norm if norm > 1e-6 else np.array([1.0, 0.0, 0.0])
        goal = Goal(position=target.position + direction * self.distance, velocity=target.velocity.copy(),
                    distance=self.distance, role="agent_ad")
        return RoleStep(FLY, goal=goal, percent=self._percent(elapsed))

    def _percent(self, elapsed):
        return 100.0 * min(1.0, elapsed / self.duration) if self.duration > 0 else 0.0


class FollowAgentAtPositionRole(FollowAgentAtDistanceRole):
    """Hold `offset` (map frame) from UAV `target_id`, aiming where it will be `prediction` seconds ahead
    (naive constant-velocity prediction; 0.3 s is about the lag of a multirotor reaching a new velocity)."""

    name = "agent_ap"

    def __init__(self, target_id: int, offset, duration: float = 0.0, prediction: float = 0.3,
                 lost_after: float = 2.0):
        super().__init__(target_id, 0.0, duration, lost_after)
        self.offset = np.asarray(offset, dtype=float).reshape(3)
        self.prediction = prediction  # s: naive constant-velocity prediction of the target

    def _step(self, view, now, elapsed):
        step = super()._step(view, now, elapsed)
        if step.action != FLY:
            return step
        target = view.agent(self.target_id)
        predicted = target.position + target.velocity * self.prediction
        step.goal = Goal(position=predicted + self.offset, velocity=target.velocity.copy(), offset=self.offset.copy(),
                         role="agent_ap")
        return step


class BasicMoveRole(Role):
    """Translation by `value` metres or rotation by `value` degrees, in a direction, by position or velocity.

    Directions: up/down along the map's z; forward/backward/left/right in the UAV's
    heading at the start. A rotation turns left (counter-clockwise) or right.
    """

    name = "basic_move"

    def __init__(self, move_type: str, direction: str, value: float, dynamic: str = "position", duration: float = 0.0,
                 accepted_radius: float = 0.3, accepted_angle: float = math.radians(5.0)):
        super().__init__(duration)
        if move_type not in ("translation", "rotation"):
            raise ValueError(f"basic_move move_type is {move_type!r}: give 'translation' or 'rotation' "
                             "(take-off and landing are their own roles)")
        if direction not in DIRECTIONS:
            raise ValueError(f"basic_move direction is {direction!r}: give one of {', '.join(DIRECTIONS)}")
        if move_type == "rotation" and direction not in ("left", "right"):
            raise ValueError(f"basic_move rotation direction is {direction!r}: give 'left' or 'right'")
        if dynamic not in DYNAMICS:
            raise ValueError(f"basic_move dynamic is {dynamic!r}: give 'position' or 'velocity'")
        self.move_type, self.direction, self.value, self.dynamic = move_type, direction, float(value), dynamic
        self.accepted_radius, self.accepted_angle = accepted_radius, accepted_angle
        self.goal: Goal | None = None
        self.start_position: np.ndarray | None = None
        self.stall = Stall()

    def _plan(self, own) -> Goal:
        yaw = own.yaw
        if self.move_type == "rotation":
            turn = math.radians(self.value) * (1.0 if self.direction == "left" else -1.0)
            return Goal(position=own.position.copy(), yaw=_wrap(yaw + turn), role="basic_move")
        unit = np.array(direction_vector(self.direction, yaw))
        return Goal(position=own.position + unit * self.value, yaw=yaw, role="basic_move")

    def _step(self, view, now, elapsed):
        own = view.own
        not_up = not_flying(own, f"a {self.move_type} by velocity")
        if self.dynamic == "velocity" and not_up:  # by position the UAL refuses the waypoint itself
            return RoleStep(HOVER, goal=self.goal, outcome=ABORTED, message=not_up)
        if self.goal is None:
            self.goal, self.start_position = self._plan(own), own.position.copy()
        if self.move_type == "rotation":
            left = abs(_wrap(self.goal.yaw - own.yaw))
            total = max(abs(math.radians(self.value)), 1e-9)
            percent, arrived = 100.0 * (1.0 - min(1.0, left / total)), left <= self.accepted_angle
        else:
            left = float(np.linalg.norm(self.goal.position - own.position))
            total = max(float(np.linalg.norm(self.goal.position - self.start_position)), 1e-9)
            percent, arrived = 100.0 * (1.0 - min(1.0, left / total)), left <= self.accepted_radius
        if arrived:
            return RoleStep(HOVER, goal=self.goal, percent=100.0, outcome=SUCCEEDED,
                            message=f"{self.move_type} {self.direction} {self.value:g} done")
        if self.timed_out(elapsed):
            return RoleStep(HOVER, goal=self.goal, percent=percent, outcome=ABORTED,
                            message=f"{self.move_type} not done within {self.duration:g} s")
        # a rotation's distance in radians: STALL_PROGRESS (0.1) is about 6 degrees
        if self.stall.stuck(None, left, elapsed):
            unit = "rad" if self.move_type == "rotation" else "m"
            return RoleStep(HOVER, goal=self.goal, percent=percent, outcome=ABORTED,
                            message=f"{self.move_type} stuck: {self.stall.best:.2f} {unit} short of its goal for "
                                    f"{STALL_TIME:g} s")
        return RoleStep(WAYPOINT if self.dynamic == "position" else FLY, goal=self.goal, percent=percent)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class OnBoardMissionRole(Role):
    """A mission handed to the UAV (set_mission): its roles one after the other.

    The next role starts when one succeeds; any other outcome ends the mission with it.
    """

    name = "set_mission"

    # PX4's mission mode takes a landed vehicle up to MIS_TAKEOFF_ALT (2.5 m by default) before the first item
    # that is not a take-off; the original's set_mission relied on it (it never asked for a take-off itself)
    IMPLICIT_TAKEOFF_HEIGHT = 2.5

    def __init__(self, roles: list[Role]):
        super().__init__(0.0)
        if not roles:
            raise ValueError("set_mission: the mission has nothing to do")
        self.roles, self.index = list(roles), 0

    def ual_answered(self, now: float) -> None:
        self.roles[self.index].ual_answered(now)  # the role that asked: a take-off or landing step never succeeds

    def _step(self, view, now, elapsed):
        if elapsed == 0.0 and view.own.ual_state in LANDED and not isinstance(self.roles[0], TakeOffRole):
            self.roles.insert(0, TakeOffRole(self.IMPLICIT_TAKEOFF_HEIGHT))
        step = self.roles[self.index].step(view, now)
        done_before = self.index
        percent = 100.0 * (done_before + step.percent / 100.0) / len(self.roles)
        if step.outcome == SUCCEEDED and self.index + 1 < len(self.roles):
            self.index += 1
            step.outcome, step.action = None, HOVER if step.action == HOVER else step.action
        step.percent = percent
        if step.outcome is not None:
            step.message = f"{self.roles[done_before].name}: {step.message}"
        return step
