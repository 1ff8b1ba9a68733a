"""Legacy mission JSON -> the current schema, in one step that says what it changed.

Three generations of ROS-MAGNA missions exist (all in real files, sometimes mixed in one):

- January 2019: the file is the state list alone (the Master's N_uav and uav_models gave the
  UAVs) -> `State_Machine`, with agents 1..N (N the highest UAV id the states name, iris, sitl);
  a leaf with no `state_type` took the type from its name -> `state_type: <name>`;

- `UAVs_Config` (entries with `uav_manager_on_gs`) -> `Agents_Config` (`agent_manager_on_gs`);
- state_type `new_world` (no parameters: world 1 from the hyperparameters) -> `world_config`
  `{action: spawn, id: 1, world_part_def: from_hyperparameters}`;
- state_type `spawn_uavs` (no parameters: agent i above cell [i, 0, 0] of the take-off matrix)
  -> `spawn_agents` `{initial_poses: [[Ground_Station, Agents_take_off, matrix, [i, 0, 0]], ...]}`;
- state_type `follow_uav_ad`, `follow_uav_ap` -> `follow_agent_ad`, `follow_agent_ap`;
- `ids_var: uav` -> `ids_var: agent`; parameters `time` -> `duration`;
- a `wait` with a duration and no `exit_type` -> `exit_type: time`;
- outcome-map conditions `succeeded` / `aborted` on a CBState child (save_csv was an action
  state once, and maps kept its vocabulary) -> `completed` / `failed`;
- a pose definition of three items (February-March 2019, when the world read no fourth item
  for these kinds): `[volume, geometry, "path"]` -> `[..., "path", null]` (the geometry's
  zigzag path) and `[volume, geometry, "random"]` -> `[..., "random", 1]` (one random pose).

`migrate(data)` never changes its argument and never fails: what it does not recognise
is left for the parser to report. Migration renames and fills in, it never adds or
removes states, so JSON paths stay those of the file (`original_path` maps the few
renamed keys back).
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from magna_common.json_fields import copy_json
from magna_worlds.migrate import Migration  # the same record of what a migration changed, for worlds and missions

LEGACY_AGENTS_KEY = "UAVs_Config"
AGENTS_KEY = "Agents_Config"
LEGACY_GS_KEY = "uav_manager_on_gs"
GS_KEY = "agent_manager_on_gs"
STATE_TYPE_RENAMES = {"new_world": "world_config", "spawn_uavs": "spawn_agents",
                      "follow_uav_ad": "follow_agent_ad", "follow_uav_ap": "follow_agent_ap"}
IDS_VAR_RENAMES = {"uav": "agent"}
# The legacy spawn put agent i (from 0) above cell [i, 0, 0] of the ground station's take-off matrix; the geometry
# was called UAVs_take_off then and is Agents_take_off in the current worlds.
LEGACY_SPAWN_VOLUME, LEGACY_SPAWN_GEOMETRY = "Ground_Station", "Agents_take_off"
# new_world made world 1 from the world and subworld of the hyperparameters.
LEGACY_NEW_WORLD = {"action": "spawn", "id": 1, "world_part_def": "from_hyperparameters"}
CB_OUTCOME_FOR_ACTION_OUTCOME = {"succeeded": "completed", "aborted": "failed"}
# The January 2019 schema (the file is the state list): the agents it gets, as the Master's defaults flew them.
STATE_LIST_MODEL = "iris"
STATE_LIST_COLORS = ((255, 0, 0, 0.5), (0, 255, 0, 0.5), (0, 0, 255, 0.5), (255, 255, 0, 0.5))
# Leaf types whose name was the type before state_type existed (besides the renamed legacy ones).
NAME_TYPES = ("take_off", "land", "follow_path", "basic_move", "save_csv", "wait")
# Until April 2019 the world answered "path" with the geometry's (only) zigzag path and "random" with one random
# pose, reading no fourth item; files of that time write three. The fourth item each kind takes now:
THREE_ITEM_DEFINITION_ARG = {"path": (None, "the geometry's zigzag path"), "random": (1, "one random pose")}


def migrate(data: Any) -> Migration:
    """Bring a mission to the current schema; `changes` says what was done, in file order."""
    result = Migration(copy_json(data), data)
    root = "State_Machine"
    if _is_state_list(result.data):
        _agents_for_a_state_list(result)
        root = ""  # the file's own paths: [3].occurrencies[0]...
    mission = result.data
    if not isinstance(mission, dict):
        return result
    agents_key = AGENTS_KEY
    if LEGACY_AGENTS_KEY in mission and AGENTS_KEY not in mission:
        result.data = mission = {(AGENTS_KEY if k == LEGACY_AGENTS_KEY else k): v for k, v in mission.items()}
        result.changes.append(f"{LEGACY_AGENTS_KEY} -> {AGENTS_KEY}")
        result.renamed[AGENTS_KEY] = LEGACY_AGENTS_KEY
        agents_key = LEGACY_AGENTS_KEY
    agents = mission.get(AGENTS_KEY)
    if isinstance(agents, list):
        for index, entry in enumerate(agents):
            if isinstance(entry, dict) and LEGACY_GS_KEY in entry and GS_KEY not in entry:
                agents[index] = {(GS_KEY if k == LEGACY_GS_KEY else k): v for k, v in entry.items()}
                result.changes.append(f"{agents_key}[{index}].{LEGACY_GS_KEY} -> {GS_KEY}")
                result.renamed[f"{AGENTS_KEY}[{index}].{GS_KEY}"] = f"{agents_key}[{index}].{LEGACY_GS_KEY}"
    n_agents = len(agents) if isinstance(agents, list) else 0
    nodes = mission.get("State_Machine")
    if isinstance(nodes, list):
        for index, node in enumerate(nodes):
            _node(node, f"{root}[{index}]", n_agents, result)
    return result


def _is_state_list(data: Any) -> bool:
    return isinstance(data, list) and bool(data) and all(isinstance(n, dict) and "type" in n for n in data)


def _agents_for_a_state_list(result: Migration) -> None:
    """The January 2019 schema: the file is the state list; the Master's N_uav and uav_models gave the UAVs."""
    states = result.data
    named = sorted({i for node in states for i in _uav_ids(node)})
    count = max(named, default=1)
    result.data = {AGENTS_KEY: [{"ID": i, "model": STATE_LIST_MODEL, "mode": "sitl",
                                        "marker_color": list(STATE_LIST_COLORS[(i - 1) % len(STATE_LIST_COLORS)])}
                                       for i in range(1, count + 1)],
                   "State_Machine": states}
    result.changes.append(f"the file is the state list alone (January 2019, when the Master's N_uav and uav_models "
                          f"gave the UAVs) -> State_Machine, with {AGENTS_KEY} of {count} {STATE_LIST_MODEL} UAV(s) "
                          f"(IDs 1..{count}, the highest the states name); write {AGENTS_KEY} to fly others")
    for index in range(len(states)):
        result.renamed[f"State_Machine[{index}]"] = f"[{index}]"


def _uav_ids(node: dict[str, Any]) -> Iterator[int]:
    """The UAV ids a node (and what it holds) names explicitly."""
    if node.get("ids_var") in ("uav", "agent"):
        ids = node.get("ids")
        for i in ids if isinstance(ids, list) else [ids]:
            if isinstance(i, int) and not isinstance(i, bool) and i >= 1:
                yield i
    for child in node.get("occurrencies") or []:
        if isinstance(child, dict):
            yield from _uav_ids(child)


def _node(node: Any, path: str, n_agents: int, result: Migration) -> None:
    if not isinstance(node, dict):
        return
    if "state_type" not in node and node.get("type") in ("CBState", "SimpleActionState"):
        _type_from_name(node, path, result)
    state_type = node.get("state_type")
    if isinstance(state_type, str) and state_type in STATE_TYPE_RENAMES:
        new_type = STATE_TYPE_RENAMES[state_type]
        node["state_type"] = new_type
        note = ""
        if state_type == "new_world" and "parameters" not in node:
            node["parameters"] = copy_json(LEGACY_NEW_WORLD)
            note = (" with parameters {action: spawn, id: 1, world_part_def: from_hyperparameters} "
                    "(world 1 from the hyperparameters' world, as new_world made it)")
        elif state_type == "spawn_uavs" and "parameters" not in node:
            node["parameters"] = {"initial_poses": [[LEGACY_SPAWN_VOLUME, LEGACY_SPAWN_GEOMETRY, "matrix", [i, 0, 0]]
                                                    for i in range(n_agents)]}
            note = (f" with parameters.initial_poses [{LEGACY_SPAWN_VOLUME}, {LEGACY_SPAWN_GEOMETRY}, matrix, "
                    f"[i, 0, 0]] for i = 0..{n_agents - 1} (where the legacy spawn put each agent)")
        result.changes.append(f"{path}.state_type: {state_type} -> {new_type}{note}")
    ids_var = node.get("ids_var")
    if isinstance(ids_var, str) and ids_var in IDS_VAR_RENAMES:
        node["ids_var"] = IDS_VAR_RENAMES[ids_var]
        result.changes.append(f"{path}.ids_var: {ids_var} -> {node['ids_var']}")
    parameters = node.get("parameters")
    if isinstance(parameters, dict):
        _three_item_definitions(parameters, f"{path}.parameters", result)
        if "time" in parameters and "duration" not in parameters:
            node["parameters"] = parameters = {("duration" if k == "time" else k): v for k, v in parameters.items()}
            result.changes.append(f"{path}.parameters.time -> duration")
            migrated = path if path.startswith("State_Machine") else f"State_Machine{path}"  # a state list's
            result.renamed[f"{migrated}.parameters.duration"] = f"{path}.parameters.time"
        if node.get("state_type") == "wait" and "exit_type" not in parameters and "duration" in parameters:
            parameters["exit_type"] = "time"
            result.changes.append(f"{path}.parameters.exit_type: added 'time' (a legacy wait of a duration)")
    children = node.get("occurrencies")
    if isinstance(children, list):
        for index, child in enumerate(children):
            _node(child, f"{path}.occurrencies[{index}]", n_agents, result)
        if node.get("type") == "Concurrence":
            _callback_outcomes_in_map(node, children, path, result)


def _type_from_name(node: dict, path: str, result: Migration) -> None:
    """Until late January 2019 a leaf had no state_type: its name was the type (new_world, take_off, ...)."""
    name = node.get("name")
    known = (*STATE_TYPE_RENAMES, *STATE_TYPE_RENAMES.values(), *NAME_TYPES)
    if isinstance(name, str) and name in known:
        node["state_type"] = name
        result.changes.append(f"{path}.state_type: added '{name}' (its name, which named the type then)")


def _three_item_definitions(parameters: dict, path: str, result: Migration) -> None:
    """[volume, geometry, "path" | "random"] (no fourth item) in paths and initial poses -> four items."""
    places: list[tuple[Any, Any, str]] = []  # (the list or object holding a definition, its index or key, its path)
    if isinstance(parameters.get("path"), list):
        places += [(item, "definition", f"{path}.path[{i}].definition")
                   for i, item in enumerate(parameters["path"]) if isinstance(item, dict)]
    if isinstance(parameters.get("initial_poses"), list):
        places += [(parameters["initial_poses"], i, f"{path}.initial_poses[{i}]")
                   for i in range(len(parameters["initial_poses"]))]
    for holder, key, where in places:
        definition = holder.get(key) if isinstance(holder, dict) else holder[key]
        if (isinstance(definition, list) and len(definition) == 3 and isinstance(definition[2], str)
                and definition[2] in THREE_ITEM_DEFINITION_ARG):
            arg, meaning = THREE_ITEM_DEFINITION_ARG[definition[2]]
            holder[key] = [*definition, arg]
            result.changes.append(f"{where}: [{', '.join(map(str, definition))}] -> fourth item {_json(arg)} "
                                  f"({meaning}, what a definition of three items meant)")


def _json(value: Any) -> str:
    return "null" if value is None else str(value)


def _callback_outcomes_in_map(node: dict, children: list, path: str, result: Migration) -> None:
    """Outcome-map conditions written in the action vocabulary on CBState children (save_csv used to be an action)."""
    outcome_map = node.get("occurrencies_outcome_map")
    if not isinstance(outcome_map, dict):
        return
    for outcome, conditions in outcome_map.items():
        if not isinstance(conditions, dict):
            continue
        for key, wanted in list(conditions.items()):
            if not isinstance(wanted, str) or wanted not in CB_OUTCOME_FOR_ACTION_OUTCOME:
                continue  # not an action outcome (a wrong type is the parser's to report)
            if key == "all":
                named = [c for c in children if isinstance(c, dict)]
            else:
                named = [c for c in children if isinstance(c, dict) and c.get("name") == key
                         and c.get("type") == "CBState"]
            if named and all(c.get("type") == "CBState" for c in named):
                conditions[key] = CB_OUTCOME_FOR_ACTION_OUTCOME[wanted]
                what = ", ".join(sorted({str(c.get("state_type")) for c in named}))
                result.changes.append(f"{path}.occurrencies_outcome_map.{outcome}.{key}: {wanted} -> {conditions[key]} "
                                      f"({what} is a CBState, which ends completed or failed)")
