"""ORCA-3D in numpy: the same algorithm as the C++ library, step for step.

It is the oracle of the tests (results agree with C++ within 1e-4) and the solver UAV
managers fall back on when the orca3d_server service is absent. It is written for
clarity, not speed: the C++ service is the fast path.

Method (van den Berg, Guy, Lin, Manocha, "Reciprocal n-body collision avoidance", 2011):
every neighbour contributes one half-space of velocities (the agent takes half the
avoidance against a cooperative neighbour, all of it against one that keeps its course);
the new velocity is the one nearest the preferred velocity inside the max-speed sphere
and all half-spaces, found by incremental linear programming; when no velocity satisfies
every half-space, the one whose largest violation is smallest is taken instead.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from magna_orca_cpp.model import Agent, Params, Solution, with_defaults
from magna_orca_cpp.validation import check_agent, check_params

SHARED_RESPONSIBILITY = 0.5
FULL_RESPONSIBILITY = 1.0
_TINY = 1e-12  # lengths below this have no usable direction
_PARALLEL = 1e-9  # |cos| or |sin| below this counts as parallel

Plane = tuple[np.ndarray, np.ndarray]  # (point, unit normal): {v : normal . (v - point) >= 0}


def violation(plane: Plane, velocity: np.ndarray) -> float:
    """How far `velocity` is outside `plane` (<= 0 when inside)."""
    point, normal = plane
    return float(normal @ (point - velocity))


def any_perpendicular(axis: np.ndarray) -> np.ndarray:
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    perpendicular = np.cross(axis, helper)
    return perpendicular / np.linalg.norm(perpendicular)


def orca_half_space(me: Agent, other: Agent, time_horizon: float, time_step: float,
                    responsibility: float) -> Plane:
    """Velocities of `me` that stay clear of `other` for the horizon (radii resolved)."""
    rel_position = other.position - me.position
    rel_velocity = me.velocity - other.velocity
    dist_sq = float(rel_position @ rel_position)
    combined = me.radius + other.radius

    if dist_sq > combined * combined:
        inv_tau = 1.0 / time_horizon
        from_cap_centre = rel_velocity - inv_tau * rel_position
        along_axis = float(from_cap_centre @ rel_position)
        cap_sq = combined * combined * float(from_cap_centre @ from_cap_centre)
        if along_axis < 0.0 and along_axis * along_axis > cap_sq:
            length = math.sqrt(float(from_cap_centre @ from_cap_centre))
            normal = from_cap_centre / length
            to_boundary = (combined * inv_tau - length) * normal
        else:
            dist = math.sqrt(dist_sq)
            axis = rel_position / dist
            sin_theta = combined / dist
            cos_theta = math.sqrt(dist_sq - combined * combined) / dist
            axial = float(rel_velocity @ axis)
            radial_part = rel_velocity - axial * axis
            radial = math.sqrt(float(radial_part @ radial_part))
            radial_dir = radial_part / radial if radial > _TINY else any_perpendicular(axis)
            along_side = max(0.0, axial * cos_theta + radial * sin_theta)
            on_side = along_side * (cos_theta * axis + sin_theta * radial_dir)
            normal = cos_theta * radial_dir - sin_theta * axis
            to_boundary = on_side - rel_velocity
    else:
        inv_step = 1.0 / time_step
        from_centre = rel_velocity - inv_step * rel_position
        length = math.sqrt(float(from_centre @ from_centre))
        if length > _TINY:
            normal = from_centre / length
        else:
            dist = math.sqrt(dist_sq)
            normal = -rel_position / dist if dist > _TINY else np.array([1.0, 0.0, 0.0])
            length = 0.0
        to_boundary = (combined * inv_step - length) * normal
    return me.velocity + responsibility * to_boundary, normal


# --- the linear programs --------------------------------------------------------------
# An objective is (target, is_direction): nearest to the point `target`, or furthest
# along the unit vector `target`.

def _best_in_sphere(radius: float, target: np.ndarray, is_direction: bool) -> np.ndarray:
    if is_direction:
        return radius * target
    length_sq = float(target @ target)
    if length_sq > radius * radius:
        return (radius / math.sqrt(length_sq)) * target
    return target.copy()


def solve_on_line(planes: Sequence[Plane], count: int, origin: np.ndarray, direction: np.ndarray, radius: float,
                  target: np.ndarray, is_direction: bool) -> np.ndarray | None:
    origin_along = float(origin @ direction)
    discriminant = origin_along * origin_along + radius * radius - float(origin @ origin)
    if discriminant < 0.0:
        return None
    half_chord = math.sqrt(discriminant)
    t_low, t_high = -origin_along - half_chord, -origin_along + half_chord
    for point, normal in planes[:count]:
        slope = float(normal @ direction)
        needed = float(normal @ (point - origin))
        if abs(slope) <= _PARALLEL:
            if needed > 0.0:
                return None
            continue
        t = needed / slope
        if slope > 0.0:
            t_low = max(t_low, t)
        else:
            t_high = min(t_high, t)
        if t_low > t_high:
            return None
    if is_direction:
        t = t_high if float(target @ direction) > 0.0 else t_low
    else:
        t = min(max(float(direction @ (target - origin)), t_low), t_high)
    return origin + t * direction


def solve_on_plane(planes: Sequence[Plane], index: int, radius: float, target: np.ndarray,
                   is_direction: bool) -> np.ndarray | None:
    point, normal = planes[index]
    offset = float(point @ normal)
    disc_radius_sq = radius * radius - offset * offset
    if disc_radius_sq < 0.0:
        return None
    disc_radius = math.sqrt(disc_radius_sq)
    centre = offset * normal
    if is_direction:
        along = target - float(target @ normal) * normal
        along_sq = float(along @ along)
        result = centre + (disc_radius / math.sqrt(along_sq)) * along if along_sq > _PARALLEL * _PARALLEL else centre
    else:
        projected = target + float((point - target) @ normal) * normal
        from_centre = projected - centre
        from_centre_sq = float(from_centre @ from_centre)
        if from_centre_sq > disc_radius_sq:
            result = centre + (disc_radius / math.sqrt(from_centre_sq)) * from_centre
        else:
            result = projected
    for j in range(index):
        if violation(planes[j], result) <= 0.0:
            continue
        other_point, other_normal = planes[j]
        crossing = np.cross(other_normal, normal)
        crossing_sq = float(crossing @ crossing)
        if crossing_sq <= _PARALLEL * _PARALLEL:
            return None
        direction = crossing / math.sqrt(crossing_sq)
        across = np.cross(direction, normal)
        step = float(other_normal @ (other_point - point)) / float(other_normal @ across)
        on_line = solve_on_line(planes, j, point + step * across, direction, radius, target, is_direction)
        if on_line is None:
            return None
        result = on_line
    return result


def solve_in_space(planes: Sequence[Plane], radius: float, target: np.ndarray,
                   is_direction: bool) -> tuple[int, np.ndarray]:
    """(len(planes), optimum), or (index of the first plane that could not be met, optimum before it)."""
    result = _best_in_sphere(radius, target, is_direction)
    for i in range(len(planes)):
        if violation(planes[i], result) <= 0.0:
            continue
        moved = solve_on_plane(planes, i, radius, target, is_direction)
        if moved is None:
            return i, result
        result = moved
    return len(planes), result


def least_violation(planes: Sequence[Plane], first_failed: int, radius: float, result: np.ndarray) -> np.ndarray:
    """The velocity in the sphere whose largest violation is smallest, continuing from `result`."""
    worst = 0.0
    for i in range(first_failed, len(planes)):
        if violation(planes[i], result) <= worst:
            continue
        point_i, normal_i = planes[i]
        bisectors: list[Plane] = []
        for point_j, normal_j in planes[:i]:
            normal_gap = normal_j - normal_i
            gap_sq = float(normal_gap @ normal_gap)
            if gap_sq <= _PARALLEL * _PARALLEL:
                continue
            offset = float(normal_j @ point_j) - float(normal_i @ point_i)
            bisectors.append(((offset / gap_sq) * normal_gap, normal_gap / math.sqrt(gap_sq)))
        reached, candidate = solve_in_space(bisectors, radius, normal_i, True)
        if reached == len(bisectors):
            result = candidate
        worst = violation(planes[i], result)
    return result


def solve_velocity(planes: Sequence[Plane], max_speed: float, preferred: np.ndarray) -> Solution:
    """Nearest to `preferred` within `max_speed` and every plane, or the least violating velocity."""
    preferred = np.asarray(preferred, dtype=float)
    reached, result = solve_in_space(planes, max_speed, preferred, False)
    if reached < len(planes):
        return Solution(least_violation(planes, reached, max_speed, result), False)
    return Solution(result, True)


# --- agents ---------------------------------------------------------------------------

def surface_gap(a: Agent, b: Agent) -> float:
    return math.sqrt(float((b.position - a.position) @ (b.position - a.position))) - a.radius - b.radius


def select_neighbors(me: Agent, others: Sequence[Agent], max_neighbors: int, neighbor_dist: float,
                     skip: int | None = None) -> list[int]:
    """Indices of the nearest `max_neighbors` of `others` whose gap is below `neighbor_dist`, nearest first."""
    candidates = []
    for j, other in enumerate(others):
        if j == skip:
            continue
        gap = surface_gap(me, other)
        if gap < neighbor_dist:
            candidates.append((gap, j))
    candidates.sort()
    return [j for _, j in candidates[:max_neighbors]]


def half_spaces(me: Agent, others: Sequence[Agent], params: Params, skip: int | None = None) -> list[Plane]:
    """The half-spaces the selected neighbours impose on `me` (radii resolved), nearest first."""
    planes = []
    for j in select_neighbors(me, others, params.max_neighbors, params.neighbor_dist, skip):
        other = others[j]
        share = SHARED_RESPONSIBILITY if other.cooperative else FULL_RESPONSIBILITY
        planes.append(orca_half_space(me, other, params.time_horizon, params.time_step, share))
    return planes


def _solve(me: Agent, others: Sequence[Agent], params: Params, skip: int | None = None) -> Solution:
    if not me.cooperative:
        return Solution(me.preferred_velocity.copy(), True)
    return solve_velocity(half_spaces(me, others, params, skip), me.max_speed, me.preferred_velocity)


def new_velocity(agent: Agent, others: Sequence[Agent], params: Params) -> Solution:
    """New velocity of `agent` against the agents it may see (checked first)."""
    check_params(params)
    check_agent(agent, params, "agent")
    for j, other in enumerate(others):
        check_agent(other, params, f"neighbors[{j}]")
    return _solve(with_defaults(agent, params), [with_defaults(o, params) for o in others], params)


def new_velocities(agents: Sequence[Agent], params: Params) -> list[Solution]:
    """New velocities of all `agents`, each against its nearest among the others."""
    check_params(params)
    for i, agent in enumerate(agents):
        check_agent(agent, params, f"agents[{i}]")
    resolved = [with_defaults(agent, params) for agent in agents]
    return [_solve(me, resolved, params, skip=i) for i, me in enumerate(resolved)]
