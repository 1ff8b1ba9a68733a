"""The C++ solver against the numpy reference, and both against the definition of the answer.

10,000 seeded random scenarios (0-20 neighbours, cooperative and not, overlapping and
not): whenever the program is feasible the velocity lies inside every half-space and the
max-speed sphere, C++ and Python build the same half-spaces and agree within 1e-4. A
smaller set is checked against scipy's general-purpose optimiser, so the two
implementations cannot share a mistake unnoticed.
"""
import numpy as np
import pytest
from scipy.optimize import minimize

from magna_orca_cpp import native, reference
from magna_orca_cpp.model import Agent, Params, with_defaults
from magna_orca_cpp.scenarios import crowd, scenarios

SCENARIOS = 10_000
AGREEMENT = 1e-4  # m/s, the bar between C++ and Python
INSIDE = 1e-9  # m/s: how far rounding may leave a velocity outside a half-space it meets


@pytest.fixture(scope="module")
def random_set():
    return scenarios(seed=2026, count=SCENARIOS, n_neighbors=(0, 20))


@pytest.fixture(scope="module")
def native_answers(random_set):
    """C++ velocities (n, 3) and feasibility flags (n,) of the random set."""
    solved = [native.new_velocity(s.agent, s.neighbors, s.params) for s in random_set]
    return np.array([s.velocity for s in solved]), np.array([s.feasible for s in solved])


def largest_violation(planes, velocity):
    return max((reference.violation(p, velocity) for p in planes), default=-np.inf)


def test_feasible_results_meet_every_half_space_and_the_speed_limit(random_set, native_answers):
    velocities, feasible = native_answers
    assert 0.05 < feasible.mean() < 0.98, "the set must exercise both the feasible and the infeasible programs"
    for scenario, velocity, ok in zip(random_set, velocities, feasible, strict=True):
        me = with_defaults(scenario.agent, scenario.params)
        assert np.linalg.norm(velocity) <= me.max_speed * (1 + 1e-12)
        if ok:
            planes = native.half_spaces(scenario.agent, scenario.neighbors, scenario.params)
            assert largest_violation(planes, velocity) <= INSIDE


def test_cpp_and_python_agree(random_set, native_answers):
    velocities, feasible = native_answers
    worst = 0.0
    for k, scenario in enumerate(random_set):
        expected = reference.new_velocity(scenario.agent, scenario.neighbors, scenario.params)
        assert expected.feasible == feasible[k], f"scenario {k}: feasibility differs"
        worst = max(worst, float(np.abs(expected.velocity - velocities[k]).max()))
        assert worst <= AGREEMENT, f"scenario {k}: C++ {velocities[k]} vs Python {expected.velocity}"


def test_cpp_and_python_build_the_same_half_spaces(random_set):
    planes_seen = 0
    for scenario in random_set[:2000]:
        ours = native.half_spaces(scenario.agent, scenario.neighbors, scenario.params)
        theirs = reference.half_spaces(with_defaults(scenario.agent, scenario.params),
                                       [with_defaults(n, scenario.params) for n in scenario.neighbors], scenario.params)
        assert len(ours) == len(theirs)
        planes_seen += len(ours)
        for (p1, n1), (p2, n2) in zip(ours, theirs, strict=True):
            np.testing.assert_allclose(p1, p2, atol=1e-9)
            np.testing.assert_allclose(n1, n2, atol=1e-9)
    assert planes_seen > 10_000


def _scipy_nearest(planes, radius, preferred):
    """The feasible velocity nearest `preferred`, by SLSQP (None when it does not converge)."""
    points = np.array([p for p, _ in planes]).reshape(-1, 3)
    normals = np.array([n for _, n in planes]).reshape(-1, 3)
    constraints = [{"type": "ineq", "fun": lambda v: radius * radius - v @ v}]
    if len(planes):
        constraints.append({"type": "ineq", "fun": lambda v: normals @ v - np.sum(normals * points, axis=1)})
    result = minimize(lambda v: np.sum((v - preferred) ** 2), np.zeros(3), constraints=constraints, method="SLSQP",
                      options={"ftol": 1e-12, "maxiter": 500})
    inside = result.success and (not len(planes) or largest_violation(planes, result.x) <= 1e-7)
    return result.x if inside and result.x @ result.x <= radius * radius + 1e-9 else None


def _scipy_least_violation(planes, radius, starts):
    """The smallest largest-violation reachable in the sphere, by SLSQP on (v, d) from several starts."""
    points = np.array([p for p, _ in planes])
    normals = np.array([n for _, n in planes])
    constraints = [{"type": "ineq", "fun": lambda x: normals @ x[:3] - np.sum(normals * points, axis=1) + x[3]},
                   {"type": "ineq", "fun": lambda x: radius * radius - x[:3] @ x[:3]}]
    best = np.inf
    for start in starts:
        result = minimize(lambda x: x[3], np.r_[start, 10.0], constraints=constraints, method="SLSQP",
                          options={"ftol": 1e-12, "maxiter": 1000})
        if result.success:
            best = min(best, largest_violation(planes, result.x[:3]))
    return best


def test_answers_are_optimal_by_an_independent_optimiser(random_set, native_answers):
    velocities, feasible = native_answers
    checked = {True: 0, False: 0}
    for k, scenario in enumerate(random_set[:600]):
        planes = native.half_spaces(scenario.agent, scenario.neighbors, scenario.params)
        me = with_defaults(scenario.agent, scenario.params)
        if feasible[k]:
            other = _scipy_nearest(planes, me.max_speed, me.preferred_velocity)
            if other is None:
                continue
            ours = np.linalg.norm(velocities[k] - me.preferred_velocity)
            assert ours <= np.linalg.norm(other - me.preferred_velocity) + 1e-6, f"scenario {k}: scipy found nearer"
        else:
            best = _scipy_least_violation(planes, me.max_speed, [np.zeros(3), velocities[k], me.preferred_velocity])
            assert largest_violation(planes, velocities[k]) <= best + 1e-6, f"scenario {k}: scipy violates less"
        checked[bool(feasible[k])] += 1
    assert checked[True] > 300 and checked[False] > 50, checked


@pytest.mark.parametrize("n_agents", [8, 125, 400])
def test_batch_with_kd_tree_equals_reference_brute_force(n_agents):
    params = Params(max_neighbors=6, neighbor_dist=3.0, time_horizon=2.0, time_step=0.1)
    agents = crowd(seed=n_agents, n_agents=n_agents, spacing=1.6, params=params)
    ours = native.new_velocities(agents, params)
    theirs = reference.new_velocities(agents, params)
    for k, (a, b) in enumerate(zip(ours, theirs, strict=True)):
        assert a.feasible == b.feasible, f"agent {k}"
        np.testing.assert_allclose(a.velocity, b.velocity, atol=AGREEMENT, err_msg=f"agent {k}")


def test_non_cooperative_agents_keep_their_course_and_others_take_all_the_avoidance():
    params = Params(time_horizon=4.0)
    uav = Agent([0, 0, 0], [1, 0, 0], [1, 0, 0], 0.5, 2.0)
    obstacle = Agent([4, 0.2, 0], [0, 0, 0], [0, 0, 0], 0.5, 0.0, cooperative=False)
    twin = Agent([4, 0.2, 0], [0, 0, 0], [0, 0, 0], 0.5, 2.0, cooperative=True)
    for solver in (native, reference):
        solved = solver.new_velocities([uav, obstacle], params)
        np.testing.assert_array_equal(solved[1].velocity, [0, 0, 0])
        against_obstacle = solver.new_velocity(uav, [obstacle], params).velocity
        against_twin = solver.new_velocity(uav, [twin], params).velocity
        # Full responsibility turns twice as far from the preferred velocity as a shared one.
        np.testing.assert_allclose(np.linalg.norm(against_obstacle - uav.preferred_velocity),
                                   2 * np.linalg.norm(against_twin - uav.preferred_velocity), rtol=1e-9)


def test_python_reference_closed_loop_keeps_four_agents_apart():
    params = Params(max_neighbors=5, time_step=0.05, neighbor_dist=20.0, time_horizon=3.0, agent_radius=0.5)
    rng = np.random.default_rng(4)
    starts = [np.array([5 * np.cos(a), 5 * np.sin(a), 0.0]) + rng.uniform(-0.01, 0.01, 3)
              for a in np.linspace(0, 2 * np.pi, 4, endpoint=False)]
    agents = [Agent(s, np.zeros(3), np.zeros(3), 0.5, 2.0) for s in starts]
    goals = [-s for s in starts]
    closest = np.inf
    for _ in range(400):
        for agent, goal in zip(agents, goals, strict=True):
            gap = goal - agent.position
            distance = np.linalg.norm(gap)
            speed = min(2.0, distance / params.time_step) if distance > 1e-9 else 0.0
            agent.preferred_velocity = gap / max(distance, 1e-9) * speed
        solved = reference.new_velocities(agents, params)
        for agent, solution in zip(agents, solved, strict=True):
            agent.velocity = solution.velocity
            agent.position = agent.position + params.time_step * solution.velocity
        closest = min(closest, min(np.linalg.norm(a.position - b.position)
                                   for i, a in enumerate(agents) for b in agents[i + 1:]))
    assert closest >= 1.0 - 1e-9
    assert all(np.linalg.norm(a.position - g) < 0.05 for a, g in zip(agents, goals, strict=True))
