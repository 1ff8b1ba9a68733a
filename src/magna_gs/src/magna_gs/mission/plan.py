"""The mission tree expanded into the states the machine will have: labels, UAVs, transitions, outcomes.

`plan_mission(mission)` is pure data (no magna_sm objects): `validate` reports on it,
`build` turns it into a machine, the CLI counts it. The rules, as the original
ROS-MAGNA ground station applied them (where it left a case undefined or crashing,
the rule chosen here is said so):

Expansion (`ids`, `ids_var`)
- `ids` is an id, a list of ids, or "all". With `ids_var: agent`, "all" means every
  agent of Agents_Config; with `ids_var: wp` it means 1..N, N the number of
  definitions in the state's `parameters.path`.
- A SimpleActionState becomes one state per id, labelled `{id}_{name}`. With `agent`
  (or no ids_var) the id is the UAV that flies it. With `wp` each copy flies only
  waypoint `id` of the path (the original's step-by-step path following), and the UAV
  is the id of the nearest enclosing container with `ids_var: agent` (an error if
  there is none). In a StateMachine the copies are chained (copy k's "succeeded"
  goes to copy k+1; the last keeps the written transitions: the original left the
  copies after the first unreachable); in a Sequence the connector chains them; in a
  Concurrence they would fly every waypoint at once, which is refused.
- A container becomes one container per id, labelled `{id}_{name}`; without ids_var
  the id only names it; with `ids_var: agent` it is also the UAV of the `wp` states
  inside. Inside such a container an action state may leave out `ids` (it flies that UAV).
- A CBState is one state and keeps its `name`; its ids (expanded the same way) are the
  agents it addresses (save_csv, algorithm_control). spawn_agents addresses every
  agent unless ids are given.
- An action state naming a UAV that Agents_Config does not configure (real missions
  keep safety branches written for more UAVs than they fly) is kept, marked `absent`,
  and ends "aborted" at once when reached, as the original's did when no UAV manager
  served its goal (a warning says so).

Outcomes
- Leaves end with `model.ACTION_OUTCOMES` or `model.CALLBACK_OUTCOMES`.
- In a StateMachine (or Sequence), `outcomes` maps a child's outcome to a sibling's
  label or to an outcome of the container: the keys of the container's own `outcomes`
  (what its parent maps), or at the top level "completed" or "failed" (the original's
  root outcomes). Anything else is an error: `no state named '1_land'`.
- A child outcome with no transition ends the container with the outcome of the same
  name (smach's rule; the original crashed when that outcome was not declared).
  Here the container declares it, so it reaches the parent, and the top-level machine
  ends with it; `validate` lists these as warnings. "preempted" is every container's.
- A Concurrence ends with its outcome_cb's answer when it gives one, else with the
  satisfied occurrencies_outcome_map entry with the most conditions (key "all": every
  expanded child), else "completed" (the original's default_outcome).
- A container's outcomes are exactly those its children can produce (plus
  "preempted"): an outcome written in `outcomes` that nothing inside can produce is
  dropped, and the parent's transition for it is never taken (a warning). An outcome
  map entry that waits for an outcome a child can never produce (not even one outside
  the child's vocabulary, e.g. "completed" of an action state: the original's map just
  never matched) is dropped likewise.
"""
from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field

from magna_gs.mission.model import (
    ACTION_OUTCOMES,
    ALL_CHILDREN,
    CALLBACK_OUTCOMES,
    CONCURRENCE_DEFAULT_OUTCOME,
    MISSION_OUTCOMES,
    FollowPathParams,
    Ids,
    Mission,
    Node,
    NodeType,
    Parameters,
    SetMissionParams,
    StateType,
)
from magna_gs.mission.outcome_callbacks import CHILD_TERMINATION_CALLBACKS, OUTCOME_CALLBACKS

PREEMPTED = "preempted"  # every container's (magna_sm adds it)
WP_CHAIN_OUTCOME = "succeeded"  # how wp copies follow each other in a StateMachine
ROOT_LABEL = "MISSION"
# What an action state for a UAV the mission does not configure ends with: the original's goal found no action
# server and its SimpleActionState ended so.
ABSENT_UAV_OUTCOME = "aborted"


@dataclass
class PlannedState:
    """One state of the machine to build."""

    label: str
    node: Node | None  # None for the mission's root machine
    kind: NodeType
    uav: int | None = None  # SimpleActionState: the UAV that flies it
    ids: tuple[int, ...] = ()  # CBState: the agents it addresses
    parameters: Parameters | None = None  # leaves: what the factory is given (wp: one waypoint)
    transitions: dict[str, str] = field(default_factory=dict)  # in a StateMachine/Sequence: outcome -> target
    outcomes: tuple[str, ...] = ()  # what it can end with
    children: list[PlannedState] = field(default_factory=list)
    outcome_map: dict[str, dict[str, str]] = field(default_factory=dict)  # Concurrence: expanded, pruned
    default_outcome: str | None = None  # Concurrence
    connector_outcome: str | None = None  # Sequence
    absent: bool = False  # SimpleActionState of a UAV the mission does not configure: ends ABSENT_UAV_OUTCOME at once

    @property
    def file_node(self) -> Node:
        """The node of the file this state comes from: every state's but the mission's root machine's."""
        if self.node is None:
            raise AttributeError(f"{self.label} is the mission's root machine, which no node of the file writes")
        return self.node

    @property
    def json_path(self) -> str:
        return self.node.json_path if self.node is not None else "State_Machine"

    @property
    def state_type(self) -> StateType | None:
        return self.node.state_type if self.node is not None else None

    def walk(self) -> Iterator[PlannedState]:
        yield self
        for child in self.children:
            yield from child.walk()

    def leaves(self) -> Iterator[PlannedState]:
        return (state for state in self.walk() if not state.children and state.node is not None
                and not state.node.is_container)


@dataclass
class Plan:
    root: PlannedState  # the top-level StateMachine (label MISSION)
    problems: list[str]  # `file: path: message`, each one a reason the machine cannot be built
    warnings: list[str]

    @property
    def outcomes(self) -> tuple[str, ...]:
        return self.root.outcomes


@dataclass(frozen=True)
class _Context:
    agent: int | None = None  # from the nearest enclosing container with ids_var agent


class _Planner:
    def __init__(self, mission: Mission):
        self.mission = mission
        self.agents = mission.agent_ids
        self.problems: list[str] = []
        self.warnings: list[str] = []
        self._ignored: set[str] = set()  # nodes already warned about ignored outcomes

    def where(self, path: str) -> str:
        return self.mission.where(path)

    def fail(self, path: str, message: str) -> None:
        self.problems.append(f"{self.where(path)}: {message}")

    def warn(self, path: str, message: str) -> None:
        self.warnings.append(f"{self.where(path)}: {message}")

    # --- expansion ------------------------------------------------------------------------------------------------

    def _agent_ids(self, node: Node, ids: Ids, what: str) -> list[int]:
        """ids meaning agents -> the list; problems for ids not in Agents_Config."""
        if ids == "all":
            return list(self.agents)
        listed = _written_ids(ids)
        unknown = [i for i in listed if i not in self.agents]
        if unknown:
            self.fail(f"{node.json_path}.ids", f"{what} {', '.join(map(str, unknown))} not in "
                      f"{self.mission.agents_key} (IDs {', '.join(map(str, self.agents)) or 'none'})")
            return [i for i in listed if i in self.agents]
        return listed

    def expand(self, node: Node, ctx: _Context, parent_kind: str) -> list[PlannedState]:
        if node.kind == "CBState":
            return [self._callback(node, ctx)]
        if node.kind == "SimpleActionState":
            return self._actions(node, ctx, parent_kind)
        return self._containers(node, ctx)

    def _callback(self, node: Node, ctx: _Context) -> PlannedState:
        ids: list[int] = []
        if node.ids_var == "wp":
            self.fail(f"{node.json_path}.ids_var", "'wp' repeats an action state per waypoint of its path; a CBState "
                      "is one state (its ids are the agents it addresses): use ids_var 'agent'")
        elif node.ids is not None:
            if node.ids == "all" and node.ids_var is None:
                self.fail(f"{node.json_path}.ids_var", "ids \"all\" needs ids_var 'agent' (every agent)")
            else:
                ids = self._agent_ids(node, node.ids, "agent")
        elif node.state_type == "spawn_agents":
            ids = list(self.agents)
        elif node.state_type in ("save_csv", "algorithm_control"):
            if ctx.agent is not None:
                ids = [ctx.agent]
            else:
                self.fail(f"{node.json_path}.ids", f"missing; {node.state_type} addresses agents: give their ids "
                          "(e.g. \"ids\": \"all\", \"ids_var\": \"agent\")")
        return PlannedState(node.name, node, "CBState", ids=tuple(ids), parameters=node.parameters,
                            outcomes=CALLBACK_OUTCOMES)

    def _actions(self, node: Node, ctx: _Context, parent_kind: str) -> list[PlannedState]:
        if node.ids_var == "wp":
            return self._waypoints(node, ctx, parent_kind)
        if node.ids is None:
            if ctx.agent is None:
                self.fail(f"{node.json_path}.ids", "missing; give the UAV(s) that fly this state (an id, a list, or "
                          "\"all\" with \"ids_var\": \"agent\")")
                return []
            uavs = [ctx.agent]
        elif node.ids == "all" and node.ids_var is None:
            self.fail(f"{node.json_path}.ids_var", "ids \"all\" needs ids_var 'agent' (every agent) or 'wp' (every "
                      "waypoint of parameters.path)")
            return []
        else:
            uavs = list(self.agents) if node.ids == "all" else _written_ids(node.ids)
        absent = [uav for uav in uavs if uav not in self.agents]
        if absent:
            labels = ", ".join(f"'{uav}_{node.name}'" for uav in absent)
            self.warn(f"{node.json_path}.ids", f"UAV {', '.join(map(str, absent))} not in {self.mission.agents_key} "
                      f"(IDs {', '.join(map(str, self.agents)) or 'none'}): no UAV manager will answer {labels}, so "
                      f"if this state is reached it ends '{ABSENT_UAV_OUTCOME}' at once, as in the original (whose "
                      "goal found no action server); configure the UAV or remove the state")
        return [PlannedState(f"{uav}_{node.name}", node, "SimpleActionState", uav=uav, parameters=node.parameters,
                             outcomes=ACTION_OUTCOMES, absent=uav not in self.agents) for uav in uavs]

    def _waypoints(self, node: Node, ctx: _Context, parent_kind: str) -> list[PlannedState]:
        params = node.parameters
        if not isinstance(params, FollowPathParams | SetMissionParams) or not params.path:
            self.fail(f"{node.json_path}.ids_var", f"'wp' makes one state per waypoint of parameters.path; "
                      f"{node.state_type} has no path written out")
            return []
        if parent_kind == "Concurrence":
            self.fail(f"{node.json_path}.ids_var", "'wp' in a Concurrence would fly every waypoint at once; put the "
                      "state in a Sequence or StateMachine")
            return []
        if ctx.agent is None:
            self.fail(f"{node.json_path}.ids_var", "'wp' states take their UAV from an enclosing container with "
                      "\"ids_var\": \"agent\"; there is none")
            return []
        count = len(params.path)
        if node.ids is None or node.ids == "all":
            numbers = list(range(1, count + 1))
        else:
            numbers = _written_ids(node.ids)
            bad = [n for n in numbers if not 1 <= n <= count]
            if bad:
                self.fail(f"{node.json_path}.ids", f"waypoint(s) {', '.join(map(str, bad))} out of range: "
                          f"parameters.path has {count} (numbered from 1)")
                return []
        return [PlannedState(f"{n}_{node.name}", node, "SimpleActionState", uav=ctx.agent,
                             parameters=dataclasses.replace(params, path=(params.path[n - 1],)),
                             outcomes=ACTION_OUTCOMES) for n in numbers]

    def _containers(self, node: Node, ctx: _Context) -> list[PlannedState]:
        if node.ids_var == "wp":
            self.fail(f"{node.json_path}.ids_var", "'wp' is for action states with a path; a container is repeated "
                      "per agent with ids_var 'agent'")
            return []
        if node.ids is None:
            if ctx.agent is None:
                self.fail(f"{node.json_path}.ids", "missing; a container is registered as {id}_{name}: give an id "
                          "(e.g. 1)")
                return []
            ids = [ctx.agent]
        elif node.ids == "all" and node.ids_var is None:
            self.fail(f"{node.json_path}.ids_var", "ids \"all\" needs ids_var 'agent' (one container per agent)")
            return []
        elif node.ids_var == "agent":
            ids = self._agent_ids(node, node.ids, "agent")
        else:
            ids = _written_ids(node.ids)
        out = []
        for container_id in ids:
            inner = _Context(container_id) if node.ids_var == "agent" else ctx
            label = f"{container_id}_{node.name}"
            children = [c for child in node.occurrencies for c in self.expand(child, inner, node.kind)]
            state = PlannedState(label, node, node.kind, children=children)
            if node.kind == "Concurrence":
                self._concurrence(state)
            else:
                self._machine(state, tuple(node.outcomes), f"'{label}'")
            out.append(state)
        return out

    # --- outcomes -------------------------------------------------------------------------------------------------

    def _unique_labels(self, state: PlannedState, declared: tuple[str, ...]) -> dict[str, PlannedState]:
        labels: dict[str, PlannedState] = {}
        for child in state.children:
            if child.label in labels:
                other = labels[child.label]
                self.fail(child.json_path, f"label '{child.label}' is taken by {other.json_path} in the same "
                          "container; give one of them another name or id")
            elif child.label in declared or child.label == PREEMPTED:
                self.fail(f"{child.json_path}.name", f"label '{child.label}' is also an outcome of the container "
                          f"({state.label}); rename the state")
            else:
                labels[child.label] = child
        return labels

    def _machine(self, state: PlannedState, declared: tuple[str, ...], what: str) -> None:
        """StateMachine or Sequence (or the root): effective transitions, reachability, outcomes."""
        labels = self._unique_labels(state, declared)
        connector = state.node.connector_outcome if state.node is not None else None
        state.connector_outcome = connector
        children = state.children
        problems_before = len(self.problems)
        for index, child in enumerate(children):
            written = dict(child.file_node.outcomes)
            following = children[index + 1] if index + 1 < len(children) else None
            if (child.file_node.ids_var == "wp" and state.kind == "StateMachine" and following is not None
                    and following.node is child.node):
                written[WP_CHAIN_OUTCOME] = following.label
            transitions = {}
            for outcome, target in written.items():
                where = f"{child.json_path}.outcomes.{outcome}"
                if outcome not in child.outcomes:
                    if child.file_node.is_container and outcome in child.file_node.outcomes:
                        self.warn(where, f"never taken: '{child.label}' cannot end with '{outcome}' (no state inside "
                                  "leads to it)")
                    else:
                        self.fail(where, f"'{child.label}' never ends with '{outcome}'; its outcomes: "
                                  f"{', '.join(child.outcomes)}")
                    continue
                if target not in labels and target not in declared:
                    outcomes_text = f"or end {what} with {' or '.join(declared)}" if declared else \
                        f"{what} declares no outcomes of its own (its 'outcomes' in the parent)"
                    self.fail(where, f"no state named '{target}'; states here: {', '.join(labels) or 'none'}; "
                              f"{outcomes_text}")
                    continue
                transitions[outcome] = target
            if state.kind == "Sequence" and following is not None and connector not in transitions:
                if connector in child.outcomes:
                    transitions[connector] = following.label
                else:
                    self.fail(f"{state.json_path}.connector_outcome", f"'{child.label}' never ends with "
                              f"'{connector}', so the Sequence cannot go on to '{following.label}'; its outcomes: "
                              f"{', '.join(child.outcomes)}")
            child.transitions = transitions

        produced: list[str] = []
        unhandled: dict[str, list[str]] = defaultdict(list)
        for child in children:
            for outcome in child.outcomes:
                goes_to = child.transitions.get(outcome)
                if goes_to is None:
                    if outcome == PREEMPTED:
                        continue
                    goes_to = outcome
                    if outcome not in declared:
                        unhandled[outcome].append(child.label)
                if goes_to not in labels and goes_to not in produced:
                    produced.append(goes_to)
        ordered = [o for o in declared if o in produced] + [o for o in produced if o not in declared]
        state.outcomes = (*ordered, PREEMPTED)
        if unhandled:
            listing = "; ".join(f"{o} (from {', '.join(sources)})" for o, sources in unhandled.items())
            self.warn(state.json_path, f"outcomes with no transition end {what} with the same name: {listing}")
        if children and len(self.problems) == problems_before:  # a bad transition would make others unreachable
            self._reachability(state, labels)

    def _reachability(self, state: PlannedState, labels: dict[str, PlannedState]) -> None:
        initial = state.children[0].label
        seen, frontier = set(), [initial]
        while frontier:
            label = frontier.pop()
            if label in seen or label not in labels:
                continue
            seen.add(label)
            frontier.extend(t for t in labels[label].transitions.values() if t in labels)
        for label, child in labels.items():
            if label not in seen:
                self.fail(child.json_path, f"'{label}' is never reached from '{initial}' (the first state of "
                          f"{state.label}): no transition leads to it; add one or remove the state")

    def _concurrence(self, state: PlannedState) -> None:
        node = state.file_node
        labels = self._unique_labels(state, tuple(node.outcomes))
        for child in state.children:
            if not child.file_node.is_container and child.file_node.outcomes and child.json_path not in self._ignored:
                self._ignored.add(child.json_path)
                self.warn(f"{child.json_path}.outcomes", "ignored: the children of a Concurrence have no "
                          "transitions (its occurrencies_outcome_map decides)")
        outcome_map: dict[str, dict[str, str]] = {}
        for outcome, conditions in node.occurrencies_outcome_map.items():
            expanded: dict[str, str] = {}
            ok = True
            ordered = sorted(conditions.items(), key=lambda item: item[0] != ALL_CHILDREN)  # "all" first
            for key, wanted in ordered:
                where = f"{node.json_path}.occurrencies_outcome_map.{outcome}.{key}"
                if key == ALL_CHILDREN:
                    named = list(labels)
                elif key in labels:
                    named = [key]
                else:
                    self.fail(where, f"no child named '{key}'; children: {', '.join(labels) or 'none'} (or \"all\")")
                    ok = False
                    continue
                for label in named:
                    expanded[label] = wanted
            impossible, foreign = [], []
            for label, wanted in expanded.items():
                child = labels[label]
                vocabulary = set(child.outcomes) | (set(child.file_node.outcomes) if child.file_node.is_container
                                                    else set())
                if wanted not in vocabulary:  # the original's map simply never matched (its files have these)
                    foreign.append(f"'{label}' never ends with '{wanted}' (its outcomes: {', '.join(child.outcomes)})")
                elif wanted not in child.outcomes:
                    impossible.append(f"'{label}' cannot end with '{wanted}' (no state inside leads to it)")
            if not ok:
                continue
            if impossible or foreign:
                deciders = "its other entries" + (", its outcome_cb" if node.outcome_cb else "")
                self.warn(f"{node.json_path}.occurrencies_outcome_map.{outcome}",
                          f"never satisfied: {'; '.join(foreign + impossible)}; this entry is left out, as it never "
                          f"matched in the original either (the Concurrence ends by {deciders} or "
                          f"'{CONCURRENCE_DEFAULT_OUTCOME}')")
                continue
            outcome_map[outcome] = expanded
        possible = list(outcome_map)
        if node.outcome_cb is not None:
            callback = OUTCOME_CALLBACKS.get(node.outcome_cb)
            if callback is None:
                self.fail(f"{node.json_path}.outcome_cb", f"unknown outcome_cb {node.outcome_cb!r}; known: "
                          f"{', '.join(OUTCOME_CALLBACKS)}")
            else:
                possible += [o for o in callback.outcomes if o not in possible]
        if node.child_termination_cb is not None and node.child_termination_cb not in CHILD_TERMINATION_CALLBACKS:
            self.fail(f"{node.json_path}.child_termination_cb", f"unknown child_termination_cb "
                      f"{node.child_termination_cb!r}; known: {', '.join(CHILD_TERMINATION_CALLBACKS)}")
        if CONCURRENCE_DEFAULT_OUTCOME not in possible:
            possible.append(CONCURRENCE_DEFAULT_OUTCOME)
        declared = [o for o in node.outcomes if o in possible]
        state.outcomes = (*declared, *[o for o in possible if o not in declared and o != PREEMPTED], PREEMPTED)
        state.outcome_map = outcome_map
        state.default_outcome = CONCURRENCE_DEFAULT_OUTCOME


def _written_ids(ids: Ids) -> list[int]:
    """The ids a node writes out: [id] for one, the list for several; "all" (which the caller expands) none."""
    if isinstance(ids, int):
        return [ids]
    return [] if isinstance(ids, str) else list(ids)


def plan_mission(mission: Mission) -> Plan:
    """Expand the mission (module docstring); problems and warnings name file and JSON path."""
    planner = _Planner(mission)
    children = [c for node in mission.root for c in planner.expand(node, _Context(), "StateMachine")]
    root = PlannedState(ROOT_LABEL, None, "StateMachine", children=children)
    planner._machine(root, MISSION_OUTCOMES, "the mission")
    # a container repeated per id repeats its findings: say each once
    return Plan(root, list(dict.fromkeys(planner.problems)), list(dict.fromkeys(planner.warnings)))
