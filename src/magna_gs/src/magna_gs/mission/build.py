"""Mission -> magna_sm.StateMachine, with the leaves made by a factory the caller supplies.

    machine = build_machine(mission, factory)     # a StateMachine named MISSION, checked
    outcome = machine.execute()

The ground station supplies a factory that makes ROS states (SimpleActionStates to the
UAV managers, CBStates that spawn agents or wait for the operator); tests supply
scripted ones; `InertFactory` makes states that never run, for drawing. The structure
(expansion, naming, transitions, outcome maps, callbacks) is `plan.plan_mission`'s;
this module only turns the plan into magna_sm objects.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Protocol, cast

from magna_gs.mission.model import (
    ACTION_OUTCOMES,
    CALLBACK_OUTCOMES,
    ActionParameters,
    CallbackParameters,
    Mission,
    MissionError,
)
from magna_gs.mission.outcome_callbacks import CHILD_TERMINATION_CALLBACKS, OUTCOME_CALLBACKS
from magna_gs.mission.plan import ABSENT_UAV_OUTCOME, Plan, PlannedState, plan_mission
from magna_sm import Concurrence, Sequence, State, StateMachine, ValidationError


class StateFactory(Protocol):
    """Makes the leaves of a mission machine."""

    def action_state(self, uav_id: int, action: str, parameters: ActionParameters, json_path: str) -> State:
        """A state sending one goal of `action` (take_off, land, follow_path, basic_move, follow_agent_ad,
        follow_agent_ap, save_csv, set_mission) to UAV `uav_id`; its outcomes are exactly model.ACTION_OUTCOMES."""

    def callback_state(self, state_type: str, ids: list[int], parameters: CallbackParameters,
                       json_path: str) -> State:
        """A state doing `state_type` (world_config, wait, spawn_agents, algorithm_control, save_csv) at the
        ground station for agents `ids`; its outcomes are exactly model.CALLBACK_OUTCOMES."""


class InertState(State):
    """A leaf that only has outcomes: for drawing and structure checks; running it is an error."""

    def __init__(self, outcomes: Iterable[str], description: str):
        super().__init__(outcomes)
        self.description = description

    def execute(self, ud: Any) -> str:
        raise RuntimeError(f"{self.description}: an inert state (built for drawing) cannot run")


_INERT_TYPES: dict[str, type[InertState]] = {}


def _inert(state_type: str, outcomes: Iterable[str], description: str) -> InertState:
    """An InertState whose class is named after its state type, so drawings read `1_take_off / take_off`."""
    cls = _INERT_TYPES.setdefault(state_type, type(state_type, (InertState,), {"__module__": __name__}))
    return cls(outcomes, description)


class InertFactory:
    """A StateFactory whose states never run (their class names are the state types, for drawings)."""

    def action_state(self, uav_id: int, action: str, parameters: ActionParameters, json_path: str) -> State:
        return _inert(action, ACTION_OUTCOMES, f"{json_path}: {action} for UAV {uav_id}")

    def callback_state(self, state_type: str, ids: list[int], parameters: CallbackParameters,
                       json_path: str) -> State:
        return _inert(state_type, CALLBACK_OUTCOMES, f"{json_path}: {state_type}")


def build_machine(mission: Mission, factory: StateFactory, plan: Plan | None = None,
                  name: str = "MISSION") -> StateMachine:
    """The mission's machine, validated by magna_sm; MissionError when the mission has problems."""
    plan = plan_mission(mission) if plan is None else plan
    if plan.problems:
        raise MissionError(plan.problems)
    machine = StateMachine(plan.root.outcomes, name=name)
    _fill_machine(machine, plan.root, mission, factory)
    try:
        machine.check()
    except ValidationError as error:  # the plan and magna_sm disagree: a bug here, not in the mission
        raise AssertionError(f"{mission.source}: the planned machine does not validate:\n{error}") from None
    return machine


class AbsentUavState(State):
    """An action state of a UAV the mission does not configure: nobody would answer its goal, so it ends at once."""

    def __init__(self, description: str):
        super().__init__(ACTION_OUTCOMES)
        self.description = description

    def execute(self, ud: Any) -> str:
        return ABSENT_UAV_OUTCOME


def _make(state: PlannedState, mission: Mission, factory: StateFactory) -> State:
    if state.kind == "SimpleActionState" and state.absent:
        return AbsentUavState(f"{mission.where(state.json_path)}: {state.state_type} for UAV {state.uav}, which "
                              f"{mission.agents_key} does not configure")
    if state.kind == "SimpleActionState":
        assert state.uav is not None and state.state_type is not None, "the plan gives each its UAV and type"
        parameters = cast(ActionParameters, state.parameters)  # read for its state type
        made = factory.action_state(state.uav, state.state_type, parameters, state.json_path)
        return _checked(made, ACTION_OUTCOMES, "action_state", state, mission)
    if state.kind == "CBState":
        assert state.state_type is not None, "the plan gives each leaf its type"
        made = factory.callback_state(state.state_type, list(state.ids), cast(CallbackParameters, state.parameters),
                                      state.json_path)
        return _checked(made, CALLBACK_OUTCOMES, "callback_state", state, mission)
    if state.kind == "Concurrence":
        node = state.file_node
        assert state.default_outcome is not None, "the plan gives each Concurrence its default outcome"
        outcome_cb = OUTCOME_CALLBACKS[node.outcome_cb].function if node.outcome_cb else None
        termination_cb = (CHILD_TERMINATION_CALLBACKS[node.child_termination_cb].function
                          if node.child_termination_cb else None)
        concurrence = Concurrence(state.outcomes, default_outcome=state.default_outcome, outcome_map=state.outcome_map,
                                  outcome_cb=outcome_cb, child_termination_cb=termination_cb)
        for child in state.children:
            concurrence.add_state(child.label, _make(child, mission, factory))
        return concurrence
    if state.kind == "Sequence":
        assert state.connector_outcome is not None, "a Sequence without one is a problem of the mission's"
        sequence = Sequence(state.outcomes, connector_outcome=state.connector_outcome)
        _fill_machine(sequence, state, mission, factory)
        return sequence
    machine = StateMachine(state.outcomes)
    _fill_machine(machine, state, mission, factory)
    return machine


def _fill_machine(machine: StateMachine, state: PlannedState, mission: Mission, factory: StateFactory) -> None:
    for child in state.children:
        machine.add_state(child.label, _make(child, mission, factory), dict(child.transitions))


def _checked(made: Any, outcomes: tuple[str, ...], method: str, state: PlannedState, mission: Mission) -> State:
    if not isinstance(made, State):
        raise TypeError(f"{mission.where(state.json_path)}: factory.{method} returned {made!r}, not a magna_sm State")
    if set(made.get_registered_outcomes()) != set(outcomes):
        raise TypeError(f"{mission.where(state.json_path)}: factory.{method} returned a state with outcomes "
                        f"{list(made.get_registered_outcomes())}; it must have exactly {list(outcomes)}")
    return made
