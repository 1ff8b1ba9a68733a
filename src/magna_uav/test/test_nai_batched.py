"""NavigationInterfaces of one process sharing an OrcaBatcher: the same commands as separate ones, one call per tick.

A manager host gives each manager's NAI an OrcaNavigator on the process's batcher, keyed by the stepping clock's
tick; a role's first step (key None) is solved alone, and a role's end releases the UAV so nobody waits for it.
"""
import threading

import numpy as np

from magna_uav.nai import Goal, NavigationInterface
from magna_uav.nai.orca import OrcaNavigator, ReferenceSolver
from magna_uav.nai.orca_batch import OrcaBatcher
from magna_uav.world_view import AgentState, Obstacle, WorldView

NEVER = 3600.0  # no round may close by the straggler wait: only because everyone stepping is in
MAX_SPEED, SAFETY_RADIUS = 2.0, 0.3


class CountingSolver(ReferenceSolver):
    """The numpy reference, noting the size of every many-call and the number of single calls."""

    def __init__(self):
        self.many_sizes: list[int] = []
        self.single_calls = 0
        self._lock = threading.Lock()

    def new_velocity(self, agent, others, params):
        with self._lock:
            self.single_calls += 1
        return super().new_velocity(agent, others, params)

    def new_velocity_many(self, problems):
        with self._lock:
            self.many_sizes.append(len(problems))
        return super().new_velocity_many(problems)


def orca3d(nai: NavigationInterface) -> NavigationInterface:
    nai.control("orca3d", "set", ["N_neighbors_aware", "N_obstacles_aware", "timeHorizon"], [4, 1, 3.0])
    return nai


class Swarm:
    """n UAVs on a ring, each flying to the opposite point past a pillar in the middle, moved by the commands."""

    def __init__(self, n: int = 6):
        angles = 2 * np.pi * np.arange(n) / n
        self.ids = list(range(1, n + 1))
        jitter = np.random.default_rng(5).uniform(-0.05, 0.05, (n, 3))
        starts = np.stack([6 * np.cos(angles), 6 * np.sin(angles), np.full(n, 5.0)], axis=1) + jitter
        self.starts = starts
        self.positions = {i: starts[i - 1].copy() for i in self.ids}
        self.velocities = {i: np.zeros(3) for i in self.ids}
        self.goals = {i: Goal(position=-starts[i - 1] * [1, 1, 0] + [0, 0, 5.0]) for i in self.ids}
        self.pillar = Obstacle("pillar", np.array([0.3, -0.2, 5.0]), 1.0)

    def views(self) -> dict[int, WorldView]:
        views = {}
        for i in self.ids:
            view = WorldView(i)
            for j in self.ids:
                view.update_agent(AgentState(j, self.positions[j].copy(), velocity=self.velocities[j].copy(),
                                             safety_radius=SAFETY_RADIUS))
            view.set_obstacles([self.pillar])
            views[i] = view
        return views

    def move(self, commands: dict, dt: float = 0.1) -> None:
        for i, command in commands.items():
            self.velocities[i] = command.velocity
            self.positions[i] = self.positions[i] + dt * command.velocity


def in_threads(calls: dict) -> dict:
    """Each call in a thread of its own, as the managers of a host step; their results by key."""
    results, errors = {}, []

    def run(key, call):
        try:
            results[key] = call()
        except Exception as err:  # noqa: BLE001 - reported by the assertion below
            errors.append(err)

    threads = [threading.Thread(target=run, args=item, daemon=True) for item in calls.items()]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    assert not any(t.is_alive() for t in threads), "a step is still waiting: someone it waits for never comes"
    assert not errors, errors
    return results


def assert_same(batched, alone, where: str) -> None:
    assert batched.velocity.tobytes() == alone.velocity.tobytes(), where
    assert (batched.yaw_rate, batched.algorithm, batched.feasible, batched.neighbors, batched.obstacles,
            batched.error) == (alone.yaw_rate, alone.algorithm, alone.feasible, alone.neighbors, alone.obstacles,
                               alone.error), where


def test_shared_batcher_gives_the_commands_of_separate_interfaces_in_one_call_per_tick():
    swarm = Swarm()
    solver = CountingSolver()
    batcher = OrcaBatcher(solver, straggler_wait=NEVER)
    tick: dict[str, tuple | None] = {"key": None}
    shared = {i: orca3d(NavigationInterface(MAX_SPEED, SAFETY_RADIUS,
                                            orca=OrcaNavigator(batcher=batcher, step_key=lambda: tick["key"])))
              for i in swarm.ids}
    separate = {i: orca3d(NavigationInterface(MAX_SPEED, SAFETY_RADIUS, solver=ReferenceSolver())) for i in swarm.ids}
    avoided = 0
    for step in range(40):
        tick["key"] = None if step == 0 else (0.1, step)  # a role's first step is on no shared tick
        views = swarm.views()
        commands = in_threads({i: (lambda i=i, views=views: shared[i].velocity(views[i], swarm.goals[i]))
                               for i in swarm.ids})
        for i in swarm.ids:
            alone = separate[i].velocity(views[i], swarm.goals[i])
            assert_same(commands[i], alone, f"UAV {i} at step {step}")
            preferred = shared[i]._preferred(views[i], swarm.goals[i])
            avoided += not np.allclose(alone.velocity, preferred, atol=1e-6)
        if step == 0:
            assert solver.single_calls == len(swarm.ids) and solver.many_sizes == [], \
                "the first step is solved alone per UAV"
            assert batcher.participants == set(swarm.ids), "and joins, so the next tick waits for everyone"
        swarm.move(commands)
    assert solver.many_sizes == [len(swarm.ids)] * 39, "one call per tick for all six"
    assert avoided > len(swarm.ids), "ORCA-3D changed preferred velocities (the comparison covers real avoidance)"
    assert min(np.linalg.norm(swarm.positions[i] - swarm.starts[i - 1]) for i in swarm.ids) > 2.0, "they flew"
    for nai in shared.values():
        nai.release()
    assert batcher.participants == frozenset()


def test_a_released_uav_holds_nobody_up_and_joins_again_when_it_steps():
    """UAV 3's role ends (released) while the others fly on: with no straggler wait at all, their ticks go through
    without it; when it flies ORCA-3D again it is in the same calls again. A UAV flying 'simple' never joins."""
    swarm = Swarm(4)
    solver = CountingSolver()
    batcher = OrcaBatcher(solver, straggler_wait=NEVER)
    tick: dict[str, tuple | None] = {"key": None}
    nais = {i: NavigationInterface(MAX_SPEED, SAFETY_RADIUS,
                                   orca=OrcaNavigator(batcher=batcher, step_key=lambda: tick["key"]))
            for i in swarm.ids}
    for i in (1, 2, 3):
        orca3d(nais[i])  # UAV 4 flies with "simple": it never calls ORCA-3D

    def step(key, flying):
        tick["key"] = key
        views = swarm.views()
        swarm.move(in_threads({i: (lambda i=i: nais[i].velocity(views[i], swarm.goals[i])) for i in flying}))

    step(None, swarm.ids)  # the roles' first steps
    for k in (1, 2):
        step((0.1, k), swarm.ids)
    assert solver.many_sizes == [3, 3] and batcher.participants == {1, 2, 3}
    nais[3].release()  # its role ended
    assert batcher.participants == {1, 2}
    for k in (3, 4):
        step((0.1, k), [1, 2, 4])
    step(None, [3])  # its next role's first step: alone, at once
    for k in (5, 6):
        step((0.1, k), swarm.ids)
    assert solver.many_sizes == [3, 3, 2, 2, 3, 3] and solver.single_calls == 3 + 1
    assert batcher.participants == {1, 2, 3}
