"""ORCA-3D solved again from an input vector alone: relabelling recorded samples with the teacher.

The input vector holds everything ORCA-3D decided on, in the thesis's scenarios: the own velocity, the
goal, the neighbours' positions and velocities and the obstacles' centres (mlr/README.md, "The input
vector, input by input"). With the mission's ORCA-3D parameters and the obstacles' one radius, the
numpy reference reproduces every recorded label (mlr.thesis_gap measures it). So the teacher's own
samples can be relabelled with other ORCA-3D parameters, for example a wider `agent_radius`, without
flying again (`relabelled`). That needs every obstacle to be a sphere of one size; otherwise the
vector does not say an obstacle's size, and `relabelled` refuses.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math

import numpy as np

from mlr.config import RunConfig
from mlr.nn_mission import parameters_with
from mlr.pickler import PicklerError, Samples, Simulation


@dataclasses.dataclass(frozen=True)
class TeacherSetup:
    """What ORCA-3D was given in the scenario's missions, besides the input vector."""

    orca_params: tuple[list[str], list]  # the mission's algorithm_control orca set: names, values
    obstacle_radius: float | None  # the one bounding radius of every obstacle; None: several, or none seen
    safety_radius: float
    max_speed: float


def teacher_setup(sim: Simulation, run: RunConfig) -> TeacherSetup:
    """The ORCA-3D parameters from the simulation's mission, the obstacles' radius from its recorded gaps."""
    from magna_common.airframes import load_airframe
    from magna_common.storage_tree import MISSION_FILE
    from magna_uav.recorder import read_csv

    mission = json.loads((sim.directory / MISSION_FILE).read_text())
    orca = next(s["parameters"] for s in _states(mission.get("State_Machine", []))
                if s.get("state_type") == "algorithm_control"
                and s.get("parameters", {}).get("name") in ("orca3", "orca3d"))
    model = next(iter(sim.uav_models.values()))
    airframe = load_airframe(model)
    radii = []
    for csv_path in sorted(sim.directory.glob("uav_*.csv")):
        for row in read_csv(csv_path)[1]:
            for k in range(5):
                gap = row.get(f"obs{k}.gap", math.nan)
                if math.isfinite(gap):
                    centre = np.array([row[f"obs{k}.pos.{a}"] for a in "xyz"])
                    own = np.array([row[f"pos.{a}"] for a in "xyz"])
                    radii.append(float(np.linalg.norm(centre - own)) - gap - airframe.safety_radius)
    # a sphere's gap is its centre's distance less both radii: one radius throughout means spheres of one size
    radius = float(np.median(radii)) if radii and np.ptp(radii) < 1e-6 else None
    return TeacherSetup((list(orca.get("params", [])), list(orca.get("values", []))), radius,
                        float(airframe.safety_radius), float(airframe.max_speed))


def _states(nodes):
    for node in nodes:
        if isinstance(node, dict):
            yield node
            yield from _states(node.get("occurrencies", []) or [])


def teacher_nai(setup: TeacherSetup):
    """The NAI flying ORCA-3D as the missions set it, on the numpy reference (no ROS here)."""
    from magna_uav.nai.interface import NavigationInterface
    from magna_uav.nai.orca import ReferenceSolver

    # the reference is chosen on purpose here: its one warning about a missing service would mislead
    logging.getLogger("magna_uav.nai").setLevel(logging.ERROR)
    nav = NavigationInterface(setup.max_speed, setup.safety_radius, solver=ReferenceSolver())
    nav.control("orca3d", "set", *setup.orca_params)
    return nav


@functools.lru_cache(maxsize=16)
def _layout(role: str, n_neighbors: int, n_obstacles: int, neighbor_dist: float) -> tuple[dict[str, list[int]],
                                                                                       np.ndarray]:
    """Where each xyz block sits in the input vector, and the padding position: worked out once per layout."""
    from magna_uav.nai.inputs import input_names, pad_position

    names = input_names(role, n_neighbors, n_obstacles)
    blocks = {name.rsplit(".", 1)[0] for name in names if name.endswith(".x")}
    columns = {block: [names.index(f"{block}.{a}") for a in "xyz"] for block in blocks}
    return columns, pad_position(neighbor_dist)


def orca_from_inputs(x: np.ndarray, run: RunConfig, setup: TeacherSetup, nav=None) -> tuple[np.ndarray, np.ndarray]:
    """(ORCA-3D's answer, the preferred velocity) from one path-role input vector (module docstring, 1); `nav`:
    a `teacher_nai(setup)` to reuse."""
    from magna_uav.nai.goal import Goal
    from magna_uav.nai.simple import simple_velocity
    from magna_uav.world_view import AgentState, Obstacle, WorldView

    columns, pad = _layout(run.role, run.n_neighbors, run.n_obstacles, run.neighbor_dist)
    if len(x) != sum(len(c) for c in columns.values()):
        raise ValueError(f"an input vector of {len(x)} values; the {run.role} role with {run.n_neighbors} "
                         f"neighbour(s) and {run.n_obstacles} obstacle(s) has "
                         f"{sum(len(c) for c in columns.values())}")

    def block(name: str) -> np.ndarray:
        return np.asarray(x[columns[name]], dtype=float)

    view = WorldView(1)
    own = AgentState(1, np.zeros(3), velocity=block("own_vel"), safety_radius=setup.safety_radius)
    view.update_agent(own)
    for k in range(run.n_neighbors):
        position, velocity = block(f"others_pos_rel[{k}]"), block(f"others_vel[{k}]")
        if not (np.array_equal(position, pad) and not velocity.any()):
            view.update_agent(AgentState(2 + k, position, velocity=velocity, safety_radius=setup.safety_radius))
    obstacles = []
    for k in range(run.n_obstacles):
        position = block(f"obstacles_pos_rel[{k}]")
        if not np.array_equal(position, pad) and setup.obstacle_radius is not None:
            obstacles.append(Obstacle(f"o{k}", position, setup.obstacle_radius))
    view.set_obstacles(obstacles)
    goal = Goal(block("goal_pose_rel"))
    nav = nav if nav is not None else teacher_nai(setup)
    preferred, _ = simple_velocity(own, goal, setup.max_speed)
    return nav.velocity(view, goal).velocity, preferred


def with_param(setup: TeacherSetup, name: str, value: float) -> TeacherSetup:
    """The same teacher with one ORCA-3D parameter (algorithm_control name) set to `value`."""
    return dataclasses.replace(setup, orca_params=parameters_with(*setup.orca_params, {name: value}))


def relabelled(samples: Samples, run: RunConfig, setup: TeacherSetup) -> Samples:
    """`samples` (path role) with each label replaced by `setup`'s ORCA-3D answer to its input vector."""
    if run.role != "path":
        raise PicklerError(f"relabelling from the input vector is for the path role; the samples are of {run.role}")
    if run.n_obstacles and setup.obstacle_radius is None and _any_obstacle(samples.x, run):
        raise PicklerError("the teacher's samples cannot be relabelled from their input vectors: the obstacles "
                           "are not spheres of one size, and the vector does not say an obstacle's size; record "
                           "the teacher's flights again with the new parameters instead")
    nav = teacher_nai(setup)
    labels = np.array([orca_from_inputs(x, run, setup, nav)[0] for x in samples.x]).reshape(len(samples), 3)
    return dataclasses.replace(samples, y=labels)


def _any_obstacle(x: np.ndarray, run: RunConfig) -> bool:
    columns, pad = _layout(run.role, run.n_neighbors, run.n_obstacles, run.neighbor_dist)
    return any(np.any(np.any(x[:, columns[f"obstacles_pos_rel[{k}]"]] != pad, axis=1))
               for k in range(run.n_obstacles))
