"""The mission designer's side of the studio: open, check and draw a mission, and the forms of its states.

Every check is magna_gs' own, as `magna mission check [--world]` runs it: migrate, parse and validate
(`mission_from_data`), build the machine, and with a world resolve every pose definition there
(`check_in_world`). The checkers report `file: JSON.path: message` lines; each becomes a diagnostic
on that path (documents.finding). The graph is `magna mission draw`'s SVG, each state's group marked
with its magna_sm path (`data-state`), the path the running machine's introspection reports.
"""
from __future__ import annotations

import re
import tempfile
from html import escape, unescape
from pathlib import Path
from typing import Any, get_args, get_type_hints

from magna_common.errors import UsageError
from magna_common.json_fields import copy_json
from magna_gs.mission.build import InertFactory, build_machine
from magna_gs.mission.cli import mission_folders
from magna_gs.mission.loader import LoadedMission, mission_from_data, read_mission_json, resolve_mission_path
from magna_gs.mission.migrate import migrate
from magna_gs.mission.model import (
    ACTION_OUTCOMES,
    ACTION_TYPES,
    CALLBACK_OUTCOMES,
    CALLBACK_TYPES,
    CONTAINER_TYPES,
    EXIT_TYPES,
    FROM_HYPERPARAMETERS,
    IDS_VARS,
    LEAF_TYPES,
    MISSION_OUTCOMES,
    WORLD_ACTIONS,
    BasicMoveParams,
    FollowPathParams,
    MissionError,
)
from magna_gs.mission.outcome_callbacks import CHILD_TERMINATION_CALLBACKS, OUTCOME_CALLBACKS
from magna_gs.mission.plan import ROOT_LABEL, PlannedState
from magna_gs.mission.world_check import check_in_world
from magna_sm.draw import DrawError, draw
from magna_studio.documents import (
    Diagnostic,
    design_error,
    document_name,
    finding,
    in_current_schema,
    one_line,
    require_object,
)
from magna_studio.world_design import resolve_world_data, world_folders_for
from magna_worlds.errors import WorldError

ROOT_PATH = "/" + ROOT_LABEL  # the magna_sm path of the mission's root machine (build_machine names it so)


def _mission_folders(search_path: list[Path]) -> list[Path]:
    try:
        return mission_folders(search_path)
    except UsageError as error:
        raise design_error(error) from None


def _checked(data: Any, source: str, world: dict[str, Any] | None, search_path: list[Path], seed: int,
             migrated: Any = None) -> tuple[list[Diagnostic], LoadedMission | None]:
    """What `magna mission check [--world]` reports, in its order, and the mission when it loads. `migrated`: the
    document after migration, whose paths some findings of a legacy file use."""
    documents = (data,) if migrated is None else (data, migrated)
    try:
        loaded = mission_from_data(data, source)
    except MissionError as error:
        return [finding("error", problem, source, *documents) for problem in error.problems], None
    build_machine(loaded.mission, InertFactory(), loaded.plan)  # magna_sm checks the machine it would run
    diagnostics = [finding("warning", warning, source, *documents) for warning in loaded.warnings]
    if world is not None:
        diagnostics += _in_world(loaded, documents, source, world, search_path, seed)
    return diagnostics, loaded


def _in_world(loaded: LoadedMission, documents: tuple[Any, ...], source: str, world: dict[str, Any],
              search_path: list[Path], seed: int) -> list[Diagnostic]:
    """`--world`: the world's warnings (about the world: whole-file), then the mission's findings in it."""
    world_source = str(world.get("source") or "world.json")
    try:
        resolved = resolve_world_data(world["data"], world_source, search_path, seed)
    except WorldError as error:
        return [finding("error", str(error), source, *documents)]
    found = check_in_world(loaded.mission, resolved, seed, world_folders_for(search_path))
    return ([finding("warning", warning, source, *documents) for warning in [*resolved.warnings, *found.warnings]]
            + [finding("error", problem, source, *documents) for problem in found.problems])


def check_mission(data: dict[str, Any], source: str, world: dict[str, Any] | None, search_path: list[Path],
                  seed: int = 0) -> dict[str, Any]:
    """`magna mission check` of the document (with `world` {"data": world document, "source": its name}, as
    `--world`), each finding on its field; the graph (None when the mission does not load); and its states
    [{"path": magna_sm path, "type": state type or container type, "kind", "json_path"}]."""
    return _report(*_checked(data, source, world, search_path, seed))


def _report(diagnostics: list[Diagnostic], loaded: LoadedMission | None) -> dict[str, Any]:
    graph, states = None, []
    if loaded is not None:
        states = mission_states(loaded)
        try:
            graph = mission_graph_svg(loaded)
        except DrawError as error:  # the checks stand; only the picture is missing
            diagnostics = [*diagnostics, Diagnostic("warning", "", f"the graph could not be drawn: {error}",
                                                    one_line(str(error)))]  # what `magna mission draw` prints
    return {"diagnostics": [d.to_json() for d in diagnostics], "graph_svg": graph, "states": states}


def open_mission(spec: str, search_path: list[Path]) -> dict[str, Any]:
    """A mission file (a path, or MISSION/SUBMISSION looked up as `magna run` does) in the current schema: a legacy
    one migrated, its changes as `magna mission check` lists them. Its diagnostics are the command's on the file as
    written (same lines), placed on the migrated document's fields; with its graph and states as check_mission
    gives them. DesignError for a file not found or not JSON."""
    try:
        path = resolve_mission_path(spec, _mission_folders(search_path))
        raw = read_mission_json(path, str(path))
    except MissionError as error:
        raise design_error(error) from None
    migration = migrate(raw)
    data = require_object(migration.data, path, "mission")
    diagnostics, loaded = _checked(raw, str(path), None, search_path, 0, migrated=data)
    report = _report([in_current_schema(d, migration.renamed) for d in diagnostics], loaded)
    return {"path": str(path.resolve()), "name": document_name(path), "data": data,
            "schema": "legacy" if migration.changes else "current", "changes": list(migration.changes), **report}


def new_mission() -> dict[str, Any]:
    """The smallest mission that passes `magna mission check --strict`: one UAV, and the world of the run made."""
    return {
        "Agents_Config": [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5],
                           "ual_use": True, "agent_manager_on_gs": True}],
        "State_Machine": [
            {"type": "CBState", "state_type": "world_config", "name": "new_world",
             "parameters": {"action": "spawn", "id": 1, "world_part_def": FROM_HYPERPARAMETERS},
             "outcomes": {"completed": "completed", "failed": "failed"}},
        ],
    }


def mission_states(loaded: LoadedMission) -> list[dict[str, Any]]:
    """Every state of the expanded machine, the root first: its magna_sm path (the SVG's `data-state`), its state
    type (a leaf) or container type, its kind and the JSON path of the node that makes it."""
    assert loaded.plan is not None, "a mission loaded with validation has its plan"
    states = [{"path": ROOT_PATH, "type": "StateMachine", "kind": "StateMachine", "json_path": "State_Machine"}]

    def walk(state: PlannedState, path: str) -> None:
        for child in state.children:
            child_path = f"{path}/{child.label}"
            states.append({"path": child_path, "type": child.state_type or child.kind, "kind": child.kind,
                           "json_path": child.json_path})
            walk(child, child_path)

    walk(loaded.plan.root, ROOT_PATH)
    return states


# --- the graph -----------------------------------------------------------------------------------------------------

_GROUP = re.compile(r'<g id="[^"]*" class="(node|cluster)">\s*<title>([^<]*)</title>')
_ANCHOR = "/__anchor"  # magna_sm.draw's node that stands for a container
_CLUSTER = "cluster_"  # magna_sm.draw's name of a container's box
_OUTCOME = "/:"  # magna_sm.draw's node of a container's outcome: <container path>/:<outcome>


def mission_graph_svg(loaded: LoadedMission) -> str:
    """The SVG `magna mission draw` writes (magna_sm.draw through graphviz), every state's `<g>` carrying
    `data-state="<magna_sm path>"` (a leaf's node; a container's box, or its node when dot drew it flat) and every
    container outcome's `data-outcome="<container path>/:<outcome>"`. DrawError when graphviz cannot draw it."""
    machine = build_machine(loaded.mission, InertFactory(), loaded.plan)
    count = len(mission_states(loaded)) - 1  # as the command's title counts them: the root is no state of the file
    with tempfile.TemporaryDirectory(prefix="magna_studio_") as folder:
        drawn = draw(machine, Path(folder) / "mission.svg", title=f"{loaded.mission.source} ({count} states)",
                     show_active=False)
        svg = drawn.read_text(encoding="utf-8")
    return _GROUP.sub(_mark, svg)


def _mark(match: re.Match[str]) -> str:
    title = unescape(match.group(2))
    if match.group(1) == "cluster":
        attribute, value = "data-state", title.removeprefix(_CLUSTER)
    elif _OUTCOME in title:
        attribute, value = "data-outcome", title
    else:
        attribute, value = "data-state", title.removesuffix(_ANCHOR)
    group = match.group(0)
    at = group.index(">")
    return f'{group[:at]} {attribute}="{escape(value, quote=True)}"{group[at:]}'


# --- the forms -----------------------------------------------------------------------------------------------------

def _param(name: str, kind: str, doc: str, *, required: bool = False, default: Any = None,
           choices: tuple[Any, ...] | list[Any] = (), example: Any = None, **more: Any) -> dict[str, Any]:
    """One form field: {"name", "kind" (number | text | bool | choice | pose | uav | list), "default" (what the
    parser takes when it is left out), "choices", "required", "doc", "example" (a value the parser accepts, to start
    the form with)}, and where they apply: "items" (what a list holds: pose, number, text, any, volume, transition,
    outcome_condition), "item_key" (each item is {item_key: item}, as a path's {"definition": ...}), "also" (texts
    taken instead of the list or id: "from utm", "from_hyperparameters", "all"), "yaw" (a pose may add a yaw),
    "length", "integer", "minimum", "exclusive_minimum", "many" (several ids), "required_when" ({field: [values]}:
    required when that field holds one of them)."""
    return {"name": name, "kind": kind, "default": default, "choices": list(choices), "required": required,
            "doc": doc, "example": default if example is None else example, **more}


def _choices(params: type, field: str) -> tuple[str, ...]:
    """The values a parameter takes, read from its typed field in magna_gs.mission.model (a Literal)."""
    return get_args(get_type_hints(params)[field])


_DURATION = "seconds allowed, >= 0 (0: no limit)"
_PATH_DOC = ('the waypoints: [{"definition": [volume, geometry or "volume", kind, arg]}, ...] (pick them in the '
             'world); "from utm" flies the UTM flight plan')
_EXAMPLE_PATH = [{"definition": ["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]]}]

# Per state type the parameters `magna_gs.mission.parse` reads: names, defaults and what each holds.
_FORMS: dict[str, tuple[str, list[dict[str, Any]]]] = {
    "take_off": ("take off to a height above the take-off point", [
        _param("height", "number", "m above the take-off point, > 0", required=True, example=2.0, minimum=0,
               exclusive_minimum=True)]),
    "land": ("land where the UAV is", [
        _param("height", "number", "written by the original's missions; landing does not use it")]),
    "follow_path": ("fly a path of pose definitions", [
        _param("path", "list", _PATH_DOC, required=True, example=_EXAMPLE_PATH, items="pose",
               item_key="definition", also=["from utm"]),
        _param("smooth_path_mode", "number", "0: straight segments; n >= 1: a spline of order n", default=0,
               integer=True, minimum=0),
        _param("dynamic", "choice", "how the UAV is commanded", default="velocity",
               choices=_choices(FollowPathParams, "dynamic")),
        _param("duration", "number", _DURATION, default=0.0, minimum=0)]),
    "basic_move": ("a move relative to where the UAV is", [
        _param("move_type", "choice", "what kind of move", required=True,
               choices=_choices(BasicMoveParams, "move_type"), example="translation"),
        _param("dynamic", "choice", "how the UAV is commanded", required=True,
               choices=_choices(BasicMoveParams, "dynamic"), example="position"),
        _param("direction", "choice", "which way", required=True, choices=_choices(BasicMoveParams, "direction"),
               example="up"),
        _param("value", "number", "m (translation) or degrees (rotation)", required=True, example=1.0),
        _param("duration", "number", _DURATION, default=0.0, minimum=0)]),
    "follow_agent_ad": ("follow another agent at a distance behind it", [
        _param("target_ID", "uav", "the agent to follow (an ID of Agents_Config, not the follower)", required=True,
               example=1),
        _param("distance", "number", "m behind the target, > 0", required=True, example=2.0, minimum=0,
               exclusive_minimum=True),
        _param("duration", "number", "seconds to follow, >= 0 (0: until preempted)", default=0.0, minimum=0)]),
    "follow_agent_ap": ("follow another agent at an offset from it", [
        _param("target_ID", "uav", "the agent to follow (an ID of Agents_Config, not the follower)", required=True,
               example=1),
        _param("pos", "list", "[x, y, z]: the offset from the target in m, map frame", required=True,
               example=[0.0, -2.0, 1.0], items="number", length=3),
        _param("duration", "number", "seconds to follow, >= 0 (0: until preempted)", default=0.0, minimum=0)]),
    "save_csv": ("save the agents' data to their CSV files", []),
    "set_mission": ("hand a UAV its whole path at once", [
        _param("path", "list", 'the waypoints: [{"definition": [volume, geometry or "volume", kind, arg]}, ...]',
               required=True, example=_EXAMPLE_PATH, items="pose", item_key="definition"),
        _param("include_takeoff", "bool", "take off first", default=False),
        _param("include_land", "bool", "land at the end", default=False)]),
    "world_config": ("make, extend or remove a world (part) in the world node", [
        _param("action", "choice", "spawn a world, add a part to it, or delete one", required=True,
               choices=WORLD_ACTIONS, example="spawn"),
        _param("id", "text", "the world (part) id (a name or a whole number); needed by spawn and delete",
               required_when={"action": ["spawn", "delete"]}, example=1),
        _param("world_part_def", "list", f'"{FROM_HYPERPARAMETERS}" (the world of the run) or a list of world '
               "volumes written inline; needed by add, refused by delete", items="volume",
               also=[FROM_HYPERPARAMETERS], required_when={"action": ["add"]}, example=FROM_HYPERPARAMETERS)]),
    "wait": ("wait for a time or for the operator's button", [
        _param("exit_type", "choice", "what ends the wait", required=True, choices=EXIT_TYPES, example="time"),
        _param("duration", "number", "seconds to wait, >= 0 (a button wait ignores it)", default=0.0, minimum=0,
               example=1.0)]),
    "spawn_agents": ("spawn the agents, one pose per agent in Agents_Config order", [
        _param("initial_poses", "list", "[volume, geometry, kind, arg, yaw?] per agent, in Agents_Config order "
               "(the yaw in radians)", required=True, items="pose", yaw=True,
               example=[["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]]])]),
    "algorithm_control": ("select or configure the agents' navigation algorithm", [
        _param("name", "text", "the algorithm: simple, orca3d (orca3) or neural_network", required=True,
               example="orca3d"),
        _param("action", "text", "set (select and configure) or configure (only change parameters)",
               required=True, example="set"),
        _param("params", "list", "the names of the parameters to set", default=[], items="text"),
        _param("values", "list", "one value per name in params", default=[], items="any"),
        _param("text_value", "text", "a text parameter, e.g. the path of a TorchScript model (not empty)",
               default="", example="models/policy.pt")]),
}

_NODE_FIELDS = [
    _param("name", "text", "the state's name; action states and containers are registered as {id}_{name}",
           required=True),
    _param("ids", "uav", 'the UAV(s) (or, with ids_var "wp", the waypoints): an ID, a list of IDs, or "all"',
           many=True, also=["all"]),
    _param("ids_var", "choice", '"agent": ids are agents; "wp": one action state per waypoint of its path',
           choices=IDS_VARS),
    _param("outcomes", "list", "transitions {outcome: the label of a state of the same container, or an "
           "outcome of the container}", items="transition"),
]

_CONTAINER_FORMS: dict[str, tuple[str, list[dict[str, Any]]]] = {
    "StateMachine": ("states run one after another, as their transitions say; the first starts", []),
    "Concurrence": ("states run together; the outcome map (or outcome_cb) decides how it ends", [
        _param("occurrencies_outcome_map", "list", '{container outcome: {child label or "all": child outcome}}',
               items="outcome_condition"),
        _param("outcome_cb", "choice", "a callback that decides the outcome", choices=tuple(OUTCOME_CALLBACKS)),
        _param("child_termination_cb", "choice", "a callback that decides when the others are preempted",
               choices=tuple(CHILD_TERMINATION_CALLBACKS))]),
    "Sequence": ("states chained by one outcome, in the order written", [
        _param("connector_outcome", "text", "the outcome that goes on to the next state (e.g. succeeded)",
               required=True, example="succeeded")]),
}


def state_types() -> dict[str, Any]:
    """The forms of the mission designer, from magna_gs.mission.model's vocabulary:
    {"states": {state type: {"doc", "leaf_types": the node types it may be, "outcomes", "parameters": [field]}},
     "leaf_types": {CBState|SimpleActionState: {"state_types", "outcomes"}},
     "containers": {container type: {"doc", "fields": [field]}}, "node_fields": [field] (every node),
     "mission_outcomes"}, a field being {"name", "kind", "default", "choices", "required", "doc", "example", ...}
    (kind number | text | bool | choice | pose | uav | list; a list says its `items`)."""
    leaf_types = {"SimpleActionState": (ACTION_TYPES, ACTION_OUTCOMES), "CBState": (CALLBACK_TYPES, CALLBACK_OUTCOMES)}
    states: dict[str, dict[str, Any]] = {}
    for leaf in LEAF_TYPES:
        types, outcomes = leaf_types[leaf]
        for state_type in types:
            doc, parameters = _FORMS[state_type]
            entry = states.setdefault(state_type, {"doc": doc, "leaf_types": [], "outcomes": {}, "parameters":
                                                   parameters})
            entry["leaf_types"].append(leaf)
            entry["outcomes"][leaf] = list(outcomes)
    return copy_json({  # the caller may fill the forms in: the tables here stay as they are
        "states": states,
        "leaf_types": {leaf: {"state_types": list(types), "outcomes": list(outcomes)}
                       for leaf, (types, outcomes) in leaf_types.items()},
        "containers": {kind: {"doc": _CONTAINER_FORMS[kind][0], "fields": _CONTAINER_FORMS[kind][1]}
                       for kind in CONTAINER_TYPES},
        "node_fields": _NODE_FIELDS,
        "mission_outcomes": list(MISSION_OUTCOMES),
    })
