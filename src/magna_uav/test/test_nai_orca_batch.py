"""OrcaBatcher: the ORCA-3D problems of a process's managers in one call per step, answers unchanged."""
import threading

import numpy as np
import pytest

from magna_orca_cpp.model import Agent, Params, Problem, Solution
from magna_orca_cpp.validation import OrcaInputError
from magna_uav.nai.orca import OrcaNavigator, ReferenceSolver
from magna_uav.nai.orca_batch import OrcaBatcher
from magna_uav.world_view import AgentState, Obstacle, WorldView
from tests.support import wait_until

NEVER = 3600.0  # a straggler wait no test reaches: rounds must close because everyone is in, or someone left


class FakeSolver:
    """Answers each problem with its agent's position (so a misrouted answer shows), recording every call."""

    using_service = True

    def __init__(self, refuse_x=None):
        self.many_calls: list[list[Problem]] = []
        self.one_calls: list[Problem] = []
        self.refuse_x = refuse_x  # a problem whose agent is at this x is bad input
        self._lock = threading.Lock()

    def _answer(self, problem):
        if self.refuse_x is not None and problem.agent.position[0] == self.refuse_x:
            raise OrcaInputError(f"agent.position.x is {self.refuse_x}: refused")
        return Solution(problem.agent.position.copy(), problem.agent.position[0] > 0)

    def new_velocity_many(self, problems):
        with self._lock:
            self.many_calls.append(list(problems))
        return [self._answer(p) for p in problems]

    def new_velocity(self, agent, others, params):
        problem = Problem(agent, others, params)
        with self._lock:
            self.one_calls.append(problem)
        return self._answer(problem)


def problem_of(uav_id):
    return Problem(Agent(position=[float(uav_id), 10.0 * uav_id, 1.0]), [], Params())


class Submission(threading.Thread):
    """One participant's solve, in a thread of its own; the answer or the error is kept."""

    def __init__(self, batcher, uav_id, key, problem=None):
        super().__init__(daemon=True)
        self.batcher, self.uav_id, self.key = batcher, uav_id, key
        self.problem = problem or problem_of(uav_id)
        self.answer = self.error = None
        self.start()

    def run(self):
        try:
            self.answer = self.batcher.solve(self.uav_id, self.key, self.problem)
        except Exception as err:
            self.error = err

    def finished(self):
        return not self.is_alive()


def finish(*submissions):
    wait_until(lambda: all(s.finished() for s in submissions), "every submission to be answered")


def test_three_participants_are_served_by_one_call_each_with_its_own_answer():
    solver = FakeSolver()
    batcher = OrcaBatcher(solver, straggler_wait=NEVER)
    for uav_id in (1, 2, 3):
        batcher.join(uav_id)
    first, second = Submission(batcher, 1, 7), Submission(batcher, 2, 7)
    wait_until(lambda: 2 in batcher._last_key, "UAV 2 to submit")
    assert not first.finished() and not second.finished(), "nobody is answered before UAV 3 submits"
    assert solver.many_calls == []
    third = Submission(batcher, 3, 7)
    finish(first, second, third)
    assert len(solver.many_calls) == 1 and len(solver.many_calls[0]) == 3 and solver.one_calls == []
    for s in (first, second, third):
        assert s.error is None
        np.testing.assert_array_equal(s.answer.velocity, s.problem.agent.position)
        assert s.answer.feasible
    assert batcher.rounds == 1


def test_a_silent_participant_costs_one_wait_then_is_not_waited_for_until_it_submits():
    solver = FakeSolver()
    batcher = OrcaBatcher(solver, straggler_wait=0.05)
    for uav_id in (1, 2, 3):
        batcher.join(uav_id)
    lone = Submission(batcher, 1, 0)
    finish(lone)  # UAVs 2 and 3 never submit step 0: the straggler wait ends the round
    assert [len(c) for c in solver.many_calls] == [1] and lone.answer is not None

    batcher.straggler_wait = NEVER  # from now on a step goes through only if idle UAVs are not waited for
    lone = Submission(batcher, 1, 1)
    finish(lone)
    assert [len(c) for c in solver.many_calls] == [1, 1]

    # UAV 3 steps again: it is no longer idle, and the next step waits for it and UAV 1, not for UAV 2
    back = Submission(batcher, 3, 2)
    wait_until(lambda: 3 in batcher._last_key, "UAV 3 to submit")
    assert not back.finished(), "UAV 1 has not submitted step 2 yet"
    lone = Submission(batcher, 1, 2)
    finish(back, lone)
    assert [len(c) for c in solver.many_calls] == [1, 1, 2]
    assert back.error is None and lone.error is None


def test_leaving_releases_the_participants_waiting_for_it():
    solver = FakeSolver()
    batcher = OrcaBatcher(solver, straggler_wait=NEVER)
    for uav_id in (1, 2, 3):
        batcher.join(uav_id)
    a, b = Submission(batcher, 1, "t5"), Submission(batcher, 2, "t5")
    wait_until(lambda: {1, 2} <= batcher._last_key.keys(), "UAVs 1 and 2 to submit")
    assert not a.finished()
    batcher.leave(3)
    finish(a, b)
    assert [len(c) for c in solver.many_calls] == [2]
    assert batcher.participants == {1, 2}
    batcher.leave(3)  # leaving twice is harmless


def test_joined_leaves_however_the_block_ends():
    batcher = OrcaBatcher(FakeSolver())
    with pytest.raises(RuntimeError, match="the manager failed"):
        with batcher.joined(4):
            assert batcher.participants == {4}
            raise RuntimeError("the manager failed")
    assert batcher.participants == frozenset()


def test_misuse_is_named():
    batcher = OrcaBatcher(FakeSolver())
    with pytest.raises(ValueError, match=r"UAV 5 has not joined .* join\(5\)"):
        batcher.solve(5, 0, problem_of(5))
    batcher.join(5)
    with pytest.raises(ValueError, match="already joined"):
        batcher.join(5)
    with pytest.raises(ValueError, match="straggler_wait"):
        OrcaBatcher(FakeSolver(), straggler_wait=0)
    with pytest.raises(ValueError, match="step_key"):
        OrcaNavigator(batcher=batcher)


def test_a_refused_problem_fails_only_its_own_uav():
    solver = FakeSolver(refuse_x=2.0)
    batcher = OrcaBatcher(solver, straggler_wait=NEVER)
    for uav_id in (1, 2, 3):
        batcher.join(uav_id)
    subs = [Submission(batcher, i, 0) for i in (1, 2, 3)]
    finish(*subs)
    assert isinstance(subs[1].error, OrcaInputError) and "refused" in str(subs[1].error)
    for s in (subs[0], subs[2]):
        assert s.error is None
        np.testing.assert_array_equal(s.answer.velocity, s.problem.agent.position)
    assert len(solver.one_calls) == 3, "the refused many-call is redone problem by problem"


def ring(n, radius=6.0, height=5.0):
    angles = 2 * np.pi * np.arange(n) / n
    return np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(n, height)], axis=1)


def test_batched_flight_equals_one_solve_per_uav_bit_for_bit():
    """Eight UAVs cross a ring past a pillar, each step solved by eight threads through one batcher,
    and again one UAV at a time through the same solver: every velocity is the same, bit for bit."""
    n, steps, dt = 8, 40, 0.1
    starts = ring(n) + np.random.default_rng(3).uniform(-0.05, 0.05, (n, 3))
    goals = -starts * [1, 1, 0] + [0, 0, 5.0]
    pillar = Obstacle("pillar", np.array([0.3, -0.2, 5.0]), 1.0)
    params = Params(max_neighbors=5, neighbor_dist=6.0, time_horizon=3.0, time_step=0.1, agent_radius=0.5,
                    max_speed=2.0)
    ids = list(range(1, n + 1))
    solver = ReferenceSolver()
    batcher = OrcaBatcher(solver, straggler_wait=NEVER)
    tick = {"index": 0}
    batched = {i: OrcaNavigator(batcher=batcher, step_key=lambda: tick["index"]) for i in ids}
    alone = {i: OrcaNavigator(solver) for i in ids}
    positions = {i: starts[i - 1].copy() for i in ids}
    velocities = {i: np.zeros(3) for i in ids}

    def views():
        result = {}
        for i in ids:
            view = WorldView(i)
            for j in ids:
                view.update_agent(AgentState(j, positions[j].copy(), velocity=velocities[j].copy(),
                                             safety_radius=0.3))
            view.set_obstacles([pillar])
            result[i] = view
        return result

    def preferred(i):
        to_goal = goals[i - 1] - positions[i]
        distance = np.linalg.norm(to_goal)
        return to_goal / distance * min(2.0, distance) if distance > 0 else np.zeros(3)

    for i in ids:
        batcher.join(i)
    avoided = 0
    try:
        for step in range(steps):
            tick["index"] = step
            step_views = views()
            answers, errors = {}, []

            def fly(i, step_views=step_views, answers=answers, errors=errors):
                try:
                    answers[i] = batched[i].velocity(step_views[i], preferred(i), params, 2, 0.3, 2.0)
                except Exception as err:  # noqa: BLE001 - reported by the assertion below
                    errors.append(err)

            threads = [threading.Thread(target=fly, args=(i,)) for i in ids]
            for t in threads:
                t.start()
            for t in threads:
                t.join(60)
            assert not errors and len(answers) == n
            for i in ids:
                single = alone[i].velocity(step_views[i], preferred(i), params, 2, 0.3, 2.0)
                assert answers[i].velocity.tobytes() == single.velocity.tobytes(), f"UAV {i} at step {step}"
                assert answers[i].feasible == single.feasible
                assert answers[i].neighbors.ids == single.neighbors.ids
                avoided += not np.allclose(single.velocity, preferred(i), atol=1e-6)
            for i in ids:
                velocities[i] = answers[i].velocity
                positions[i] = positions[i] + dt * velocities[i]
    finally:
        for i in ids:
            batcher.leave(i)
    assert batcher.rounds == steps, "one call per step for all eight"
    crossed = [np.linalg.norm(positions[i] - starts[i - 1]) for i in ids]
    assert min(crossed) > 2.0, "the UAVs flew (the comparison is not of a standstill)"
    assert avoided > n, "ORCA-3D changed preferred velocities (the comparison covers real avoidance)"
