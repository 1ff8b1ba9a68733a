"""Migrated mission JSON -> `model.Mission`, checking every field once.

Every problem is collected, not only the first (magna_common.json_fields in its collecting
mode), and reported together as one `MissionError`, each line `file: JSON.path: what is wrong;
what to write instead`. Paths are the file's own (keys renamed by the migration are mapped
back). Keys a state does not use are warnings: the original ignored them, and real missions
carry some.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from magna_common.json_fields import (
    MISSING,
    JsonFields,
    ObjectFields,
    describe,
    did_you_mean,
    is_integer,
    is_number,
    join_path,
)
from magna_gs.mission.migrate import AGENTS_KEY, LEGACY_AGENTS_KEY, Migration
from magna_gs.mission.model import (
    ACTION_TYPES,
    ALLOW_REAL,
    CALLBACK_TYPES,
    CONTAINER_TYPES,
    EXIT_TYPES,
    FROM_HYPERPARAMETERS,
    FROM_UTM,
    IDS_VARS,
    NODE_TYPES,
    OPERATOR_COMMANDS_KEY,
    WORLD_ACTIONS,
    AlgorithmControlParams,
    BasicMoveParams,
    FollowAgentADParams,
    FollowAgentAPParams,
    FollowPathParams,
    Ids,
    LandParams,
    Mission,
    MissionError,
    Node,
    Parameters,
    PoseDefinition,
    SaveCsvParams,
    SetMissionParams,
    SpawnAgentsParams,
    StateType,
    TakeOffParams,
    WaitParams,
    WorldConfigParams,
    WorldPartDef,
)
from magna_uav.config import UavConfig
from magna_uav.vocabulary import DIRECTIONS, DYNAMICS, MOVE_TYPES
from magna_worlds.vocabulary import POSE_KINDS

NODE_KEYS = ("type", "name", "state_type", "parameters", "outcomes", "ids", "ids_var", "occurrencies",
             "occurrencies_outcome_map", "outcome_cb", "child_termination_cb", "connector_outcome")
UTM_KEY = "UTM"  # optional: the mission's own UTM flight plans (magna_gs.utm), or the name of a plan file
TOP_KEYS = (AGENTS_KEY, "State_Machine", UTM_KEY, OPERATOR_COMMANDS_KEY)


class _Reader(JsonFields[None]):
    """Collects every problem and warning with file and (original) JSON path, and how far the mission was read."""

    def __init__(self, source: str, migration: Migration):
        super().__init__(source, None, migration.original_path)
        self.migration = migration
        self.complete = True  # False once a node or the agents could not be read at all
        self.parameter_problems = 0  # how many of the problems are in parameters (the node is kept)


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
                           f"\"State_Machine\": [...]}}, got {describe(data)}")
    for key in data:
        if key not in TOP_KEYS and key != LEGACY_AGENTS_KEY:  # both agent keys: _agents says so
            reader.fail(str(key), f"unknown key{did_you_mean(key, (*TOP_KEYS, LEGACY_AGENTS_KEY))}; a mission has "
                                  f"{AGENTS_KEY} and State_Machine (and optionally {UTM_KEY}, its flight plans, and "
                                  f"{OPERATOR_COMMANDS_KEY}, what the operator may command)")
    if UTM_KEY in data:
        _utm(reader, data)
    agents, agents_key = _agents(reader, airframe_dir)
    root: list[Node] = []
    if "State_Machine" not in data:
        reader.fail("State_Machine", "missing; list the mission's states here ([{\"type\": \"CBState\", ...}, ...])")
    else:
        states = reader.list(data["State_Machine"], "State_Machine", "a non-empty list of states", non_empty=True)
        for index, raw in enumerate(states or []):
            node = _node(reader, raw, f"State_Machine[{index}]")
            if node is not None:
                root.append(node)
    if not root:
        reader.complete = False
    operator_real = _operator_commands(reader, data[OPERATOR_COMMANDS_KEY], agents) \
        if OPERATOR_COMMANDS_KEY in data else ()
    return Parsed(Mission(source, agents, root, agents_key, operator_real), reader.warnings, reader.problems,
                  reader.complete)


def _operator_commands(reader: _Reader, raw: Any, agents: list[UavConfig]) -> tuple[int, ...]:
    """Operator_Commands {"allow_real": [ids] | "all"}: the real UAVs the operator may command (none without it)."""
    key, usage = OPERATOR_COMMANDS_KEY, f'{{"{ALLOW_REAL}": [ids of real UAVs] or "all"}}'
    obj = reader.object(raw, key, usage)
    if obj is None:
        return ()
    for name in obj:
        if name != ALLOW_REAL:
            reader.fail(f"{key}.{name}", f"unknown key{did_you_mean(name, (ALLOW_REAL,))}; {key} is {usage}")
    where, allowed = f"{key}.{ALLOW_REAL}", obj.get(ALLOW_REAL, [])
    real = [a.id for a in agents if a.mode == "real"]
    if allowed == "all":
        return tuple(real)
    if not isinstance(allowed, list) or not all(is_integer(i) for i in allowed):
        reader.fail(where, f"expected a list of UAV ids or \"all\", got {describe(allowed)}")
        return ()
    modes = {a.id: a.mode for a in agents}
    for index, uav_id in enumerate(allowed):
        if uav_id not in modes:
            reader.fail(f"{where}[{index}]", f"UAV {uav_id} is not in {AGENTS_KEY}; list real UAVs of this mission")
        elif modes[uav_id] != "real":
            reader.fail(f"{where}[{index}]", f"UAV {uav_id} is {modes[uav_id]}: the operator commands sitl and hil "
                                             "UAVs without permission; list only real UAVs here")
    return tuple(int(i) for i in allowed if i in real)


def _utm(reader: _Reader, data: dict[str, Any]) -> None:
    """The mission's UTM section is checked now, as the ground station would check it before flying."""
    from magna_gs.utm import UtmPlanError, mission_plan

    try:
        mission_plan(data, reader.source)
    except UtmPlanError as error:
        reader.problems.append(" ".join(str(error).split()))


def _agents(reader: _Reader, airframe_dir: Path | None) -> tuple[list[UavConfig], str]:
    """The agents (read by magna_uav.config, which stops at an entry's first problem) and the key the file used."""
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
        if not is_integer(agent_id) or agent_id not in ids[:index]:
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
    if reader.object(raw, path, "a state object {\"type\": ..., \"name\": ...}") is None:
        return None
    problems_before, parameter_problems_before = len(reader.problems), reader.parameter_problems
    for key in raw:
        if key not in NODE_KEYS:
            reader.fail(f"{path}.{key}", f"unknown key{did_you_mean(key, NODE_KEYS)}; a state has "
                                         f"{', '.join(NODE_KEYS)}")
    if "type" not in raw:
        reader.fail(f"{path}.type", f"missing; give one of {', '.join(NODE_TYPES)}")
        reader.complete = False
        return None
    kind = reader.choice(raw["type"], f"{path}.type", NODE_TYPES, noun="type")
    if kind is None:
        reader.complete = False
        return None
    name = raw.get("name", MISSING)
    if name is MISSING:
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
            parameters = _parameters(reader, raw.get("parameters", {}), f"{path}.parameters", state_type)
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
        if "occurrencies" not in raw:
            reader.fail(f"{path}.occurrencies", f"missing; a {kind} lists its states under occurrencies (spelled so)")
        else:
            raw_children = reader.list(raw["occurrencies"], f"{path}.occurrencies", "a non-empty list of states",
                                       non_empty=True)
            parsed = [_node(reader, child, f"{path}.occurrencies[{i}]") for i, child in enumerate(raw_children or [])]
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
    callbacks: dict[str, str | None] = {}
    for key in ("outcome_cb", "child_termination_cb"):
        value = raw.get(key)
        if kind == "Concurrence" and value is not None:
            callbacks[key] = reader.text(value, f"{path}.{key}", "a callback name (a string)", allow_empty=True)
        else:
            callbacks[key] = None

    connector = None
    if kind == "Sequence":
        if "connector_outcome" not in raw:
            reader.fail(f"{path}.connector_outcome", "missing; a Sequence chains its states by one outcome "
                                                     "(e.g. \"succeeded\")")
        else:
            connector = reader.text(raw["connector_outcome"], f"{path}.connector_outcome", "an outcome name")
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


def _state_type(reader: _Reader, raw: dict[str, Any], path: str, kind: str) -> StateType | None:
    allowed: tuple[StateType, ...] = ACTION_TYPES if kind == "SimpleActionState" else CALLBACK_TYPES
    other_kind, other = ("CBState", CALLBACK_TYPES) if kind == "SimpleActionState" else ("SimpleActionState",
                                                                                          ACTION_TYPES)
    if "state_type" not in raw:
        reader.fail(f"{path}.state_type", f"missing; a {kind} has one of {', '.join(allowed)}")
        return None
    state_type = raw["state_type"]
    if state_type in allowed:
        return allowed[allowed.index(state_type)]
    if state_type in other:
        reader.fail(f"{path}.state_type", f"{state_type!r} is a {other_kind} type; make this state a {other_kind} "
                                          f"or use one of {', '.join(allowed)}")
    else:
        reader.fail(f"{path}.state_type", f"unknown state_type {state_type!r}{did_you_mean(state_type, allowed)}; "
                                          f"a {kind} has one of {', '.join(allowed)}")
    return None


def _transitions(reader: _Reader, raw: Any, path: str) -> dict[str, str]:
    transitions = reader.object(raw, path, "an object {outcome: next state or outcome}")
    out = {}
    for outcome, target in (transitions or {}).items():
        label = reader.text(target, f"{path}.{outcome}", "the label of a state or an outcome (a string)")
        if label is not None:
            out[outcome] = label
    return out


def _ids(reader: _Reader, raw: Any, path: str) -> Ids | None:
    if raw == "all":
        return "all"
    if is_integer(raw) and raw >= 0:
        return int(raw)
    if isinstance(raw, list) and raw and all(is_integer(i) and i >= 0 for i in raw):
        if len(set(raw)) != len(raw):
            reader.fail(path, f"{raw} names an id twice; give each once")
            return None
        return tuple(int(i) for i in raw)
    reader.fail(path, f"expected an id (a whole number >= 0), a non-empty list of ids, or \"all\", got {raw!r}")
    return None


def _outcome_map(reader: _Reader, raw: Any, path: str) -> dict[str, dict[str, str]]:
    outcome_map = reader.object(raw, path, "{container outcome: {child label or \"all\": child outcome}}")
    out = {}
    for outcome, conditions in (outcome_map or {}).items():
        if not isinstance(conditions, dict) or not conditions:
            reader.fail(f"{path}.{outcome}", f"expected a non-empty object {{child label or \"all\": child outcome}}, "
                                             f"got {conditions!r}")
            continue
        read = [reader.text(wanted, f"{path}.{outcome}.{key}", "a child outcome (a string)")
                for key, wanted in conditions.items()]
        if None not in read:
            out[outcome] = dict(conditions)
    return out


# --- parameters ----------------------------------------------------------------------------------------------------

def _parameters(reader: _Reader, raw: Any, path: str, state_type: StateType) -> Parameters | None:
    """The state's parameters, typed; None when any is bad. Keys the state does not use are warnings."""
    obj = reader.object(raw, path, f"an object of {state_type} parameters")
    if obj is None:
        return None
    f = ObjectFields(reader, obj, path, lambda key, usage: f"{state_type} needs {key} ({usage})")
    params = _PARSERS[state_type](f)
    for key in f.unused():
        reader.warn(f"{path}.{key}", f"{state_type} does not use {key}; ignored{did_you_mean(key, sorted(f.used))}")
    return params if f.ok else None


def _take_off(f: ObjectFields) -> TakeOffParams | None:
    height = f.number("height", positive=True, usage="a height above the take-off point in m, > 0")
    return TakeOffParams(height) if height is not None else None


def _land(f: ObjectFields) -> LandParams:
    return LandParams(f.number("height", default=None, usage="a number (m); landing does not use it"))


def _follow_path(f: ObjectFields) -> FollowPathParams | None:
    path = _path_items(f, "path")
    mode = f.integer("smooth_path_mode", default=0, usage="0 (straight segments) or a spline order >= 1")
    dynamic = f.choice("dynamic", DYNAMICS, default="velocity")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds allowed, >= 0 (0: no limit)")
    if mode is None or dynamic is None or duration is None:
        return None
    if path is None:
        return FollowPathParams((), mode, dynamic, duration, from_utm=True)
    return FollowPathParams(path, mode, dynamic, duration)


def _basic_move(f: ObjectFields) -> BasicMoveParams | None:
    move_type = f.choice("move_type", MOVE_TYPES)
    dynamic = f.choice("dynamic", DYNAMICS)
    direction = f.choice("direction", DIRECTIONS)
    value = f.number("value", usage="metres (translation) or degrees (rotation)")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds allowed, >= 0 (0: no limit)")
    if move_type is None or dynamic is None or direction is None or value is None or duration is None:
        return None
    return BasicMoveParams(move_type, dynamic, direction, value, duration)


def _target(f: ObjectFields) -> int | None:
    return f.integer("target_ID", usage="the ID of the agent to follow (Agents_Config)")


def _follow_agent_ad(f: ObjectFields) -> FollowAgentADParams | None:
    target = _target(f)
    distance = f.number("distance", positive=True, usage="a distance behind the target in m, > 0")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds to follow, >= 0 (0: until preempted)")
    if target is None or distance is None or duration is None:
        return None
    return FollowAgentADParams(target, distance, duration)


def _follow_agent_ap(f: ObjectFields) -> FollowAgentAPParams | None:
    target = _target(f)
    pos = f.get("pos", True, "[x, y, z], the offset from the target in m")
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds to follow, >= 0 (0: until preempted)")
    if pos is MISSING:
        return None
    if not (isinstance(pos, list) and len(pos) == 3 and all(is_number(v) for v in pos)):
        f.fail("pos", f"expected [x, y, z], the offset from the target in m, got {pos!r}")
        return None
    if target is None or duration is None:
        return None
    x, y, z = (float(v) for v in pos)
    return FollowAgentAPParams(target, (x, y, z), duration)


def _save_csv(f: ObjectFields) -> SaveCsvParams:
    return SaveCsvParams()


def _set_mission(f: ObjectFields) -> SetMissionParams | None:
    path = _path_items(f, "path")
    include_takeoff = f.flag("include_takeoff", False)
    include_land = f.flag("include_land", False)
    if path is None:
        f.fail("path", "set_mission needs the path written out; \"from utm\" is for follow_path")
        return None
    return SetMissionParams(path, include_takeoff, include_land)


def _world_config(f: ObjectFields) -> WorldConfigParams | None:
    action = f.choice("action", WORLD_ACTIONS)
    raw_id = f.get("id", action in ("spawn", "delete"), "the world (part) id, e.g. 1")
    world_id = None
    if raw_id is not MISSING:
        if (is_integer(raw_id) and raw_id >= 0) or (isinstance(raw_id, str) and raw_id.strip()):
            world_id = str(raw_id)
        else:
            f.fail("id", f"expected an id (a whole number or a name), got {raw_id!r}")
    part = None
    raw_part = f.get("world_part_def", action == "add", f"\"{FROM_HYPERPARAMETERS}\" or a list of world volumes")
    if raw_part is not MISSING:
        where = f.path_of("world_part_def")
        if raw_part == FROM_HYPERPARAMETERS:
            part = WorldPartDef(from_hyperparameters=True, json_path=where)
        elif isinstance(raw_part, list) and raw_part and all(isinstance(v, dict) for v in raw_part):
            part = WorldPartDef(volumes=tuple(raw_part), json_path=where)
        else:
            f.fail("world_part_def", f"expected \"{FROM_HYPERPARAMETERS}\" or a non-empty list of world volumes "
                                     f"({{\"name\": ..., \"geometries\": ...}} or {{\"name\": \"JSON\", \"world\": W, "
                                     f"\"subworld\": S}}), got {raw_part!r}")
    if action == "delete" and raw_part is not MISSING:
        f.fail("world_part_def", "delete removes the part named by id; it takes no world_part_def")
    if action is None or not f.ok:
        return None
    return WorldConfigParams(action, world_id, part)


def _wait(f: ObjectFields) -> WaitParams | None:
    exit_type = f.choice("exit_type", EXIT_TYPES)
    duration = f.number("duration", default=0.0, minimum=0.0, usage="seconds to wait, >= 0")
    if exit_type == "button" and "duration" in f.obj:
        f.fields.warn(f.path_of("duration"), "a button wait ends on the operator's command; duration is ignored")
    return None if exit_type is None or duration is None else WaitParams(exit_type, duration)


def _spawn_agents(f: ObjectFields) -> SpawnAgentsParams | None:
    poses = _definitions(f, "initial_poses", "a list of [volume, geometry, kind, arg, yaw?], one per agent in "
                                             "Agents_Config order")
    return SpawnAgentsParams(poses) if poses else None


def _algorithm_control(f: ObjectFields) -> AlgorithmControlParams | None:
    name = f.text("name", usage="an algorithm name: simple, orca3d (orca3) or neural_network")
    action = f.text("action", usage="set (select and configure) or configure (only change parameters)")
    params = f.get("params", False, "a list of parameter names")
    values = f.get("values", False, "a list of values, one per name")
    text_value = f.text("text_value", default="", usage="a string (e.g. the path of a TorchScript model)")
    params = [] if params is MISSING else params
    values = [] if values is MISSING else values
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
    if not f.ok or name is None or action is None or text_value is None:
        return None
    return AlgorithmControlParams(name, action, tuple(params), tuple(values), text_value)


_PARSERS: dict[str, Callable[[ObjectFields], Parameters | None]] = {
    "take_off": _take_off, "land": _land, "follow_path": _follow_path, "basic_move": _basic_move,
    "follow_agent_ad": _follow_agent_ad, "follow_agent_ap": _follow_agent_ap, "save_csv": _save_csv,
    "set_mission": _set_mission, "world_config": _world_config, "wait": _wait, "spawn_agents": _spawn_agents,
    "algorithm_control": _algorithm_control,
}


# --- pose definitions ----------------------------------------------------------------------------------------------

def _definitions(f: ObjectFields, key: str, usage: str) -> tuple[PoseDefinition, ...]:
    """A non-empty list of definitions [volume, geometry, kind, arg, yaw?]."""
    value = f.get(key, True, usage)
    if value is MISSING:
        return ()
    if not isinstance(value, list) or not value:
        f.fail(key, f"expected {usage}, got {describe(value)}")
        return ()
    out = []
    for index, item in enumerate(value):
        definition = _definition(f.fields, item, join_path(f.path_of(key), index), allow_yaw=True)
        if definition is None:
            f.ok = False
        else:
            out.append(definition)
    return tuple(out)


def _path_items(f: ObjectFields, key: str) -> tuple[PoseDefinition, ...] | None:
    """`[{"definition": [...]}, ...]`; None (no problem) for a path from the UTM."""
    usage = "a non-empty list of {\"definition\": [volume, geometry, kind, arg]}"
    value = f.get(key, True, usage)
    if value is MISSING:
        return ()
    if value in FROM_UTM:
        return None
    if not isinstance(value, list) or not value:
        f.fail(key, f"expected {usage} (or \"from utm\"), got {describe(value)}")
        return ()
    out = []
    for index, item in enumerate(value):
        where = join_path(f.path_of(key), index)
        if not isinstance(item, dict) or "definition" not in item:
            f.ok = False
            f.fields.fail(where, f"expected {{\"definition\": [volume, geometry, kind, arg]}}, got {item!r}")
            continue
        for extra in item:
            if extra != "definition":
                f.fields.warn(f"{where}.{extra}", "unknown key, ignored; a path item has only 'definition'")
        definition = _definition(f.fields, item["definition"], f"{where}.definition", allow_yaw=False)
        if definition is None:
            f.ok = False
        else:
            out.append(definition)
    return tuple(out)


def _definition(reader: JsonFields[None], raw: Any, path: str, allow_yaw: bool) -> PoseDefinition | None:
    usage = "[volume, geometry or \"volume\", kind, arg" + (", yaw?]" if allow_yaw else "]")
    if not isinstance(raw, list) or len(raw) not in ((4, 5) if allow_yaw else (4,)):
        reader.fail(path, f"expected {usage}, got {raw!r}")
        return None
    volume = reader.text(raw[0], f"{path}[0]", "a volume name")
    geometry = reader.text(raw[1], f"{path}[1]", "a geometry name or \"volume\"")
    kind = reader.choice(raw[2], f"{path}[2]", POSE_KINDS, noun="kind")
    if kind is None:
        return None
    arg = raw[3]
    problem = _arg_problem(kind, arg)
    if problem:
        reader.fail(f"{path}[3]", problem)
    yaw = reader.number(raw[4], f"{path}[4]", "a yaw in radians") if len(raw) == 5 else None
    if volume is None or geometry is None or problem or (len(raw) == 5 and yaw is None):
        return None
    return PoseDefinition(volume, geometry, kind, arg, yaw, path)


def _arg_problem(kind: str, arg: Any) -> str:
    if kind == "matrix" and not (isinstance(arg, list) and len(arg) == 3 and all(is_integer(v) and v >= 0
                                                                                  for v in arg)):
        return f"a matrix cell is [i, j, k] (whole numbers from 0), got {arg!r}"
    if kind == "random" and not (is_integer(arg) and arg >= 1):
        return f"random takes how many poses to draw (a whole number >= 1), got {arg!r}"
    if kind == "coordinates" and not (isinstance(arg, list) and arg):
        return f"coordinates take [[x, y, z], [roll, pitch, yaw] or [qx, qy, qz, qw]] or a list of them, got {arg!r}"
    if kind == "path" and not (arg is None or isinstance(arg, str) or is_integer(arg)):
        return f"path takes a zigzag name (\"Zigzag\") or index, got {arg!r}"
    if kind == "poses" and not (is_integer(arg) and arg >= 0):
        return f"poses takes the index of a set of poses (from 0), got {arg!r}"
    return ""
