"""The network's mission (`magna learn fly`, step 2): a copy of a mission that sets ORCA-3D, flying a trained
network instead. Pure functions on the mission's JSON value, and an atomic writer."""
from __future__ import annotations

import copy
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

from magna_common.files import write_text_atomically

ORCA_NAMES = ("orca3", "orca3d")
NN_NAME = "neural_network"
# The NAI's default neighbour distance (magna_uav.nai.inputs.DEFAULT_NEIGHBOR_DIST, ORCA-3D's default);
# kept here so that building the parser imports no ROS or torch.
DEFAULT_NEIGHBOR_DIST = 6.0
VARIANT_SUFFIX = "_nn"
# Roles the mission's action states fly, for the warning about roles the model does not cover.
STATE_ROLES = {"follow_path": "path", "follow_agent_ad": "agent_ad", "follow_uav_ad": "agent_ad",
               "follow_agent_ap": "agent_ap", "follow_uav_ap": "agent_ap"}


class FlyError(ValueError):
    """Bad input for fly (a file, a mission, a dataset): the message names it and the fix; exit status 2."""



@dataclass(frozen=True)
class Change:
    """One algorithm_control state of the mission that the variant flies with the network."""

    where: str  # JSON path, e.g. State_Machine[5] or State_Machine[2].occurrencies[0]
    state: str  # the state's name
    was: str  # e.g. "orca3 set"
    neighbor_dist: float
    neighbor_dist_from: str  # "the model's spec", "the mission's ORCA neighborDist" or "the default"
    network_state: str = ""  # the state added after it that sets the network; "" when replaced in place

    def __str__(self) -> str:
        then = f"{NN_NAME} set, neighborDist {self.neighbor_dist:g} ({self.neighbor_dist_from})"
        if self.network_state:
            return (f"{self.where} {self.state!r}: {self.was} -> {self.was.split()[0]} configure (the teacher's "
                    f"parameters), then {self.network_state!r}: {then}")
        return f"{self.where} {self.state!r}: {self.was} -> {then} (the teacher keeps ORCA-3D's defaults)"


def _walk_states(nodes, prefix: str, container: str = "StateMachine"):
    """(JSON path, state, its sibling list, the kind of container holding them) of every state of a State_Machine
    list, children (occurrencies) after their parent."""
    for i, node in enumerate(nodes):
        where = f"{prefix}[{i}]"
        if not isinstance(node, dict):
            continue
        yield where, node, nodes, container
        children = node.get("occurrencies")
        if isinstance(children, list):
            yield from _walk_states(children, f"{where}.occurrencies", str(node.get("type", "")))


def _unique_name(siblings: list, wanted: str) -> str:
    taken = {node.get("name") for node in siblings if isinstance(node, dict)}
    name, k = wanted, 2
    while name in taken:
        name, k = f"{wanted}_{k}", k + 1
    return name


def parameters_with(names: list, values: list, updates: dict[str, float]) -> tuple[list, list]:
    """An algorithm_control state's `params` and `values` lists with `updates` set (replaced, or added at the
    end); the lists given are left as they were."""
    names, values = list(names), list(values)
    for name, value in updates.items():
        if name in names:
            values[names.index(name)] = value
        else:
            names.append(name)
            values.append(value)
    return names, values


def _with_params(parameters: dict, updates: dict[str, float]) -> dict:
    names, values = parameters_with(parameters.get("params") or [], parameters.get("values") or [], updates)
    return {**parameters, "params": names, "values": values}


def _network_after(node: dict, siblings: list, parameters: dict) -> str:
    """Turn the ORCA-3D set state `node` into a configure (so the teacher keeps the mission's ORCA-3D parameters)
    and add after it a state that sets the network and goes on where `node` went; the new state's name."""
    name = _unique_name(siblings, f"{node.get('name', 'algorithm_control')}{VARIANT_SUFFIX}")
    network = {key: copy.deepcopy(value) for key, value in node.items() if key not in ("name", "parameters")}
    network["name"] = name
    network["parameters"] = parameters
    outcomes = node.get("outcomes")
    if isinstance(outcomes, dict) and "completed" in outcomes:
        node["outcomes"] = {**outcomes, "completed": name}
    node["parameters"] = {**node["parameters"], "action": "configure"}
    siblings.insert(next(i for i, sibling in enumerate(siblings) if sibling is node) + 1, network)
    return name


def _control(node: dict) -> dict | None:
    """The parameters of an algorithm_control state, or None for any other state."""
    parameters = node.get("parameters")
    if node.get("state_type") != "algorithm_control" or not isinstance(parameters, dict):
        return None
    return parameters


def _given_neighbor_dist(parameters: dict) -> float | None:
    """neighborDist of one algorithm_control state, when it gives a usable one (> 0: the network needs it)."""
    names, values = parameters.get("params"), parameters.get("values")
    if not isinstance(names, list) or not isinstance(values, list) or "neighborDist" not in names:
        return None
    index = names.index("neighborDist")
    value = values[index] if index < len(values) else None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
        return None
    return float(value)


def nn_variant(mission, model_path: str, neighbor_dist: float | None = None,
               source: str | os.PathLike = "mission", fallback: bool = False,
               teacher: dict[str, float] | None = None) -> tuple[dict, list[Change]]:
    """(a copy of `mission` flying the network, what changed); FlyError naming `source` if nothing sets ORCA.

    Every algorithm_control state, at any depth, whose parameters name orca3/orca3d with action
    set is followed by neural_network set with the model and neighborDist: `neighbor_dist` (the
    spec's, when given), else that state's ORCA neighborDist, else the first neighborDist any ORCA
    state of the mission gives, else DEFAULT_NEIGHBOR_DIST. The ORCA state itself becomes a
    configure, so ORCA-3D, the teacher whose answer the NAI records beside the network's (DAgger),
    keeps the mission's parameters; its "completed" outcome leads to the new state, which goes on
    where it went. In a Concurrence, where states run side by side, the state is replaced in place
    instead (the teacher then has ORCA-3D's defaults). ORCA "configure" states stay: ORCA-3D still
    flies the roles no network is trained for (basic_move). `mission` is not modified.
    `fallback` adds the NAI's fallback parameter (1): the teacher takes over a colliding command.
    `teacher` sets ORCA-3D parameters of the teacher in the configure state (e.g. {"agent_radius": 0.7}: a
    teacher with a wider margin than the mission's ORCA-3D); a state in a Concurrence cannot carry them
    (FlyError).

    The model path goes in text_value (a string field of the AlgorithmControl service); the
    ground station sends `values` as float64 and so cannot carry a path there.
    """
    if not os.path.isabs(model_path):
        raise FlyError(f"model path {model_path!r} is relative: give the absolute path the UAV managers will load")
    if not isinstance(mission, dict) or not isinstance(mission.get("State_Machine"), list):
        raise FlyError(f"{source}: not a mission: expected an object with Agents_Config (or UAVs_Config) and a "
                       "State_Machine list of states")
    variant = copy.deepcopy(mission)
    states = list(_walk_states(variant["State_Machine"], "State_Machine"))
    controls = [(where, node, p, siblings, container) for where, node, siblings, container in states
                if (p := _control(node)) is not None]
    orca = [control for control in controls if control[2].get("name") in ORCA_NAMES]
    mission_dist = next((d for _, _, p, _, _ in orca if (d := _given_neighbor_dist(p)) is not None), None)
    changes = []
    for where, node, parameters, siblings, container in orca:
        if parameters.get("action") != "set":
            continue
        if neighbor_dist is not None:
            dist, origin = float(neighbor_dist), "the model's spec"
        elif (own := _given_neighbor_dist(parameters)) is not None:
            dist, origin = own, "the mission's ORCA neighborDist"
        elif mission_dist is not None:
            dist, origin = mission_dist, "the mission's ORCA neighborDist"
        else:
            dist, origin = DEFAULT_NEIGHBOR_DIST, "the default"
        network = {"name": NN_NAME, "action": "set", "params": ["neighborDist"], "values": [dist],
                   "text_value": model_path}
        if fallback:
            network["params"], network["values"] = ["neighborDist", "fallback"], [dist, 1]
        added = ""
        if container == "Concurrence":
            if teacher:
                raise FlyError(f"{source}: {where} {node.get('name')!r} sets ORCA-3D inside a Concurrence, where the "
                               "network's state replaces it and the teacher's parameters have no state to go in: "
                               "leave the teacher's parameters out, or set ORCA-3D before the Concurrence")
            node["parameters"] = network
        else:
            added = _network_after(node, siblings, network)
            if teacher:
                node["parameters"] = _with_params(node["parameters"], teacher)
        changes.append(Change(where, str(node.get("name", "")), f"{parameters['name']} set", dist, origin, added))
    if not changes:
        found = ", ".join(f"{p.get('name')} {p.get('action')} at {where}" for where, _, p, _, _ in controls)
        raise FlyError(f"{source}: no algorithm_control state sets orca3 or orca3d "
                       f"({'found: ' + found if found else 'it has no algorithm_control state'}); fly compares the "
                       "network with ORCA-3D, so give a mission that flies ORCA-3D")
    return variant, changes


def mission_roles(mission) -> list[str]:
    """The network roles (path, agent_ad, agent_ap) the mission's action states fly, in first-seen order."""
    roles: list[str] = []
    machine = mission.get("State_Machine") if isinstance(mission, dict) else None
    for _, node, _, _ in _walk_states(machine if isinstance(machine, list) else [], "State_Machine"):
        role = STATE_ROLES.get(node.get("state_type"))
        if role is not None and role not in roles:
            roles.append(role)
    return roles


def variant_path(out: Path, mission: str, submission: str) -> Path:
    return Path(out) / "missions" / mission / f"{submission}{VARIANT_SUFFIX}.json"


def write_variant(out: Path, mission: str, submission: str, variant: dict, overwrite: bool = False) -> Path:
    """Write the variant atomically; an existing different file is kept (FlyError) unless `overwrite`."""

    path = variant_path(out, mission, submission)
    text = json.dumps(variant, indent=4) + "\n"
    if path.exists():
        try:
            same = path.read_text() == text
        except (OSError, UnicodeDecodeError):
            same = False
        if same:
            return path
        if not overwrite:
            raise FlyError(f"{path} exists and differs from this network's mission; nothing was started. Pass "
                           "--overwrite to replace it, or choose another -o/--output or --name")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomically(path, text, overwrite=True)
    return path


