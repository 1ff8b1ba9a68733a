"""Entities -> the ground station's command, or the question to ask back: the second half of understanding.

The command has the fields of magna_msgs/GroundStationCommand (intent, action, agent, parameters)
with numbers already converted to meters and degrees. Whatever is missing or unsure (no UAV named,
no distance, a word read with low confidence) becomes a `Question` instead of a guess.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from magna_gs.commands import Param as Parameter  # the ground station's own magna_msgs/NamedValue
from voice import vocabulary as vocab
from voice.entities import Entity, Understanding, understand

MIN_CONFIDENCE = 0.85  # a word read through a typo of similarity 0.80-0.85 is confirmed first
LENGTH, ANGLE = "m", "deg"


def parameter_json(p: Parameter) -> dict:
    return {"name": p.name, "number": p.number, "text": p.text, "unit": p.unit}


@dataclass(frozen=True)
class Command:
    intent: str
    action: str
    agent: str  # UAV id as text, or "all"
    parameters: tuple[Parameter, ...] = ()
    confidence: float = 1.0

    def to_json(self) -> dict:
        return {"intent": self.intent, "action": self.action, "agent": self.agent,
                "parameters": [parameter_json(p) for p in self.parameters]}

    def describe(self) -> str:
        who = "all UAVs" if self.agent == "all" else f"UAV {self.agent}"
        if self.intent == "mission":
            return f"mission {self.action}"
        details = ", ".join(_said(p) for p in self.parameters)
        return f"{who}: {self.action.replace('_', ' ')}" + (f" ({details})" if details else "")


@dataclass(frozen=True)
class Question:
    text: str
    missing: str  # identity, action, direction, number, algorithm, confirmation
    partial: dict = field(default_factory=dict)  # what was understood so far

    def to_json(self) -> dict:
        return {"text": self.text, "missing": self.missing}


def wit_entities(u: Understanding, result: Command | Question) -> dict:
    """The entities as WIT returned them, with the intent the sentence was read as."""
    action = result.action if isinstance(result, Command) else result.partial.get("action")
    out = {}
    if action in vocab.INTENT_OF_ACTION:
        confidence = result.confidence if isinstance(result, Command) else 1.0
        out["intent"] = [{"value": vocab.INTENT_OF_ACTION[action], "confidence": round(confidence, 3)}]
    out.update(u.to_json())
    return out


def parse(sentence: str, uav_ids: Iterable[int] = ()) -> tuple[Understanding, Command | Question]:
    understanding = understand(sentence)
    return understanding, interpret(understanding, uav_ids)


def interpret(u: Understanding, uav_ids: Iterable[int] = ()) -> Command | Question:
    """The first reading that makes a whole command; else the question of the first reading.

    A sentence may hold more than one verb ("come down and land", "go back to the simple
    algorithm"): each is tried in order, then the action implied without a verb, then the asking verbs."""
    ids = sorted(set(uav_ids))
    candidates = _candidate_actions(u)
    if not candidates:
        heard = f" (I heard: {' '.join(u.not_understood)})" if u.not_understood else ""
        return Question(f"Sorry, what should I do?{heard} Say for example 'drone one, take off'.", "action")
    first_question = None
    for action, entity in candidates:
        result = _reading(u, action, entity, ids)
        if isinstance(result, Command):
            return _confident(result)
        first_question = first_question or result
    assert first_question is not None  # candidates is not empty, and each reading is a command or a question
    return first_question


def _reading(u: Understanding, action: str, action_entity: Entity | None, ids: list[int]) -> Command | Question:
    used: list[Entity] = [action_entity] if action_entity else []
    if action in ("standby", "resume"):
        return Command("mission", action, "all", (), _confidence(used))
    if action == "get" and action_entity and not u.of("parameter") and u.not_understood:  # "what's the weather like"
        return Question(f"Sorry, I can tell the battery, state or position of a UAV, not "
                        f"'{' '.join(u.not_understood)}'.", "parameter", {"action": "get"})
    agent, agent_entities = _agent(u, action)
    if agent is None:
        return Question(f"Which UAV should {_verb(action)}: {_choices(ids)}?", "identity", {"action": action})
    used += agent_entities
    builder = {"take_off": _take_off, "land": _land, "move": _move, "turn": _turn, "follow": _follow,
               "get": _get, "set": _set}[action]
    outcome = builder(u, agent, ids)
    if isinstance(outcome, Question):
        return outcome
    parameters, entities = outcome
    used += entities
    return Command(vocab.INTENT_OF_ACTION[action], action, agent, tuple(parameters), _confidence(used))


# --- what to do --------------------------------------------------------------------------------
def _candidate_actions(u: Understanding) -> list[tuple[str, Entity | None]]:
    """The readings to try, in order: verbs as said, a move or turn implied by a number without a verb,
    mission verbs ("proceed forward seven meters" is a move), an action a noun implies (algorithm,
    battery), asking verbs; a yes/no question first of all."""
    actions = u.of("action")
    mission = [(e.text_value, e) for e in actions if e.value in ("standby", "resume")]
    weak = [(e.text_value, e) for e in actions if e.value == "get"]
    out: list[tuple[str, Entity | None]] = [(e.text_value, e) for e in actions
                                             if e.value not in ("get", "standby", "resume")]
    implied = _implied_action(u)
    if implied in ("move", "turn") and not out:  # a bare number and unit: only beside no other verb
        out.append((implied, None))
    out += mission
    if implied in ("set", "get"):  # a noun names its action ("go back to the simple algorithm")
        out.append((implied, None))
    out += weak
    if _asks_yes_or_no(u):  # "is drone two airborne?", "drone two, are you still in the air?"
        out.insert(0, ("get", None))
    seen, unique = set(), []
    for action, entity in out:
        if action not in seen:
            seen.add(action)
            unique.append((action, entity))
    return unique


def _asks_yes_or_no(u: Understanding) -> bool:
    identities = u.of("identity")
    if not identities:
        return False
    first = identities[0].end if identities[0].start == 0 else 0  # after a leading "drone two,"
    return first < len(u.tokens) and u.tokens[first] in vocab.YES_NO_OPENERS


def _main_action(u: Understanding) -> Entity | None:
    """The verb that commands; asking verbs only when there is no other ("tell drone one to land")."""
    actions = u.of("action")
    strong = [e for e in actions if e.value != "get"]
    found = strong or actions
    return found[0] if found else None


def _implied_action(u: Understanding) -> str | None:
    """No verb: "drone two, up five meters" is a move; "drone one, ninety degrees left" a turn."""
    if u.first("algorithm"):
        return "set"
    if u.first("parameter"):
        return "get"
    unit = u.first("unit")
    if unit is not None and unit.unit == ANGLE:
        return "turn"
    if u.first("direction") and (u.first("number") or unit):
        return "move"
    return None


def _agent(u: Understanding, action: str) -> tuple[str | None, list[Entity]]:
    agents = [e for e in u.of("identity") if e.role != "target"]
    if not agents:
        return None, []
    values = {e.value for e in agents}
    if action == "follow" and len(values) == 2 and "all" not in values:  # "drone one, lock on to drone two"
        return agents[0].text_value.removeprefix("uav_"), agents[:1]
    if "all" in values:
        return "all", agents
    if len(values) > 1:
        return None, []
    return agents[0].text_value.removeprefix("uav_"), agents


# --- the numbers ----------------------------------------------------------------------------------
def _quantities(u: Understanding) -> list[tuple[float, Entity, Entity | None]]:
    """Every number with the unit said right after it (or None): (value in m or deg, number, unit)."""
    units = {e.start: e for e in u.of("unit")}
    out = []
    for number in u.of("number"):
        unit = units.get(number.end)
        value = number.number_value * (unit.factor if unit else 1.0)
        out.append((round(value, 6), number, unit))
    return out


def _quantity(u: Understanding, kind: str, skip: Iterable[Entity] = ()) -> tuple[float, list[Entity]] | None:
    """The first number of a length (kind "m") or an angle ("deg"); a bare number counts as either."""
    skipped = set(id(e) for e in skip)
    for value, number, unit in _quantities(u):
        if id(number) in skipped:
            continue
        if unit is None or unit.unit == kind:
            return value, [number] + ([unit] if unit else [])
    return None


def _number_question(action: str, agent: str, what: str) -> Question:
    return Question(f"How {what} should {_who(agent)} {_verb(action)}?", "number", {"action": action, "agent": agent})


def _take_off(u, agent, ids):
    found = _quantity(u, LENGTH)
    if found is None:
        if _angles_only(u):
            return Question("A take-off height is a length: how many meters?", "number")
        return [], []
    height, entities = found
    return [Parameter("height", height, "", LENGTH)], entities


def _land(u, agent, ids):
    return [], []


def _move(u, agent, ids):
    direction = _direction(u, exclude=())
    if direction is None:
        return Question(f"Which way should {_who(agent)} move: up, down, left, right, forward or backward?",
                        "direction", {"action": "move", "agent": agent})
    found = _quantity(u, LENGTH)
    if found is None:
        return _number_question("move", agent, f"many meters {direction.value}")
    distance, entities = found
    return [Parameter("direction", 0.0, direction.value), Parameter("distance", distance, "", LENGTH)], \
        [direction] + entities


def _direction(u: Understanding, exclude) -> Entity | None:
    directions = [e for e in u.of("direction") if e.value not in exclude]
    return directions[0] if directions else None


def _turn(u, agent, ids):
    found = _quantity(u, ANGLE)
    if found is None:
        return _number_question("turn", agent, "many degrees")
    angle, entities = found
    side = next((e for e in u.of("direction") if e.value in vocab.TURN_SIDES), None)
    parameters = [Parameter("angle", angle, "", ANGLE)]
    if side is not None:
        parameters.append(Parameter("direction", 0.0, side.value))
        entities.append(side)
    return parameters, entities


def _follow(u, agent, ids):
    targets = [e for e in u.of("identity") if e.role == "target"]
    named = [e for e in u.of("identity") if e.value not in ("all", f"uav_{agent}")]
    if not targets and named:  # the other UAV named, even if not right after the verb
        targets = named[:1]
    target_entities = targets[:1]
    if targets:
        target = int(targets[0].value.removeprefix("uav_"))
        used_numbers = []
    else:  # "drone two, follow one": a bare number right after the verb
        verb = _main_action(u)
        bare = next((e for e in u.of("number") if verb and e.start == verb.end and e.value == int(e.value)), None)
        if bare is None:
            return Question(f"Which UAV should {_who(agent)} follow?", "identity", {"action": "follow", "agent": agent})
        target, used_numbers, target_entities = int(bare.value), [bare], [bare]
    parameters = [Parameter("target", float(target))]
    found = _quantity(u, LENGTH, skip=used_numbers)
    entities = list(target_entities)
    if found is not None:
        parameters.append(Parameter("distance", found[0], "", LENGTH))
        entities += found[1]
    return parameters, entities


def _get(u, agent, ids):
    names, entities = [], []
    for e in u.of("parameter"):
        if e.value not in names:
            names.append(e.value)
            entities.append(e)
    return [Parameter(name) for name in names or ["state"]], entities


def _set(u, agent, ids):
    algorithm = u.first("algorithm")
    if algorithm is None:
        return Question(f"Which algorithm should {_who(agent)} use: simple guidance, ORCA-3D or the neural network?",
                        "algorithm", {"action": "set", "agent": agent})
    return [Parameter("algorithm", 0.0, algorithm.value)], [algorithm]


def _angles_only(u: Understanding) -> bool:
    return any(unit is not None and unit.unit == ANGLE for _, _, unit in _quantities(u))


def _said(p: Parameter) -> str:
    if p.text:
        return f"{p.name} {p.text}"
    if p.unit:
        return f"{p.name} {p.number:g} {p.unit}"
    return p.name if p.number == 0 else f"{p.name} {p.number:g}"


# --- wording ------------------------------------------------------------------------------------------
def _confidence(entities: list[Entity]) -> float:
    return min((e.confidence for e in entities), default=1.0)


def _confident(command: Command) -> Command | Question:
    if command.confidence >= MIN_CONFIDENCE:
        return command
    return Question(f"Did you mean: {command.describe()}? I am not sure (confidence {command.confidence:.2f}); "
                    "please say it again.", "confirmation", command.to_json())


def _who(agent: str) -> str:
    return "all UAVs" if agent == "all" else f"UAV {agent}"


def _verb(action: str) -> str:
    return {"take_off": "take off", "get": "report", "set": "change its algorithm"}.get(action, action)


def _choices(ids: list[int]) -> str:
    if not ids:
        return "say 'drone' and its number, or 'all drones'"
    return ", ".join(f"drone {i}" for i in ids) + " or all drones"
