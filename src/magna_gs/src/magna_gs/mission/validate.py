"""Structural validation of a parsed mission: everything that can be known without a world.

`validate_mission(mission)` returns every problem at once (each `file: JSON.path:
what is wrong; how to fix it`) and the warnings, with the plan it checked:

- the expansion and outcome rules of `plan` (unknown states in transitions with the
  {id}_{name} naming, duplicate labels, unreachable states, outcome maps naming
  missing children or impossible outcomes, unknown outcome_cb / child_termination_cb,
  ids that are not agents of Agents_Config, waypoints out of range, ...);
- follow_agent_ad|ap targets: an agent of the mission, not the follower itself;
- spawn_agents: one initial pose per agent it spawns;
- algorithm_control: the algorithm, action and parameters the UAV managers' navigation
  interface (magna_uav.nai) accepts;
- world_config: a delete names a world id that the mission spawns or adds (warning).
"""
from __future__ import annotations

from dataclasses import dataclass

from magna_gs.mission.model import (
    AlgorithmControlParams,
    FollowAgentADParams,
    FollowAgentAPParams,
    Mission,
    SpawnAgentsParams,
    WorldConfigParams,
)
from magna_gs.mission.plan import Plan, PlannedState, plan_mission


@dataclass
class ValidationReport:
    problems: list[str]
    warnings: list[str]
    plan: Plan

    @property
    def ok(self) -> bool:
        return not self.problems


def validate_mission(mission: Mission) -> ValidationReport:
    plan = plan_mission(mission)
    problems, warnings = list(plan.problems), list(plan.warnings)
    leaves = list(plan.root.leaves())
    for state in leaves:
        params = state.parameters
        if isinstance(params, FollowAgentADParams | FollowAgentAPParams):
            problems += _follow_target(mission, state, params.target_ID)
        elif isinstance(params, SpawnAgentsParams):
            found, warned = _spawn(mission, state, params)
            problems += found
            warnings += warned
        elif isinstance(params, AlgorithmControlParams):
            problems += _algorithm_control(mission, state, params)
    warnings += _world_ids(mission, leaves)
    if any(s.kind == "SimpleActionState" for s in leaves) and not any(s.state_type == "spawn_agents" for s in leaves):
        warnings.append(f"{mission.where('State_Machine')}: no spawn_agents state, yet action states fly agents: "
                        "the agents must be spawned by other means")
    return ValidationReport(list(dict.fromkeys(problems)), list(dict.fromkeys(warnings)), plan)


def _follow_target(mission: Mission, state: PlannedState, target: int) -> list[str]:
    where = mission.where(f"{state.json_path}.parameters.target_ID")
    if target not in mission.agent_ids:
        return [f"{where}: no agent {target} in {mission.agents_key} (IDs "
                f"{', '.join(map(str, mission.agent_ids))}); follow one of them"]
    if target == state.uav:
        return [f"{where}: '{state.label}' is UAV {target} itself; follow another agent"]
    return []


def _spawn(mission: Mission, state: PlannedState, params: SpawnAgentsParams) -> tuple[list[str], list[str]]:
    where = mission.where(f"{state.json_path}.parameters.initial_poses")
    given, needed = len(params.initial_poses), len(state.ids)
    if given < needed:
        return [f"{where}: {given} pose(s) for {needed} agents ({', '.join(map(str, state.ids))}); give one "
                "[volume, geometry, kind, arg] per agent, in Agents_Config order"], []
    if given > needed:
        return [], [f"{where}: {given} poses for {needed} agent(s); the last {given - needed} are not used"]
    return [], []


def _algorithm_control(mission: Mission, state: PlannedState, params: AlgorithmControlParams) -> list[str]:
    from magna_uav.nai.interface import ACTIONS, ALGORITHMS, ALIASES, PARAMETERS

    where = mission.where(f"{state.json_path}.parameters")
    name = ALIASES.get(params.name, params.name)
    if name not in ALGORITHMS:
        aliases = ", ".join(f"{a} for {n}" for a, n in ALIASES.items())
        return [f"{where}.name: unknown algorithm {params.name!r}; use one of {', '.join(ALGORITHMS)} ({aliases})"]
    problems = []
    if params.action not in ACTIONS:
        problems.append(f"{where}.action: unknown action {params.action!r}; use set (select and configure) or "
                        "configure (only change parameters)")
    known = PARAMETERS[name]
    for index, (param, value) in enumerate(zip(params.params, params.values, strict=True)):
        if param not in known:
            problems.append(f"{where}.params[{index}]: {name} has no parameter {param!r}; it has "
                            f"{', '.join(known)}")
            continue
        check, what = known[param]
        try:
            check(value)
        except (TypeError, ValueError):
            problems.append(f"{where}.values[{index}]: {param} = {value!r}; give {what}")
    return problems


def _world_ids(mission: Mission, leaves: list[PlannedState]) -> list[str]:
    configs = [(s, s.parameters) for s in leaves if isinstance(s.parameters, WorldConfigParams)]
    made = {p.id for _, p in configs if p.action in ("spawn", "add") and p.id is not None}
    return [f"{mission.where(f'{s.json_path}.parameters.id')}: no world_config spawn or add in this mission uses id "
            f"{p.id!r} ({', '.join(sorted(made)) or 'none do'}); the world node must hold it already"
            for s, p in configs if p.action == "delete" and p.id not in made]
