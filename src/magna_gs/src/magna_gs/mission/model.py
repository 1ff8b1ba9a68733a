"""A mission as typed objects: agents, and the tree of state nodes with typed parameters.

The JSON format (the original ROS-MAGNA's, both of its schemas) is read once by `parse` into
these objects; everything after (validation, planning, building, world checks) reads
attributes, never dictionaries. Every node keeps its JSON path, so any later finding
can say where in the file it is (`State_Machine[7].occurrencies[0].parameters.path[2]`).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

from magna_common.errors import UserError
from magna_uav.config import UavConfig
from magna_uav.vocabulary import Direction, Dynamic, MoveType
from magna_worlds.vocabulary import PoseKind

# --- vocabulary: each fixed value set a Literal type and the tuple of its values (plain strings at run time) ------
# (basic_move's move types, directions and dynamics are magna_uav.vocabulary's: the UAV manager takes them too)

LeafType = Literal["CBState", "SimpleActionState"]
LEAF_TYPES: tuple[LeafType, ...] = get_args(LeafType)
ContainerType = Literal["StateMachine", "Concurrence", "Sequence"]
CONTAINER_TYPES: tuple[ContainerType, ...] = get_args(ContainerType)
NodeType = Literal[LeafType, ContainerType]
NODE_TYPES: tuple[NodeType, ...] = get_args(NodeType)

# What a SimpleActionState (one goal to one UAV manager) can end with.
ActionOutcome = Literal["succeeded", "collision", "low_battery", "GS_critical_event", "utm_new_flightplan",
                        "preempted", "aborted"]
ACTION_OUTCOMES: tuple[ActionOutcome, ...] = get_args(ActionOutcome)
# What a CBState (work done by the ground station itself) can end with.
CallbackOutcome = Literal["completed", "failed"]
CALLBACK_OUTCOMES: tuple[CallbackOutcome, ...] = get_args(CallbackOutcome)

# The state types of each leaf type (save_csv is both: a UAV's own, or the ground station's for several agents).
ActionType = Literal["take_off", "land", "follow_path", "basic_move", "follow_agent_ad", "follow_agent_ap", "save_csv",
                     "set_mission"]
ACTION_TYPES: tuple[ActionType, ...] = get_args(ActionType)
CallbackType = Literal["world_config", "wait", "spawn_agents", "algorithm_control", "save_csv"]
CALLBACK_TYPES: tuple[CallbackType, ...] = get_args(CallbackType)
StateType = Literal[ActionType, CallbackType]

# How `ids` expands when it is "all" (or what each id means): one state per agent, or per waypoint of the path.
IdsVar = Literal["agent", "wp"]
IDS_VARS: tuple[IdsVar, ...] = get_args(IdsVar)

# The outcomes a top-level transition may end the mission with (the original's root machine had exactly these).
MissionOutcome = Literal["completed", "failed"]
MISSION_OUTCOMES: tuple[MissionOutcome, ...] = get_args(MissionOutcome)
# The outcome of a Concurrence when neither its outcome_cb nor its occurrencies_outcome_map decides (as the original).
CONCURRENCE_DEFAULT_OUTCOME = "completed"
ALL_CHILDREN = "all"  # occurrencies_outcome_map key: every expanded child

WorldAction = Literal["spawn", "add", "delete"]  # world_config
WORLD_ACTIONS: tuple[WorldAction, ...] = get_args(WorldAction)
ExitType = Literal["time", "button"]  # what ends a wait
EXIT_TYPES: tuple[ExitType, ...] = get_args(ExitType)
FROM_HYPERPARAMETERS = "from_hyperparameters"
# The mission's permission for operator commands (/magna/gs/command) to real UAVs: {"allow_real": [ids] | "all"}.
OPERATOR_COMMANDS_KEY = "Operator_Commands"
ALLOW_REAL = "allow_real"
FROM_UTM = ("from utm", "from_utm")  # a follow_path whose path the UTM provides at run time


class MissionError(UserError, ValueError):
    """Bad mission input. `problems` lists every finding, each `file: JSON.path: what is wrong; how to fix it`."""

    def __init__(self, problems: list[str] | str):
        self.problems = [problems] if isinstance(problems, str) else list(problems)
        super().__init__("\n".join(self.problems))


# --- pose definitions ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PoseDefinition:
    """`[volume, geometry | "volume", kind, arg, yaw?]`: poses of the world, resolved by magna_worlds.query."""

    volume: str
    geometry: str
    kind: PoseKind
    arg: Any  # as written: [i, j, k] | N | pose(s) | path name or index | set index
    yaw: float | None = None  # spawn_agents only: the heading to spawn with (radians)
    json_path: str = ""

    def as_list(self) -> list[Any]:
        """The definition as the world node's query takes it."""
        items = [self.volume, self.geometry, self.kind, self.arg]
        return items if self.yaw is None else [*items, self.yaw]

    def __iter__(self) -> Iterator[Any]:
        """A definition reads as the list the files write: `volume, geometry, kind, arg = definition`."""
        return iter(self.as_list())

    def __str__(self) -> str:
        return f"[{self.volume}, {self.geometry}, {self.kind}, {self.arg}]"


# --- parameters of the action states ------------------------------------------------------------------------------

@dataclass(frozen=True)
class TakeOffParams:
    height: float  # m above the take-off point


@dataclass(frozen=True)
class LandParams:
    height: float | None = None  # written by the original missions; landing does not use it


@dataclass(frozen=True)
class FollowPathParams:
    path: tuple[PoseDefinition, ...]  # empty when from_utm
    smooth_path_mode: int = 0  # 0: straight segments; n > 0: spline of order n
    dynamic: Dynamic = "velocity"
    duration: float = 0.0  # s allowed; 0: no limit
    from_utm: bool = False  # the path comes from the UTM flight plan at run time


@dataclass(frozen=True)
class BasicMoveParams:
    move_type: MoveType
    dynamic: Dynamic
    direction: Direction
    value: float  # m (translation) or degrees (rotation)
    duration: float = 0.0  # s allowed; 0: no limit


@dataclass(frozen=True)
class FollowAgentADParams:
    target_ID: int  # the mission's spelling
    distance: float  # m
    duration: float = 0.0  # s to follow; 0: until preempted


@dataclass(frozen=True)
class FollowAgentAPParams:
    target_ID: int
    pos: tuple[float, float, float]  # offset from the target, map frame (m)
    duration: float = 0.0


@dataclass(frozen=True)
class SaveCsvParams:
    pass


@dataclass(frozen=True)
class SetMissionParams:
    path: tuple[PoseDefinition, ...]
    include_takeoff: bool = False
    include_land: bool = False


# --- parameters of the callback states ----------------------------------------------------------------------------

@dataclass(frozen=True)
class WorldPartDef:
    """What a world_config state adds: the world of the hyperparameters, or volumes written inline."""

    from_hyperparameters: bool = False
    volumes: tuple[Any, ...] = ()  # world-format volume objects (magna_worlds reads them), when inline
    json_path: str = ""


@dataclass(frozen=True)
class WorldConfigParams:
    action: WorldAction
    id: str | None = None  # the world (part) id: spawn and delete name one; add joins the last spawned by default
    world_part_def: WorldPartDef | None = None  # add (and spawn, when the world comes with it)


@dataclass(frozen=True)
class WaitParams:
    exit_type: ExitType
    duration: float = 0.0  # s (time)


@dataclass(frozen=True)
class SpawnAgentsParams:
    initial_poses: tuple[PoseDefinition, ...]  # initial_poses[i] for the i-th agent of Agents_Config


@dataclass(frozen=True)
class AlgorithmControlParams:
    name: str  # simple | orca3d (orca3) | neural_network
    action: str  # set | configure
    params: tuple[str, ...] = ()
    values: tuple[Any, ...] = ()
    text_value: str = ""


ActionParameters = (TakeOffParams | LandParams | FollowPathParams | BasicMoveParams | FollowAgentADParams
                    | FollowAgentAPParams | SaveCsvParams | SetMissionParams)
CallbackParameters = WorldConfigParams | WaitParams | SpawnAgentsParams | AlgorithmControlParams | SaveCsvParams
Parameters = ActionParameters | CallbackParameters


# --- the tree ------------------------------------------------------------------------------------------------------

Ids = int | tuple[int, ...] | Literal["all"]  # an id, a list of ids, or "all"


@dataclass(frozen=True)
class Node:
    """One entry of State_Machine (or of a container's occurrencies), as written, typed."""

    kind: NodeType
    name: str
    json_path: str  # e.g. "State_Machine[7].occurrencies[0]"
    state_type: StateType | None = None  # leaves: one of ACTION_TYPES / CALLBACK_TYPES
    parameters: Parameters | None = None  # leaves: typed by state_type
    outcomes: dict[str, str] = field(default_factory=dict)  # transitions {outcome: state label | container outcome}
    ids: Ids | None = None
    ids_var: IdsVar | None = None
    occurrencies: tuple[Node, ...] = ()  # containers: the children (spelled so in the files)
    occurrencies_outcome_map: dict[str, dict[str, str]] = field(default_factory=dict)  # Concurrence
    outcome_cb: str | None = None  # Concurrence: a name in outcome_callbacks.OUTCOME_CALLBACKS
    child_termination_cb: str | None = None  # Concurrence: a name in outcome_callbacks.CHILD_TERMINATION_CALLBACKS
    connector_outcome: str | None = None  # Sequence

    @property
    def is_container(self) -> bool:
        return self.kind in CONTAINER_TYPES

    @property
    def is_action(self) -> bool:
        return self.kind == "SimpleActionState"

    def walk(self) -> Iterator[Node]:
        """This node and every node below it, depth first, in file order."""
        yield self
        for child in self.occurrencies:
            yield from child.walk()


@dataclass(frozen=True)
class Mission:
    source: str  # the file (as given) or another description of where the JSON came from
    agents: list[UavConfig]
    root: list[Node]  # State_Machine, in file order
    agents_key: str = "Agents_Config"  # the key the file used (legacy files: UAVs_Config)
    operator_real_ids: tuple[int, ...] = ()  # Operator_Commands.allow_real: real UAVs the operator may command

    @property
    def agent_ids(self) -> list[int]:
        return [agent.id for agent in self.agents]

    @property
    def operator_locked_ids(self) -> frozenset[int]:
        """The real UAVs the operator may not command: a command for them is refused unless the mission lists them
        under Operator_Commands.allow_real (sitl and hil UAVs take commands without it)."""
        return frozenset(a.id for a in self.agents if a.mode == "real" and a.id not in self.operator_real_ids)

    def nodes(self) -> Iterator[Node]:
        """Every node of the mission, depth first, in file order."""
        for node in self.root:
            yield from node.walk()

    def where(self, json_path: str) -> str:
        """`file: JSON.path`, the start of every message about this mission."""
        return f"{self.source}: {json_path}" if json_path else self.source
