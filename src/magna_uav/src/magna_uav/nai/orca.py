"""ORCA-3D in the NAI: own UAV, nearest UAVs and obstacles as magna_orca_cpp agents, one solve.

- own UAV: position and velocity; preferred velocity = the simple-guidance velocity;
  radius = the larger of the safety radius and ORCA's agent_radius; max speed = the UAV's;
  cooperative.
- the N nearest other UAVs: position and velocity; preferred velocity = their current
  velocity; radius = the larger of their safety radius and agent_radius; cooperative
  (each takes half the avoidance); max speed = the UAV's (a one-shot solve does not use it).

agent_radius is the missions' margin: ORCA brings spheres exactly into contact, and a
real UAV reaches a new velocity only after its autopilot's lag, so ORCA's spheres must be
larger than the evaluator's safety spheres (the original missions use 0.5 m with 0.3 m
safety radii).
- the M nearest obstacles: bounding-sphere centre and radius, velocity 0, not
  cooperative (we take all the avoidance).

N is `N_neighbors_aware` and M is `N_obstacles_aware` (a NAI parameter, default: N):
UAVs and obstacles are counted apart, so an obstacle never hides a UAV. Both are the
nearest by their gap below `neighborDist` (to safety spheres for UAVs, to the real
shape for obstacles; `inputs.select_neighbors`,
the same selection that feeds the neural networks). The solver is given exactly these
(its own neighbour cap is set to their number).

The solver is any object with `new_velocity(agent, others, params) -> Solution`; the
default is magna_orca_cpp's `OrcaSolver` (the /magna/orca3d/compute_velocity service when
it is up, the numpy reference otherwise), or the reference alone when rospy or the
messages cannot be imported. The first time a solve runs on the reference because the
service is absent (the solver's `using_service` is False; the reference chosen on purpose has
none), one warning goes to the
`magna_uav.nai` logger.

Managers sharing a process may share an `OrcaBatcher` (orca_batch.py): the navigator then
hands its problem, built exactly as above, to the batcher with the step's key, and gets the
same answer from one call made for all of them. It joins the batcher at its first ORCA-3D step
and leaves it on `release()` (the control loop calls it when a role ends), so a UAV that is not
avoiding with ORCA-3D holds nobody up. A step whose key is None (off the shared tick: a role's
first step) is solved alone, at once.
"""
from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np

from magna_common import ros_names as names
from magna_orca_cpp import reference
from magna_orca_cpp.model import Agent, Params, Problem, Solution
from magna_uav.nai.inputs import Neighbors, select_neighbors
from magna_uav.world_view import WorldView

logger = logging.getLogger("magna_uav.nai")


class ReferenceSolver:
    """The numpy reference behind the solver interface (never uses the service).

    It has no `using_service`: a caller that chose it (the gym, with no ROS) is not told that a service is
    missing, nor to start one."""

    def new_velocity(self, agent: Agent, others: Sequence[Agent], params: Params) -> Solution:
        return reference.new_velocity(agent, others, params)

    def new_velocity_many(self, problems: Sequence[Problem]) -> list[Solution]:
        return [reference.new_velocity(p.agent, p.neighbors, p.params) for p in problems]


def default_solver():
    """magna_orca_cpp's OrcaSolver (service, else reference); the reference alone if ROS is not importable."""
    try:
        from magna_orca_cpp.service_client import OrcaSolver

        return OrcaSolver()
    except Exception as err:  # no rospy / magna_msgs, or the probe failed: fly on the reference
        logger.debug("OrcaSolver unavailable (%s): ORCA-3D runs on the numpy reference", err)
        return ReferenceSolver()


def orca_agents(view: WorldView, preferred: np.ndarray, neighbors: Neighbors, radius: float,
                max_speed: float, agent_radius: float = 0.0) -> tuple[Agent, list[Agent]]:
    """The own agent and its neighbours as in the module table (UAV radii at least `agent_radius`)."""
    own = view.own
    me = Agent(position=own.position, velocity=own.velocity, preferred_velocity=preferred,
               radius=max(radius, agent_radius), max_speed=max_speed)
    others = [Agent(position=a.position, velocity=a.velocity, preferred_velocity=a.velocity,
                    radius=max(a.safety_radius, agent_radius), max_speed=max_speed) for a in neighbors.agents]
    others += [Agent(position=o.position, radius=o.radius, max_speed=max_speed, cooperative=False)
               for o in neighbors.obstacles]
    return me, others


def would_collide(view: WorldView, velocity: np.ndarray, neighbors: Neighbors, radius: float, agent_radius: float,
                  horizon: float) -> bool:
    """Would the own UAV, flying `velocity` while the others keep theirs, touch one of `neighbors` within `horizon`
    seconds? The spheres are ORCA-3D's (`orca_agents`), so this is the command lying in one of ORCA-3D's velocity
    obstacles. Spheres that overlap already count only while the command brings them closer."""
    me, others = orca_agents(view, np.zeros(3), neighbors, radius, 0.0, agent_radius)
    velocity = np.asarray(velocity, dtype=float).reshape(3)
    for other in others:
        offset = np.asarray(other.position, dtype=float) - me.position
        closing = velocity - np.asarray(other.velocity, dtype=float)
        reach = me.radius + other.radius
        if float(offset @ offset) < reach * reach:
            if float(closing @ offset) > 0.0:
                return True
            continue
        speed2 = float(closing @ closing)
        t = 0.0 if speed2 == 0.0 else min(max(float(offset @ closing) / speed2, 0.0), horizon)
        miss = offset - closing * t
        if float(miss @ miss) < reach * reach:
            return True
    return False


@dataclass
class OrcaResult:
    velocity: np.ndarray
    feasible: bool
    neighbors: Neighbors


class OrcaNavigator:
    """One UAV's ORCA-3D step: select neighbours, build agents, call the solver.

    With a `batcher` (an OrcaBatcher shared with the other managers of the process), the solve
    goes through it under the key `step_key()` gives, the same for every participant at one
    control tick (None: this step is on no shared tick, solve it alone); the answer is the same.
    The UAV joins the batcher at its first ORCA-3D step (unless it had joined already) and
    leaves on `release()`. Without a batcher: the solver.
    """

    def __init__(self, solver=None, batcher=None, step_key: Callable[[], Hashable | None] | None = None):
        if batcher is not None and solver is not None:
            raise ValueError("OrcaNavigator takes a solver or a batcher, not both: the batcher has its own solver")
        if batcher is not None and step_key is None:
            raise ValueError("OrcaNavigator with a batcher needs step_key: a function giving the control step's "
                             "key, equal for every UAV at one tick (e.g. the tick index)")
        self._solver = solver
        self._batcher = batcher
        self._step_key = step_key
        self._joined: int | None = None  # the UAV id this navigator joined the batcher with
        self._warned = False

    @property
    def solver(self):
        if self._batcher is not None:
            return self._batcher.solver
        if self._solver is None:
            self._solver = default_solver()
        return self._solver

    def velocity(self, view: WorldView, preferred: np.ndarray, params: Params, n_obstacles: int, radius: float,
                 max_speed: float) -> OrcaResult:
        neighbors = select_neighbors(view, params.max_neighbors, n_obstacles, params.neighbor_dist)
        me, others = orca_agents(view, preferred, neighbors, radius, max_speed, params.agent_radius)
        solver = self.solver
        params = dataclasses.replace(params, max_neighbors=len(others))
        if self._batcher is not None and self._step_key is not None:
            solution = self._batched(view.own_id, self._step_key(), Problem(me, others, params))
        else:
            solution = solver.new_velocity(me, others, params)
        if not self._warned and getattr(solver, "using_service", True) is False:
            self._warned = True
            logger.warning("ORCA-3D service %s is not available: UAV %d avoids with the numpy reference "
                           "(same answers, slower); start magna_orca_cpp orca3d_server for the fast path",
                           names.ORCA_COMPUTE_VELOCITY, view.own_id)
        return OrcaResult(np.asarray(solution.velocity, dtype=float).reshape(3), bool(solution.feasible), neighbors)

    def _batched(self, uav_id: int, step_key: Hashable | None, problem: Problem) -> Solution:
        assert self._batcher is not None
        if self._joined is None and uav_id not in self._batcher.participants:
            # joined from a role's first ORCA-3D step, so its next one (on the shared tick) is waited for
            self._batcher.join(uav_id)
            self._joined = uav_id
        if step_key is None:
            return self._batcher.solve_alone(problem)
        return self._batcher.solve(uav_id, step_key, problem)

    def release(self) -> None:
        """Leave the batcher (if this navigator joined it): the UAV stops stepping with ORCA-3D for now, and
        nobody waits for it; its next batched solve joins again. Nothing to do without a batcher."""
        if self._batcher is not None and self._joined is not None:
            self._batcher.leave(self._joined)
            self._joined = None
