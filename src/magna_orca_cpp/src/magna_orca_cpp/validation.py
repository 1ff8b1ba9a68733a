"""Input checks with the same sentences as the C++ library (src/validation.cpp)."""
from __future__ import annotations

import math

from magna_orca_cpp.model import Agent, Params


class OrcaInputError(ValueError):
    """Bad ORCA-3D input; the message names the field and the fix."""


def _show(value: float) -> str:
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:g}"


def _check_positive(value: float, name: str, unit: str) -> None:
    if not math.isfinite(value) or value <= 0.0:
        raise OrcaInputError(f"{name} is {_show(value)}: give a positive number of {unit}")


def _check_not_negative(value: float, name: str, what: str) -> None:
    if not math.isfinite(value) or value < 0.0:
        raise OrcaInputError(f"{name} is {_show(value)}: {what}")


def check_params(params: Params, neighbor_limit: int | None = None, where: str = "params") -> None:
    """The C++ checkParams with a request's names ("params.time_horizon (timeHorizon)")."""
    if params.max_neighbors < 0 or (neighbor_limit is not None and params.max_neighbors > neighbor_limit):
        advice = (f"above the cap of {neighbor_limit} neighbours per agent (~max_neighbors); "
                  "lower it or raise ~max_neighbors" if params.max_neighbors >= 0 else "give a whole number >= 0")
        raise OrcaInputError(f"{where}.n_neighbors_aware (N_neighbors_aware) is {params.max_neighbors}: {advice}")
    _check_positive(params.time_step, f"{where}.time_step (timeStep)", "seconds")
    _check_positive(params.time_horizon, f"{where}.time_horizon (timeHorizon)", "seconds")
    _check_not_negative(params.neighbor_dist, f"{where}.neighbor_dist (neighborDist)",
                        "give a finite distance >= 0 (m)")
    _check_not_negative(params.agent_radius, f"{where}.agent_radius",
                        "give a finite radius >= 0 (m; 0 means every agent gives its own)")
    _check_not_negative(params.max_speed, f"{where}.max_speed (maxSpeed)",
                        "give a finite speed >= 0 (m/s; 0 means every agent gives its own)")


def check_agent(agent: Agent, params: Params, where: str) -> None:
    for name in ("position", "velocity", "preferred_velocity"):
        for axis, value in zip("xyz", getattr(agent, name), strict=True):
            if not math.isfinite(value):
                raise OrcaInputError(f"{where}.{name}.{axis} is {_show(value)}: give a finite number")
    _check_not_negative(agent.radius, f"{where}.radius",
                        "give a radius > 0 in metres, or 0 to take params.agent_radius")
    _check_not_negative(agent.max_speed, f"{where}.max_speed",
                        "give a speed > 0 in m/s, or 0 to take params.max_speed")
    if agent.radius == 0.0 and params.agent_radius == 0.0:
        raise OrcaInputError(f"{where}.radius is 0 and params.agent_radius is 0: give a positive radius in either")
    if agent.max_speed == 0.0 and params.max_speed == 0.0 and agent.cooperative:
        raise OrcaInputError(f"{where}.max_speed is 0 and params.max_speed is 0: give a positive speed limit in either")
