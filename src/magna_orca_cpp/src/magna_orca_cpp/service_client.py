"""ORCA-3D through the orca3d_server services, with the numpy reference as the fallback.

UAV managers call `OrcaSolver.new_velocity(...)`: the C++ service when it is up, the
reference (same semantics, slower) when it is not. Managers sharing a process batch their
problems through `OrcaSolver.new_velocity_many(...)`: one call to the many service, or the
reference problem by problem; each answer is the one `new_velocity` gives for that problem.
Needs rospy and magna_msgs.
"""
from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np
import rospy
from geometry_msgs.msg import Point, Vector3
from magna_msgs.msg import OrcaAgent, OrcaParams, OrcaProblem
from magna_msgs.srv import (
    OrcaComputeVelocities,
    OrcaComputeVelocitiesRequest,
    OrcaComputeVelocity,
    OrcaComputeVelocityMany,
    OrcaComputeVelocityManyRequest,
    OrcaComputeVelocityRequest,
)

from magna_common import ros_names as names
from magna_orca_cpp import reference
from magna_orca_cpp.model import Agent, Params, Problem, Solution, agent_rows
from magna_orca_cpp.validation import OrcaInputError


def agent_to_msg(agent: Agent, agent_id: int) -> OrcaAgent:
    # Positional, in the message's field order, from tolist(): about 3x faster than keywords and
    # map(float, ...), which matters for a many-call of hundreds of agents; the values are the same.
    return OrcaAgent(agent_id, Point(*agent.position.tolist()), Vector3(*agent.velocity.tolist()),
                     Vector3(*agent.preferred_velocity.tolist()), agent.radius, agent.max_speed,
                     not agent.cooperative)


def params_to_msg(params: Params) -> OrcaParams:
    return OrcaParams(n_neighbors_aware=params.max_neighbors, time_step=params.time_step,
                      neighbor_dist=params.neighbor_dist, time_horizon=params.time_horizon,
                      agent_radius=params.agent_radius, max_speed=params.max_speed)


def problem_to_msg(problem: Problem) -> OrcaProblem:
    """Ids as `new_velocity` numbers them (the agent 0, its neighbours from 1), so both ask the same."""
    return OrcaProblem(agent=agent_to_msg(problem.agent, 0),
                       neighbors=[agent_to_msg(o, j + 1) for j, o in enumerate(problem.neighbors)],
                       params=params_to_msg(problem.params))


# OrcaAgent on the wire (little-endian, unpadded): id, position, velocity, preferred velocity,
# radius, max_speed, non_cooperative. OrcaParams: n_neighbors_aware and five float64.
_WIRE_AGENT = np.dtype([("id", "<u4"), ("state", "<f8", (9,)), ("radius", "<f8"), ("max_speed", "<f8"),
                        ("non_cooperative", "u1")])
_WIRE_COUNT = struct.Struct("<I")
_WIRE_PARAMS = struct.Struct("<I5d")


def many_request_bytes(problems: Sequence[Problem]) -> bytes:
    """The serialized OrcaComputeVelocityMany request of `problems`, the same bytes as genpy writes
    for `problem_to_msg` of each (a test checks), packed from numpy in one go: building hundreds
    of genpy agent messages costs several times more than the service call itself."""
    sizes = [1 + len(problem.neighbors) for problem in problems]
    rows = agent_rows([agent for problem in problems for agent in (problem.agent, *problem.neighbors)])
    wire = np.zeros(len(rows), dtype=_WIRE_AGENT)
    wire["id"] = np.concatenate([np.arange(size) for size in sizes]) if sizes else []  # agent 0, neighbours 1..
    wire["state"] = rows[:, :9]
    wire["radius"], wire["max_speed"] = rows[:, 9], rows[:, 10]
    wire["non_cooperative"] = rows[:, 11] == 0.0
    packed = wire.tobytes()
    size = _WIRE_AGENT.itemsize
    parts = [_WIRE_COUNT.pack(len(problems))]
    start = 0
    for problem, count in zip(problems, sizes, strict=True):
        q = problem.params
        parts += [packed[start * size:(start + 1) * size], _WIRE_COUNT.pack(count - 1),
                  packed[(start + 1) * size:(start + count) * size],
                  _WIRE_PARAMS.pack(q.max_neighbors, q.time_step, q.neighbor_dist, q.time_horizon, q.agent_radius,
                                    q.max_speed)]
        start += count
    return b"".join(parts)


class _PackedManyRequest(OrcaComputeVelocityManyRequest):
    """A many request that writes bytes packed beforehand (rospy only asks it to serialize itself)."""

    __slots__ = ["_payload"]

    def __init__(self, payload: bytes):
        super().__init__()
        self._payload = payload

    def serialize(self, buff) -> None:
        buff.write(self._payload)


def _vector(msg: Vector3) -> np.ndarray:
    return np.array([msg.x, msg.y, msg.z])


class OrcaServiceClient:
    """The three services over persistent connections (reconnected when they drop)."""

    def __init__(self, one_service: str = names.ORCA_COMPUTE_VELOCITY,
                 batch_service: str = names.ORCA_COMPUTE_VELOCITIES,
                 many_service: str = names.ORCA_COMPUTE_VELOCITY_MANY):
        self._names = {OrcaComputeVelocity: one_service, OrcaComputeVelocities: batch_service,
                       OrcaComputeVelocityMany: many_service}
        self._proxies: dict = {}

    def wait(self, timeout: float) -> bool:
        """Whether every service answers within `timeout` seconds."""
        try:
            for name in self._names.values():
                rospy.wait_for_service(name, timeout)
        except rospy.ROSException:
            return False
        return True

    def _call(self, kind, request):
        proxy = self._proxies.get(kind)
        if proxy is None:
            proxy = self._proxies[kind] = rospy.ServiceProxy(self._names[kind], kind, persistent=True)
        try:
            response = proxy(request)
        except rospy.ServiceException:
            self._proxies.pop(kind, None)
            proxy.close()
            raise
        if not response.success:
            raise OrcaInputError(response.message)
        return response

    def new_velocity(self, agent: Agent, others: Sequence[Agent], params: Params) -> Solution:
        request = OrcaComputeVelocityRequest(
            agent=agent_to_msg(agent, 0), neighbors=[agent_to_msg(o, j + 1) for j, o in enumerate(others)],
            params=params_to_msg(params))
        response = self._call(OrcaComputeVelocity, request)
        return Solution(_vector(response.velocity), response.feasible)

    def new_velocity_many(self, problems: Sequence[Problem]) -> list[Solution]:
        """Each problem solved as `new_velocity` would solve it alone, in one call; same order.

        One refused problem refuses the call (OrcaInputError naming problems[i] and the field)."""
        if not problems:
            return []
        response = self._call(OrcaComputeVelocityMany, _PackedManyRequest(many_request_bytes(problems)))
        return [Solution(_vector(v), f) for v, f in zip(response.velocities, response.feasible, strict=True)]

    def new_velocities(self, agents: Sequence[Agent], params: Params) -> list[Solution]:
        request = OrcaComputeVelocitiesRequest(
            agents=[agent_to_msg(a, j) for j, a in enumerate(agents)], params=params_to_msg(params))
        response = self._call(OrcaComputeVelocities, request)
        return [Solution(_vector(v), f) for v, f in zip(response.velocities, response.feasible, strict=True)]

    def close(self) -> None:
        for proxy in self._proxies.values():
            proxy.close()
        self._proxies.clear()


class OrcaSolver:
    """The service when it is up, the numpy reference otherwise (same answers, within 1e-4)."""

    def __init__(self, client: OrcaServiceClient | None = None, wait: float = 0.0):
        self.client = client or OrcaServiceClient()
        self.using_service = self.client.wait(wait) if wait > 0 else self._probe()

    def _probe(self) -> bool:
        try:
            return self.client.wait(0.05)
        except rospy.ROSInitException:
            return False

    def new_velocity(self, agent: Agent, others: Sequence[Agent], params: Params) -> Solution:
        if self.using_service:
            try:
                return self.client.new_velocity(agent, others, params)
            except rospy.ServiceException:
                self.using_service = False  # the server went away: keep flying on the reference
        return reference.new_velocity(agent, others, params)

    def new_velocity_many(self, problems: Sequence[Problem]) -> list[Solution]:
        """`new_velocity` for each problem, in one service call; the reference problem by problem without it."""
        if self.using_service:
            try:
                return self.client.new_velocity_many(problems)
            except rospy.ServiceException:
                self.using_service = False
        return [reference.new_velocity(p.agent, p.neighbors, p.params) for p in problems]
