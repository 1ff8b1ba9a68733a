"""Operator commands (keyboard, voice, GUI) -> what the ground station does, checked first.

`plan_command` turns one magna_msgs/GroundStationCommand (intent, action, agent,
parameters) into a `CommandPlan`: action goals for UAV managers, an algorithm change,
a mission pause or resume, or answers to a question. Every request is validated against
what the ground station knows (the UAVs of the mission, their last pose and UAL state, the
world's boundaries); a bad one raises `CommandRefused` with the reason, and nothing is sent.
A flight command needs the UAL state that lets the UAL carry it out (as magna_sim's and GRVC's
UAL guard their services): take off from LANDED_ARMED (also LANDED_DISARMED for a UAV whose UAL
arms it itself), land, move, turn and follow in FLYING_AUTO. Otherwise it is refused before
anything is sent, in a sentence a voice can speak ("UAV 1 is landing, so it cannot move"); a
command for "all" is refused whole, naming each UAV that cannot. The plan's message says what
will happen, from what the ground station knows ("UAV 2 climbing to 7 m").
A real UAV (Agents_Config mode real) takes no flight or algorithm command unless the mission
allows it (`"Operator_Commands": {"allow_real": [ids] | "all"}`): a command for it, alone or
among "all", is refused whole. Questions and mission-wide commands (standby, resume, critical)
reach every UAV. Pure: the node executes the plan.
"""
from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from magna_uav.roles import (
    FLYING_AUTO,
    FLYING_MANUAL,
    LANDED_ARMED,
    LANDED_DISARMED,
    LANDING,
    TAKING_OFF,
    UNINITIALIZED,
)
from magna_uav.vocabulary import DIRECTIONS as MOVE_DIRECTIONS
from magna_uav.vocabulary import Direction, direction_vector

INTENTS = ("basic_action", "mission", "parameters", "algorithms")
BASIC_ACTIONS = ("take_off", "land", "move", "turn", "follow")
DIRECTIONS = {*MOVE_DIRECTIONS, "x", "y", "z"}  # basic_move's, and along the world axes
ALGORITHMS = ("simple", "orca3", "orca3d", "neural_network")
QUERIES = ("battery", "state", "position")
# standby pauses the mission and resume goes on; critical raises the operator's critical event (every
# running role ends GS_critical_event and the mission takes its safety branches) until a resume.
MISSION_ACTIONS = ("standby", "resume", "critical")
MISSION_MESSAGES = {"standby": "mission paused", "resume": "mission resumed",
                    "critical": "critical event raised for every UAV until the mission is resumed"}
DEFAULT_FOLLOW_DISTANCE = 2.0  # m


class CommandRefused(ValueError):
    """A command the ground station will not carry out; the message says why."""


@dataclass(frozen=True)
class UavStatus:
    """What the ground station knows of one UAV."""

    id: int
    position: np.ndarray | None = None  # map frame, None before the first pose
    yaw: float = 0.0
    state: str = ""  # the manager's last reported state
    ual_state: int = 0  # uav_abstraction_layer/State (magna_uav.roles' constants); 0 also before the first message
    battery: float = math.nan  # 0..1
    arms_on_take_off: bool = False  # its UAL arms it for a take-off (ual_mavlink with arming auto)


@dataclass(frozen=True)
class Param:
    """A command parameter (magna_msgs/NamedValue): a number, a text or both."""

    name: str
    number: float = 0.0
    text: str = ""
    unit: str = ""


@dataclass
class ActionOrder:
    uav_id: int
    action: str  # take_off, land, basic_move, follow_agent_ad
    fields: dict  # goal fields
    says: str = ""  # what the UAV will do, after "UAV 1 ": "climbing to 7 m"
    verb: str = ""  # the operator's command as a verb: "move", "take off", "follow UAV 1"

    @property
    def sentence(self) -> str:
        return f"UAV {self.uav_id} {self.says}"


@dataclass
class CommandPlan:
    orders: list[ActionOrder] = field(default_factory=list)
    algorithm: tuple[str, list[int]] | None = None  # (name, uav ids)
    mission: str | None = None  # one of MISSION_ACTIONS
    answers: list[Param] = field(default_factory=list)
    message: str = ""


def plan_command(intent: str, action: str, agent: str, params: Sequence[Param], uavs: Mapping[int, UavStatus],
                 boundaries: np.ndarray | None = None, locked: Collection[int] = ()) -> CommandPlan:
    """The plan for one command, or CommandRefused naming what is wrong. `locked`: the real UAVs the mission does
    not let the operator command (Mission.operator_locked_ids)."""
    intent, action = intent.strip(), action.strip()
    by_name = {p.name: p for p in params}
    if intent == "mission":
        if action not in MISSION_ACTIONS:
            raise CommandRefused(f"mission action {action!r} is unknown: give {', '.join(MISSION_ACTIONS)}")
        return CommandPlan(mission=action, message=MISSION_MESSAGES[action])
    if intent not in INTENTS:
        raise CommandRefused(f"intent {intent!r} is unknown: give one of {', '.join(INTENTS)}")
    ids = _targets(agent, uavs)
    if intent == "parameters":
        if action != "get":
            raise CommandRefused(f"parameters action {action!r} is unknown: give get")
        return _answers(ids, by_name, uavs)
    _refuse_locked(ids, locked)
    if intent == "algorithms":
        if action != "set":
            raise CommandRefused(f"algorithms action {action!r} is unknown: give set")
        name = _text(by_name, "algorithm", ALGORITHMS)
        return CommandPlan(algorithm=(name, ids), message=f"algorithm {name} for {_who(ids)}")
    if action not in BASIC_ACTIONS:
        raise CommandRefused(f"basic action {action!r} is unknown: give take_off, land, move, turn or follow")
    _refuse_states(action, ids, uavs)
    orders = [_basic_action(action, uav_id, by_name, uavs, boundaries) for uav_id in ids]
    return CommandPlan(orders=orders, message=describe_orders(orders))


def describe_orders(orders: Sequence[ActionOrder]) -> str:
    """What the orders will do, UAVs doing the same thing together: "UAVs 1, 2 landing"."""
    together: dict[str, list[int]] = {}
    for order in orders:
        together.setdefault(order.says, []).append(order.uav_id)
    return "; ".join(f"{_who(ids)} {says}" for says, ids in together.items())


def _metres(value: float) -> str:
    """A position or height to say: a tenth of a metre, no trailing zeros (7, 2.5, -0.3)."""
    return f"{round(float(value), 1) + 0.0:g}"


def _amount(value: float) -> str:
    """A distance or angle the operator gave, as given (to a hundredth): 2, 0.25, 90."""
    return f"{round(float(value), 2) + 0.0:g}"


def _unable(action: str, uav: UavStatus) -> tuple[str, str] | None:
    """Why `uav` cannot `action` in its UAL state, as (what it is, what to do first), or None when it can."""
    state, who = uav.ual_state, f"UAV {uav.id}"
    if action == "take_off":
        if state == LANDED_ARMED or (state == LANDED_DISARMED and uav.arms_on_take_off):
            return None
    elif state == FLYING_AUTO:
        return None
    again = "already " if (action, state) in (("take_off", TAKING_OFF), ("take_off", FLYING_AUTO),
                                              ("land", LANDING), ("land", LANDED_ARMED),
                                              ("land", LANDED_DISARMED)) else ""
    if state == UNINITIALIZED:
        return f"{who}'s state is not known yet", ""
    if state in (LANDED_ARMED, LANDED_DISARMED):
        if action == "take_off":
            return f"{who} is on the ground disarmed", "arm it first"
        return f"{who} is {again}on the ground", "" if action == "land" else "take off first"
    if state == TAKING_OFF:
        return f"{who} is {again}taking off", "" if again else "wait until it is up"
    if state == FLYING_AUTO:
        return f"{who} is already flying", ""
    if state == FLYING_MANUAL:
        return f"{who} is flown by its pilot", ""
    if state == LANDING:
        return f"{who} is {again}landing", ""
    return f"{who} reports UAL state {state}", ""


def _refuse_states(action: str, ids: list[int], uavs: Mapping[int, UavStatus]) -> None:
    """A command some target cannot carry out in its UAL state: refused whole, naming each UAV and why."""
    unable = [why for why in (_unable(action, uavs[uav_id]) for uav_id in ids) if why is not None]
    if not unable:
        return
    states = [what for what, _ in unable]
    subject = states[0] if len(states) == 1 else ", ".join(states[:-1]) + " and " + states[-1]
    text = f"{subject}, so {'it' if len(unable) == 1 else 'they'} cannot {action.replace('_', ' ')}"
    hints = {hint for _, hint in unable}
    if len(hints) == 1 and "" not in hints:
        text += f": {hints.pop()}"
    if len(ids) > 1:
        text += "; nothing was sent"
    raise CommandRefused(text)


def _targets(agent: str, uavs: Mapping[int, UavStatus]) -> list[int]:
    agent = agent.strip().lower()
    if agent in ("all", "*"):
        if not uavs:
            raise CommandRefused("agent 'all': the mission has no UAVs yet")
        return sorted(uavs)
    try:
        uav_id = int(agent)
    except ValueError:
        raise CommandRefused(f"agent {agent!r} is not a UAV id or 'all'") from None
    if uav_id not in uavs:
        raise CommandRefused(f"UAV {uav_id} is not in this mission (UAVs: {', '.join(map(str, sorted(uavs)))})")
    return [uav_id]


def _refuse_locked(ids: list[int], locked: Collection[int]) -> None:
    """A flight or algorithm command for a real UAV the mission does not open to the operator: refused whole."""
    refused = [uav_id for uav_id in ids if uav_id in locked]
    if refused:
        which = ", ".join(map(str, refused))
        raise CommandRefused(f"{_who(refused)} {'is a real UAV' if len(refused) == 1 else 'are real UAVs'} and the "
                             "mission does not allow operator commands for "
                             f"{'it' if len(refused) == 1 else 'them'}; nothing was sent. To allow them, add "
                             f"\"Operator_Commands\": {{\"allow_real\": [{which}]}} to the mission")


def _who(ids: list[int]) -> str:
    return "UAV " + ", ".join(map(str, ids)) if len(ids) < 2 else "UAVs " + ", ".join(map(str, ids))


def _number(by_name: Mapping[str, Param], name: str, unit: str, default: float | None = None) -> float:
    param = by_name.get(name)
    if param is None:
        if default is None:
            raise CommandRefused(f"parameter {name!r} is missing: give it in {unit}")
        return default
    if param.unit and param.unit != unit:
        raise CommandRefused(f"parameter {name!r} is in {param.unit!r}: give it in {unit}")
    if not math.isfinite(param.number):
        raise CommandRefused(f"parameter {name!r} is {param.number}: give a finite number of {unit}")
    return float(param.number)


def _text(by_name: Mapping[str, Param], name: str, allowed: Sequence[str]) -> str:
    param = by_name.get(name)
    value = (param.text if param else "").strip().lower()
    if value not in allowed:
        raise CommandRefused(f"parameter {name!r} is {value!r}: give one of {', '.join(allowed)}")
    return value


def _inside(boundaries: np.ndarray | None, point: np.ndarray) -> bool:
    return boundaries is None or bool(np.all(point >= boundaries[:, 0]) and np.all(point <= boundaries[:, 1]))


def _where(uav: UavStatus) -> np.ndarray:
    if uav.position is None:
        raise CommandRefused(f"UAV {uav.id} has not reported a pose yet")
    return np.asarray(uav.position, dtype=float)


def _basic_action(action: str, uav_id: int, by_name, uavs, boundaries) -> ActionOrder:
    uav = uavs[uav_id]
    if action == "take_off":
        height = _number(by_name, "height", "m", 2.0)
        if height <= 0:
            raise CommandRefused(f"take-off height {height:g} m: give a positive height")
        top = _where(uav) + [0.0, 0.0, height]
        if not _inside(boundaries, top):
            raise CommandRefused(f"UAV {uav_id} taking off {height:g} m would reach z = {top[2]:.6g} m, above the "
                                 f"world's ceiling of {boundaries[2, 1]:g} m")
        return ActionOrder(uav_id, "take_off", {"height": height}, f"taking off to {_metres(top[2])} m", "take off")
    if action == "land":
        return ActionOrder(uav_id, "land", {}, "landing", "land")
    if action == "move":
        direction = _text(by_name, "direction", sorted(DIRECTIONS))
        distance = _number(by_name, "distance", "m")
        goal = _move_goal(direction, distance)
        # where the manager will take it: the goal's direction at the UAV's heading now (an axis move is flown
        # as the body direction it matches at zero yaw, see _move_goal)
        target = _where(uav) + np.array(direction_vector(cast(Direction, goal["direction"]), uav.yaw)) * goal["value"]
        if not _inside(boundaries, target):
            raise CommandRefused(f"UAV {uav_id} moving {distance:g} m {direction} would leave the world: "
                                 f"({', '.join(f'{v:.6g}' for v in target)}) is outside its boundaries")
        if goal["direction"] in ("up", "down"):
            says = f"{'climbing' if goal['direction'] == 'up' else 'descending'} to {_metres(target[2])} m"
        else:
            says = (f"moving {_amount(goal['value'])} m {goal['direction']} to "
                    f"({', '.join(_metres(v) for v in target)})")
        return ActionOrder(uav_id, "basic_move", goal, says, "move")
    if action == "turn":
        angle = _number(by_name, "angle", "deg")
        side = by_name["direction"].text.strip().lower() if "direction" in by_name else "left"
        if side not in ("left", "right"):
            raise CommandRefused(f"turn direction {side!r}: give left or right")
        if angle < 0:
            angle, side = -angle, "right" if side == "left" else "left"
        return ActionOrder(uav_id, "basic_move", {"move_type": "rotation", "dynamic": "position", "direction": side,
                                                  "value": angle, "duration": 0.0},
                           f"turning {_amount(angle)} degrees {side}", "turn")
    # follow (plan_command let only BASIC_ACTIONS through)
    target_param = by_name.get("target")
    if target_param is None:
        raise CommandRefused("parameter 'target' is missing: give the UAV to follow")
    target = _number_id(target_param.number) if not target_param.text else _parse_id(target_param.text)
    if target == uav_id:
        raise CommandRefused(f"UAV {uav_id} cannot follow itself")
    if target not in uavs:
        raise CommandRefused(f"UAV {target} to follow is not in this mission")
    distance = _number(by_name, "distance", "m", DEFAULT_FOLLOW_DISTANCE)
    if distance <= 0:
        raise CommandRefused(f"follow distance {distance:g} m: give a positive distance")
    return ActionOrder(uav_id, "follow_agent_ad", {"target_id": target, "distance": distance, "duration": 0.0},
                       f"following UAV {target} at {_amount(distance)} m", f"follow UAV {target}")


def _number_id(number: float) -> int:
    if not (math.isfinite(number) and number == int(number)):
        raise CommandRefused(f"target {number} is not a UAV id: give a whole number")
    return int(number)


def _parse_id(text: str) -> int:
    try:
        return int(text.strip().removeprefix("uav").strip("_ "))
    except ValueError:
        raise CommandRefused(f"target {text!r} is not a UAV id") from None


def _move_goal(direction: str, distance: float) -> dict:
    """A basic_move goal; axis moves become the body direction they match at zero yaw."""
    if direction in ("x", "y", "z"):
        direction = {"x": "forward", "y": "left", "z": "up"}[direction]
    if distance < 0:
        distance = -distance
        direction = {"up": "down", "down": "up", "left": "right", "right": "left", "forward": "backward",
                     "backward": "forward"}[direction]
    return {"move_type": "translation", "dynamic": "position", "direction": direction, "value": distance,
            "duration": 0.0}


def _answers(ids: list[int], by_name: Mapping[str, Param], uavs: Mapping[int, UavStatus]) -> CommandPlan:
    asked = [name for name in by_name if name in QUERIES] or ["state"]
    unknown = [name for name in by_name if name not in QUERIES]
    if unknown:
        raise CommandRefused(f"cannot tell {unknown[0]!r}: ask for one of {', '.join(QUERIES)}")
    answers = []
    for uav_id in ids:
        uav = uavs[uav_id]
        for name in asked:
            if name == "battery":
                answers.append(Param(f"uav_{uav_id}.battery", 100.0 * uav.battery, "", "%"))
            elif name == "state":
                answers.append(Param(f"uav_{uav_id}.state", 0.0, uav.state or "unknown", ""))
            else:
                position = _where(uav)
                for axis, value in zip("xyz", position, strict=True):
                    answers.append(Param(f"uav_{uav_id}.position.{axis}", float(value), "", "m"))
    return CommandPlan(answers=answers, message=", ".join(f"{a.name} {a.text or f'{a.number:.1f}{a.unit}'}"
                                                          for a in answers))
