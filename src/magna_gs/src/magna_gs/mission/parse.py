"""Migrated mission JSON -> `model.Mission`, checking every field once.

Every problem is collected (not only the first) and reported together as one
`MissionError`, each line `file: JSON.path: what is wrong; what to write instead`.
Paths are the file's own (keys renamed by the migration are mapped back). Keys a
state does not use are warnings: the original ignored them, and real missions carry some.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from numbers import Integral, Real
from pathlib import Path
from typing import Any

from magna_gs.mission.migrate import AGENTS_KEY, LEGACY_AGENTS_KEY, Migration
from magna_gs.mission.model import (
    ACTION_TYPES,
    CALLBACK_TYPES,
    CONTAINER_TYPES,
    DIRECTIONS,
    DYNAMICS,
    EXIT_TYPES,
    FROM_HYPERPARAMETERS,
    FROM_UTM,
    IDS_VARS,
    MOVE_TYPES,
    NODE_TYPES,
    POSE_KINDS,
    WORLD_ACTIONS,
    AlgorithmControlParams,
    BasicMoveParams,
    FollowAgentADParams,
    FollowAgentAPParams,
    FollowPathParams,
    LandParams,
    Mission,
    MissionError,
    Node,
    Parameters,
    PoseDefinition,
    SaveCsvParams,
    SetMissionParams,
    SpawnAgentsParams,
    TakeOffParams,
    WaitParams,
    WorldConfigParams,
    WorldPartDef,
)

NODE_KEYS = ("type", "name", "state_type", "parameters", "outcomes", "ids", "ids_var", "occurrencies",
             "occurrencies_outcome_map", "outcome_cb", "child_termination_cb", "connector_outcome")
UTM_KEY = "UTM"  # optional: the mission's own UTM flight plans (magna_gs.utm), or the name of a plan file
TOP_KEYS = (AGENTS_KEY, "State_Machine", UTM_KEY)
_MISSING = object()


class _Reader:
    """Collects problems and warnings with file and (original) JSON path."""

    def __init__(self, source: str, migration: Migration):
        self.source = source
        self.migration = migration
        self.problems: list[str] = []
        self.warnings: list[str] = []
        self.complete = True  # False once a node or the agents could not be read at all
        self.parameter_problems = 0  # how many of the problems are in parameters (the node is kept)

    def where(self, path: str) -> str:
        path = self.migration.original_path(path)
        return f"{self.source}: {path}" if path else self.source

    def fail(self, path: str, message: str) -> None:
        self.problems.append(f"{self.where(path)}: {message}")

    def warn(self, path: str, message: str) -> None:
        self.warnings.append(f"{self.where(path)}: {message}")


@dataclass
class Parsed:
    mission: Mission
    warnings: list[str]
    problems: list[str]  # each `file: JSON.path: message`
    complete: bool  # every node and agent was read (bad parameters aside): structural checks are meaningful


def parse_mission(migration: Migration, source: str, airframe_dir: Path | None = None) -> Parsed:
    """The mission read from migrated data, with every problem found. A node whose only problems are in its
    parameters is kept (parameters None), so the structure can still be checked; MissionError when the data is
    not a mission at all."""
    reader = _Reader(source, migration)
    data = migration.data
    if not isinstance(data, dict):
        raise MissionError(f"{source}: the top level must be an object {{\"{AGENTS_KEY}\": [...], "
                           f"\"State_Machine\": [...]}}, got {_kind(data)}")
    for key in data:
        if key not in TOP_KEYS and key != LEGACY_AGENTS_KEY:  # both agent keys: _agents says so
            reader.fail(str(key), f"unknown key{_hint(key, (*TOP_KEYS, LEGACY_AGENTS_KEY))}; a mission has "
                                  f"{AGENTS_KEY} and State_Machine (and optionally {UTM_KEY}, its flight plans)")
    if UTM_KEY in data:
        _utm(reader, data)
    agents, agents_key = _agents(reader, airframe_dir)
    root: list[Node] = []
    if "State_Machine" not in data:
        reader.fail("State_Machine", "missing; list the mission's states here ([{\"type\": \"CBState\", ...}, ...])")
    elif not isinstance(data["State_Machine"], list) or not data["State_Machine"]:
        reader.fail("State_Machine", f"expected a non-empty list of states, got {_kind(data['State_Machine'])}")
    else:
        for index, raw in enumerate(data["State_Machine"]):
            node = _node(reader, raw, f"State_Machine[{index}]")
            if node is not None:
                root.append(node)
    if not root:
        reader.complete = False
    return Parsed(Mission(source, agents, root, agents_key), reader.warnings, reader.problems, reader.complete)


def _utm(reader: _Reader, data: dict) -> None:
    """The mission's UTM section is checked now, as the ground station would check it before flying."""
    from magna_gs.utm import UtmPlanError, mission_plan

    try:
        mission_plan(data, reader.source)
    except UtmPlanError as error:
        reader.problems.append(" ".join(str(error).split()))


def _agents(reader: _Reader, airframe_dir: Path | None):
    from magna_uav.config import ConfigError, configs_from_mission

    original = reader.migration.original
    if not isinstance(original, dict):  # a state list: the migration wrote the agents
        original = reader.migration.data
    key = LEGACY_AGENTS_KEY if isinstance(original, dict) and LEGACY_AGENTS_KEY in original else AGENTS_KEY
    if isinstance(original, dict) and AGENTS_KEY in original and LEGACY_AGENTS_KEY in original:
        reader.fail(LEGACY_AGENTS_KEY, f"give the agents once, under {AGENTS_KEY} (not also under the legacy "
                                       f"{LEGACY_AGENTS_KEY})")
        return [], AGENTS_KEY
    if AGENTS_KEY not in reader.migration.data:
        reader.fail(AGENTS_KEY, "missing; list the agents: [{\"ID\": 1, \"model\": \"iris\", \"mode\": \"sitl\", "
                                "\"marker_color\": [255, 0, 0, 0.5]}, ...]")
        return [], key
    raw = _tolerated_agent_entries(reader, original[key], key)
    try:
        kwargs = {} if airframe_dir is None else {"airframe_dir": airframe_dir}
        agents = configs_from_mission(raw, reader.source, key, **kwargs)
    except ConfigError as error:
        reader.problems.append(str(error))
        reader.complete = False
        return [], key
    if not agents:
        reader.fail(key, "no agents; a mission needs at least one ({\"ID\": 1, \"model\": \"iris\", ...})")
    return agents, key


# Keys of the DJI airframe a mission entry could override in the original (its launch file read them); MAGNA's
# simulated and MAVLink UAVs have no such settings.
IGNORED_AGENT_KEYS = {"laser_altimeter": "the DJI autopilot's laser altimeter switch",
                      "self_arming": "the DJI autopilot's self-arming switch"}


def _tolerated_agent_entries(reader: _Reader, raw: Any, key: str) -> Any:
    """The agent entries with what the original tolerated in them made explicit, each with a warning: DJI-only keys
    dropped, and an ID given twice replaced by the entry's position (the original numbered agents by position)."""
    if not isinstance(raw, list):
        return raw
    entries = [dict(entry) if isinstance(entry, dict) else entry for entry in raw]
    for index, entry in enumerate(entries):
        if not isinstance(entry, dict):
            continue
        for name, what in IGNORED_AGENT_KEYS.items():
            if name in entry:
                del entry[name]
                reader.warn(f"{key}[{index}].{name}", f"{what}; MAGNA's UAVs have no such setting, ignored")
    ids = [e.get("ID") if isinstance(e, dict) else None for e in entries]
    for index, entry in enumerate(entries):
        agent_id = ids[index]
        if not _is_int(agent_id) or agent_id not in ids[:index]:
            continue
        position = index + 1
        if position in ids:  # the position is another agent's ID: no faithful reading; the config check refuses it
            continue
        entry["ID"] = ids[index] = position
        reader.warn(f"{key}[{index}].ID", f"{agent_id} is already the ID of {key}[{ids.index(agent_id)}]; the "
                                          f"original ignored ID and numbered agents by position, so this one is "
                                          f"agent {position} (give it \"ID\": {position})")
    return entries


# --- nodes ---------------------------------------------------------------------------------------------------------

def _node(reader: _Reader, raw: Any, path: str) -> Node | None:
    if not isinstance(raw, dict):
        reader.fail(path, f"expected a state object {{\"type\": ..., \"name\": ...}}, got {_kind(raw)}")
        return None
    problems_before, parameter_problems_before = len(reader.problems), reader.parameter_problems
    for key in raw:
        if key not in NODE_KEYS:
            reader.fail(f"{path}.{key}", f"unknown key{_hint(key, NODE_KEYS)}; a state has {', '.join(NODE_KEYS)}")
    kind = raw.get("type", _MISSING)
    if kind is _MISSING:
        reader.fail(f"{path}.type", f"missing; give one of {', '.join(NODE_TYPES)}")
        reader.complete = False
        return None
    if kind not in NODE_TYPES:
        reader.fail(f"{path}.type", f"unknown type {kind!r}{_hint(kind, NODE_TYPES)}; use one of "
                                    f"{', '.join(NODE_TYPES)}")
        reader.complete = False
        return None
    name = raw.get("name", _MISSING)
    if name is _MISSING:
        reader.fail(f"{path}.name", "missing; every state has a name (containers and action states are registered "
                                    "as {id}_{name})")
    elif not isinstance(name, str) or not name.strip():
        reader.fail(f"{path}.name", f"expected a non-empty string, got {name!r}")
    container = kind in CONTAINER_TYPES

    state_type, parameters = None, None
    if container:
        for key in ("state_type", "parameters"):
            if key in raw:
                reader.fail(f"{path}.{key}", f"a {kind} has no {key}; it belongs to CBState and SimpleActionState")
    else:
        state_type = _state_type(reader, raw, path, kind)
        if state_type is not None:
            before = len(reader.problems)
            parameters = _parameters(reader, raw.get("parameters", _MISSING), f"{path}.parameters", state_type)
            reader.parameter_problems += len(reader.problems) - before

    outcomes = _transitions(reader, raw.get("outcomes", {}), f"{path}.outcomes")
    ids = _ids(reader, raw["ids"], f"{path}.ids") if "ids" in raw else None
    ids_var = raw.get("ids_var")
    if ids_var is not None and ids_var not in IDS_VARS:
        reader.fail(f"{path}.ids_var", f"unknown ids_var {ids_var!r}; use 'agent' (one state per agent id) or 'wp' "
                                       "(one state per waypoint of parameters.path)")
        ids_var = None

    children: tuple[Node, ...] = ()
    if container:
        raw_children = raw.get("occurrencies", _MISSING)
        if raw_children is _MISSING:
            reader.fail(f"{path}.occurrencies", f"missing; a {kind} lists its states under occurrencies (spelled so)")
        elif not isinstance(raw_children, list) or not raw_children:
            reader.fail(f"{path}.occurrencies", f"expected a non-empty list of states, got {_kind(raw_children)}")
        else:
            parsed = [_node(reader, child, f"{path}.occurrencies[{i}]") for i, child in enumerate(raw_children)]
            children = tuple(child for child in parsed if child is not None)
    elif "occurrencies" in raw:
        reader.fail(f"{path}.occurrencies", f"a {kind} has no occurrencies; put the states in a StateMachine, "
                                            "Concurrence or Sequence")

    outcome_map: dict[str, dict[str, str]] = {}
    for key in ("occurrencies_outcome_map", "outcome_cb", "child_termination_cb"):
        if key in raw and kind != "Concurrence":
            reader.fail(f"{path}.{key}", f"only a Concurrence has {key}; this is a {kind}")
    if kind == "Concurrence" and "occurrencies_outcome_map" in raw:
        outcome_map = _outcome_map(reader, raw["occurrencies_outcome_map"], f"{path}.occurrencies_outcome_map")
    callbacks = {}
    for key in ("outcome_cb", "child_termination_cb"):
        value = raw.get(key)
        if kind == "Concurrence" and value is not None and not isinstance(value, str):
            reader.fail(f"{path}.{key}", f"expected a callback name (a string), got {value!r}")
            value = None
        callbacks[key] = value if kind == "Concurrence" else None

    connector = None
    if kind == "Sequence":
        connector = raw.get("connector_outcome", _MISSING)
        if connector is _MISSING:
            reader.fail(f"{path}.connector_outcome", "missing; a Sequence chains its states by one outcome "
                                                     "(e.g. \"succeeded\")")
            connector = None
        elif not isinstance(connector, str) or not connector:
            reader.fail(f"{path}.connector_outcome", f"expected an outcome name, got {connector!r}")
            connector = None
    elif "connector_outcome" in raw:
        reader.fail(f"{path}.connector_outcome", f"only a Sequence has connector_outcome; this is a {kind}")

    parameter_problems = reader.parameter_problems - parameter_problems_before
    if parameter_problems and ids_var == "wp":  # how many states it makes depends on its path
        reader.complete = False
    if len(reader.problems) - problems_before > parameter_problems:  # more than bad parameters: cannot be placed
        reader.complete = False
        return None
    return Node(kind=kind, name=name, json_path=path, state_type=state_type, parameters=parameters,
                outcomes=outcomes, ids=ids, ids_var=ids_var, occurrencies=children,
                occurrencies_outcome_map=outcome_map, outcome_cb=callbacks["outcome_cb"],
                child_termination_cb=callbacks["child_termination_cb"], connector_outcome=connector)


def _state_type(reader: _Reader, raw: dict, path: str, kind: str) -> str | None:
    allowed = ACTION_TYPES if kind == "SimpleActionState" else CALLBACK_TYPES
    other_kind, other = ("CBState", CALLBACK_TYPES) if kind == "SimpleActionState" else ("SimpleActionState",
                                                                                          ACTION_TYPES)
    state_type = raw.get("state_type", _MISSING)
    if state_type is _MISSING:
        reader.fail(f"{path}.state_type", f"missing; a {kind} has one of {', '.join(allowed)}")
        return None
    if state_type in allowed:
        return state_type
    if state_type in other:
        reader.fail(f"{path}.state_type", f"{state_type!r} is a {other_kind} type; make this state a {other_kind} "
                                          f"or use one of {', '.join(allowed)}")
    else:
        reader.fail(f"{path}.state_type", f"unknown state_type {state_type!r}{_hint(state_type, allowed)}; a {kind} "
                                          f"has one of {', '.join(allowed)}")
    return None


def _transitions(reader: _Reader, raw: Any, path: str) -> dict[str, str]:
    if not isinstance(raw, dict):
        reader.fail(path, f"expected an object {{outcome: next state or outcome}}, got {_kind(raw)}")
        return {}
    out = {}
    for outcome, target in raw.items():
        if not isinstance(target, str) or not target:
            reader.fail(f"{path}.{outcome}", f"expected the label of a state or an outcome (a string), got {target!r}")
        else:
            out[outcome] = target
    return out


def _ids(reader: _Reader, raw: Any, path: str):
    if raw == "all":
        return "all"
    if _is_int(raw) and raw >= 0:
        return int(raw)
    if isinstance(raw, list) and raw and all(_is_int(i) and i >= 0 for i in raw):
        if len(set(raw)) != len(raw):
            reader.fail(path, f"{raw} names an id twice; give each once")
            return None
        return tuple(int(i) for i in raw)
    reader.fail(path, f"expected an id (a whole number >= 0), a non-empty list of ids, or \"all\", got {raw!r}")
    return None


def _outcome_map(reader: _Reader, raw: Any, path: str) -> dict[str, dict[str, str]]:
    usage = "{container outcome: {child label or \"all\": child outcome}}"
    if not isinstance(raw, dict):
        reader.fail(path, f"expected {usage}, got {_kind(raw)}")
        return {}
    out = {}
    for outcome, conditions in raw.items():
        if not isinstance(conditions, dict) or not conditions:
            reader.fail(f"{path}.{outcome}", f"expected a non-empty object {{child label or \"all\": child outcome}}, "
                                             f"got {conditions!r}")
            continue
        bad = [k for k, v in conditions.items() if not isinstance(v, str) or not v]
        for key in bad:
            reader.fail(f"{path}.{outcome}.{key}", f"expected a child outcome (a string), got {conditions[key]!r}")
        if not bad:
            out[outcome] = dict(conditions)
    return out


# --- parameters ----------------------------------------------------------------------------------------------------

class _Fields:
    """Typed reads of one parameters object; unknown keys become warnings when `done()` is called."""

    def __init__(self, reader: _Reader, raw: dict, path: str, state_type: str):
        self.reader, self.raw, self.path, self.state_type = reader, raw, path, state_type
        self.used: set[str] = set()
        self.ok = True

    def _get(self, key: str, required: bool, usage: str):
        self.used.add(key)
        if key not in self.raw:
            if required:
                self.fail(key, f"missing; {self.state_type} needs {key} ({usage})")
            return _MISSING
        return self.raw[key]

    def fail(self, key: str | None, message: str) -> None:
        self.ok = False
        self.reader.fail(f"{self.path}.{key}" if key else self.path, message)

    def number(self, key: str, default=_MISSING, minimum: float | None = None, positive: bool = False,
               usage: str = "a number"):
        value = self._get(key, default is _MISSING, usage)
        if value is _MISSING:
            return None if default is _MISSING else default
        if not _is_number(value):
            self.fail(key, f"expected {usage}, got {value!r}")
            return None
        if positive and value <= 0 or minimum is not None and value < minimum:
            self.fail(key, f"expected {usage}, got {value!r}")
            return None
        return float(value)

    def integer(self, key: str, default=_MISSING, minimum: int = 0, usage: str = "a whole number"):
        value = self._get(key, default is _MISSING, usage)
        if value is _MISSING:
            return None if default is _MISSING else default
        if not _is_int(value) or value < minimum:
            self.fail(key, f"expected {usage}, got {value!r}")
            return None
        return int(value)

    def choice(self, key: str, options, default=_MISSING):
        usage = "one of " + ", ".join(options)
        value = self._get(key, default is _MISSING, usage)
        if value is _MISSING:
            return None if default is _MISSING else default
        if value not in options:
            self.fail(key, f"{value!r} is not {usage}{_hint(value, options)}")
            return None
        return value

    def flag(self, key: str, default: bool) -> bool:
        value = self._get(key, False, "true or false")
        if value is _MISSING:
            return default
        if not isinstance(value, bool):
            self.fail(key, f"expected true or false, got {value!r}")
            return default
        return value

    def text(self, key: str, default=_MISSING, usage: str = "a string"):
        value = self._get(key, default is _MISSING, usage)
        if value is _MISSING:
            return None if default is _MISSING else default
        if not isinstance(value, str) or not value:
            self.fail(key, f"expected {usage}, got {value!r}")
            return None
        return value

    def definitions(self, key: str, usage: str) -> tuple[PoseDefinition, ...]:
        value = self._get(key, True, usage)
        if value is _MISSING:
            return ()
        if not isinstance(value, list) or not value:
            self.fail(key, f"expected {usage}, got {_kind(value)}")
            return ()
        out = []
        for index, item in enumerate(value):
            definition = _definition(self.reader, item, f"{self.path}.{key}[{index}]", allow_yaw=True)
            if definition is None:
                self.ok = False
            else:
                out.append(definition)
        return tuple(out)

    def path_items(self, key: str) -> tuple[PoseDefinition, ...] | None:
        """`[{"definition": [...]}, ...]`; None (no problem) for a path from the UTM."""
        usage = "a non-empty list of {\"definition\": [volume, geometry, kind, arg]}"
        value = self._get(key, True, usage)
        if value is _MISSING:
            return ()
        if value in FROM_UTM:
            return None
        if not isinstance(value, list) or not value:
            self.fail(key, f"expected {usage} (or \"from utm\"), got {_kind(value)}")
            return ()
        out = []
        for index, item in enumerate(value):
            where = f"{self.path}.{key}[{index}]"
            if not isinstance(item, dict) or "definition" not in item:
                self.ok = False
                self.reader.fail(where, f"expected {{\"definition\": [volume, geometry, kind, arg]}}, got {item!r}")
                continue
            for extra in item:
                if extra != "definition":
                    self.reader.warn(f"{where}.{extra}", "unknown key, ignored; a path item has only 'definition'")
            definition = _definition(self.reader, item["definition"], f"{where}.definition", allow_yaw=False)
            if definition is None:
                self.ok = False
            else:
                out.append(definition)
        return tuple(out)

    def done(self) -> bool:
        for key in self.raw:
            if key not in self.used:
                self.reader.warn(f"{self.path}.{key}", f"{self.state_type} does not use {key}; ignored"
                                 f"{_hint(key, sorted(self.used))}")
        return self.ok


def _parameters(reader: _Reader, raw: Any, path: str, state_type: str) -> Parameters | None:
    if raw is _MISSING:
        raw = {}
    if not isinstance(raw, dict):
        reader.fail(path, f"expected an object of {state_type} parameters, got {_kind(raw)}")
        return None
    f = _Fields(reader, raw, path, state_type)
    params = _PARSERS[state_type](f)
    return params if f.done() and params is not None else None


def _take_off(f: _Fields):
    height = f.number("height", positive=True, usage="a height above the take-off point in m, > 0")
    return TakeOffParams(height) if height is not None else None


def _land(f: _Fields):
    return LandParams(f.number("height", default=None, usage="a number (m); landing does not use it"))


def _follow_path(f: _Fields):
    path = f.path_items("path")
    mode = f.integer("smooth_path_mode", default=0, usage="0 (straight segments) or a spline order >= 1")
    dynamic = f.choice("dynamic", DYNAMICS, default="velocity")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds allowed, >= 0 (0: no limit)")
    if path is None:
        return FollowPathParams((), mode, dynamic, duration, from_utm=True)
    return FollowPathParams(path, mode, dynamic, duration)


def _basic_move(f: _Fields):
    move_type = f.choice("move_type", MOVE_TYPES)
    dynamic = f.choice("dynamic", DYNAMICS)
    direction = f.choice("direction", DIRECTIONS)
    value = f.number("value", usage="metres (translation) or degrees (rotation)")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds allowed, >= 0 (0: no limit)")
    if None in (move_type, dynamic, direction, value):
        return None
    return BasicMoveParams(move_type, dynamic, direction, value, duration)


def _target(f: _Fields):
    return f.integer("target_ID", usage="the ID of the agent to follow (Agents_Config)")


def _follow_agent_ad(f: _Fields):
    target = _target(f)
    distance = f.number("distance", positive=True, usage="a distance behind the target in m, > 0")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds to follow, >= 0 (0: until preempted)")
    return None if None in (target, distance) else FollowAgentADParams(target, distance, duration)


def _follow_agent_ap(f: _Fields):
    target = _target(f)
    pos = f._get("pos", True, "[x, y, z], the offset from the target in m")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds to follow, >= 0 (0: until preempted)")
    if pos is _MISSING:
        return None
    if not (isinstance(pos, list) and len(pos) == 3 and all(_is_number(v) for v in pos)):
        f.fail("pos", f"expected [x, y, z], the offset from the target in m, got {pos!r}")
        return None
    return None if target is None else FollowAgentAPParams(target, tuple(float(v) for v in pos), duration)


def _save_csv(f: _Fields):
    return SaveCsvParams()


def _set_mission(f: _Fields):
    path = f.path_items("path")
    include_takeoff = f.flag("include_takeoff", False)
    include_land = f.flag("include_land", False)
    if path is None:
        f.fail("path", "set_mission needs the path written out; \"from utm\" is for follow_path")
        return None
    return SetMissionParams(path, include_takeoff, include_land)


def _world_config(f: _Fields):
    action = f.choice("action", WORLD_ACTIONS)
    raw_id = f._get("id", action in ("spawn", "delete"), "the world (part) id, e.g. 1")
    world_id = None
    if raw_id is not _MISSING:
        if (_is_int(raw_id) and raw_id >= 0) or (isinstance(raw_id, str) and raw_id.strip()):
            world_id = str(raw_id)
        else:
            f.fail("id", f"expected an id (a whole number or a name), got {raw_id!r}")
    part = None
    raw_part = f._get("world_part_def", action == "add",
                      f"\"{FROM_HYPERPARAMETERS}\" or a list of world volumes")
    if raw_part is not _MISSING:
        where = f"{f.path}.world_part_def"
        if raw_part == FROM_HYPERPARAMETERS:
            part = WorldPartDef(from_hyperparameters=True, json_path=where)
        elif isinstance(raw_part, list) and raw_part and all(isinstance(v, dict) for v in raw_part):
            part = WorldPartDef(volumes=tuple(raw_part), json_path=where)
        else:
            f.fail("world_part_def", f"expected \"{FROM_HYPERPARAMETERS}\" or a non-empty list of world volumes "
                                     f"({{\"name\": ..., \"geometries\": ...}} or {{\"name\": \"JSON\", \"world\": W, "
                                     f"\"subworld\": S}}), got {raw_part!r}")
    if action == "delete" and raw_part is not _MISSING:
        f.fail("world_part_def", "delete removes the part named by id; it takes no world_part_def")
    if action is None or not f.ok:
        return None
    return WorldConfigParams(action, world_id, part)


def _wait(f: _Fields):
    exit_type = f.choice("exit_type", EXIT_TYPES)
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds to wait, >= 0")
    if exit_type == "button" and "duration" in f.raw:
        f.reader.warn(f"{f.path}.duration", "a button wait ends on the operator's command; duration is ignored")
    return None if exit_type is None else WaitParams(exit_type, duration)


def _spawn_agents(f: _Fields):
    poses = f.definitions("initial_poses", "a list of [volume, geometry, kind, arg, yaw?], one per agent in "
                                           "Agents_Config order")
    return SpawnAgentsParams(poses) if poses else None


def _algorithm_control(f: _Fields):
    name = f.text("name", usage="an algorithm name: simple, orca3d (orca3) or neural_network")
    action = f.text("action", usage="set (select and configure) or configure (only change parameters)")
    params = f._get("params", False, "a list of parameter names")
    values = f._get("values", False, "a list of values, one per name")
    text_value = f.text("text_value", default="", usage="a string (e.g. the path of a TorchScript model)")
    params = [] if params is _MISSING else params
    values = [] if values is _MISSING else values
    if not isinstance(params, list) or not all(isinstance(p, str) for p in params):
        f.fail("params", f"expected a list of parameter names, got {params!r}")
    elif not isinstance(values, list):
        f.fail("values", f"expected a list of values, one per name in params, got {values!r}")
    elif len(params) != len(values):
        f.fail("values", f"{len(values)} values for {len(params)} names in params; give one value per name")
    elif "model" in params:
        # the service carries numbers in values and text in text_value: a model path given as the
        # parameter "model" (as the NAI itself accepts) travels as text_value
        k = params.index("model")
        model = values[k]
        if not isinstance(model, str) or (text_value and text_value != model):
            f.fail("values", f"values[{k}] (model) is {model!r}: give the model's path once, as a string "
                             "(here or in text_value)")
        else:
            text_value = model
            params, values = params[:k] + params[k + 1:], values[:k] + values[k + 1:]
    if not f.ok or name is None or action is None:
        return None
    return AlgorithmControlParams(name, action, tuple(params), tuple(values), text_value)


_PARSERS = {
    "take_off": _take_off, "land": _land, "follow_path": _follow_path, "basic_move": _basic_move,
    "follow_agent_ad": _follow_agent_ad, "follow_agent_ap": _follow_agent_ap, "save_csv": _save_csv,
    "set_mission": _set_mission, "world_config": _world_config, "wait": _wait, "spawn_agents": _spawn_agents,
    "algorithm_control": _algorithm_control,
}


def _definition(reader: _Reader, raw: Any, path: str, allow_yaw: bool) -> PoseDefinition | None:
    usage = "[volume, geometry or \"volume\", kind, arg" + (", yaw?]" if allow_yaw else "]")
    if not isinstance(raw, list) or len(raw) not in ((4, 5) if allow_yaw else (4,)):
        reader.fail(path, f"expected {usage}, got {raw!r}")
        return None
    volume, geometry, kind, arg = raw[:4]
    ok = True
    for index, (value, what) in enumerate(((volume, "a volume name"), (geometry, "a geometry name or \"volume\""))):
        if not isinstance(value, str) or not value:
            reader.fail(f"{path}[{index}]", f"expected {what}, got {value!r}")
            ok = False
    if kind not in POSE_KINDS:
        reader.fail(f"{path}[2]", f"unknown kind {kind!r}{_hint(kind, POSE_KINDS)}; use one of {', '.join(POSE_KINDS)}")
        return None
    problem = _arg_problem(kind, arg)
    if problem:
        reader.fail(f"{path}[3]", problem)
        ok = False
    yaw = None
    if len(raw) == 5:
        if not _is_number(raw[4]):
            reader.fail(f"{path}[4]", f"expected a yaw in radians, got {raw[4]!r}")
            ok = False
        else:
            yaw = float(raw[4])
    return PoseDefinition(volume, geometry, kind, arg, yaw, path) if ok else None


def _arg_problem(kind: str, arg: Any) -> str:
    if kind == "matrix" and not (isinstance(arg, list) and len(arg) == 3 and all(_is_int(v) and v >= 0 for v in arg)):
        return f"a matrix cell is [i, j, k] (whole numbers from 0), got {arg!r}"
    if kind == "random" and not (_is_int(arg) and arg >= 1):
        return f"random takes how many poses to draw (a whole number >= 1), got {arg!r}"
    if kind == "coordinates" and not (isinstance(arg, list) and arg):
        return f"coordinates take [[x, y, z], [roll, pitch, yaw] or [qx, qy, qz, qw]] or a list of them, got {arg!r}"
    if kind == "path" and not (arg is None or isinstance(arg, str) or _is_int(arg)):
        return f"path takes a zigzag name (\"Zigzag\") or index, got {arg!r}"
    if kind == "poses" and not (_is_int(arg) and arg >= 0):
        return f"poses takes the index of a set of poses (from 0), got {arg!r}"
    return ""


# --- small helpers -------------------------------------------------------------------------------------------------

def _is_int(value: Any) -> bool:
    return isinstance(value, Integral) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(value)


def _hint(value: Any, options) -> str:
    close = difflib.get_close_matches(str(value), [str(o) for o in options], n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string"}.get(type(value), repr(value))
