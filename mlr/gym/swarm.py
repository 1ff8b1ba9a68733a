"""What the gym environments share: copies of a scenario in flight, their goals, and each UAV's view.

`Swarm` places a copy's UAVs where the mission's take-off leaves them, draws every UAV's goals from
the mission's path definitions for an episode's seed, sends one control step of velocity commands to
every copy, and answers per UAV (copy c, UAV j): the NAI's input vector, the distance to its goal, the
gap to the nearest UAV or obstacle, whether it collided. The single-agent environment (env.py)
and the PettingZoo one (parallel.py) fly one copy; the vectorised one (vector.py) flies many.
"""
from __future__ import annotations

import numpy as np

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs, input_size
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.simple import saturate
from magna_uav.world_view import AgentState, WorldView
from mlr.gym.fleet import Fleet
from mlr.gym.scenario import GymUav, Scenario

ROLE = "path"
GOALS_PER_EPISODE = 64  # drawn per UAV at reset; a UAV moves on to its next goal on arrival


class Swarm:
    def __init__(self, scenario: Scenario, n_neighbors: int = 1, n_obstacles: int = 2, neighbor_dist: float = 6.0,
                 copies: int = 1):
        self.scenario = scenario
        self.n_neighbors, self.n_obstacles, self.neighbor_dist = n_neighbors, n_obstacles, neighbor_dist
        self.fleet = Fleet(scenario, copies)
        self.copies = copies
        self.uavs: tuple[GymUav, ...] = scenario.uavs
        self.observation_size = input_size(ROLE, n_neighbors, n_obstacles)
        self._goals = np.zeros((copies, len(self.uavs), GOALS_PER_EPISODE, 3))
        self._next_goal = np.zeros((copies, len(self.uavs)), dtype=int)
        self._positions = self.fleet.positions()  # (K, M, 3), read once per control step
        self._velocities = self.fleet.velocities()
        self._views: dict[tuple[int, int], WorldView] = {}  # built at most once per control step
        self._gaps: dict[tuple[int, int], float] = {}  # measured at most once per control step, as the views

    def close(self) -> None:
        self.fleet.close()

    def start(self, seed: int, copy: int = 0, encounter: bool = False) -> None:
        """A new episode of copy `copy`: goals drawn for `seed`, every UAV hovering at its take-off point; or, with
        `encounter`, the first two UAVs placed on a collision course (`encounter_starts`) when there is room."""
        for j, uav in enumerate(self.uavs):
            self._goals[copy, j] = self.scenario.goals(uav, seed + j, GOALS_PER_EPISODE)
        self._next_goal[copy] = 0
        lift = np.array([0.0, 0.0, self.scenario.take_off_height])
        starts = np.array([uav.start + lift for uav in self.uavs])
        if encounter and len(self.uavs) >= 2:
            starts = self.encounter_starts(starts, self._goals[copy, :, 0], np.random.default_rng(seed))
        self.place(starts, copy)

    def encounter_starts(self, starts: np.ndarray, goals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """`starts` with UAVs 0 and 1 moved where, flying straight to their first goals at the same speed, they
        would meet half-way between the goals (give or take a metre) after 2-4 s: the head-on and crossing
        encounters a mission holds only now and then, for a curriculum (mlr/gym/README.md). A layout that leaves
        a UAV outside the world or within a metre of an obstacle or the other's start keeps `starts`."""
        meet = (goals[0] + goals[1]) / 2.0 + rng.uniform(-1.0, 1.0, 3) * [1.0, 1.0, 0.3]
        run = rng.uniform(2.0, 4.0) * self.uavs[0].max_speed
        moved = starts.copy()
        for j in (0, 1):
            away = goals[j] - meet
            length = float(np.linalg.norm(away))
            if length < 1e-6:
                return starts
            moved[j] = meet - away / length * run
            moved[j, 2] = max(moved[j, 2], 1.0)  # not below 1 m: the course still meets, a little less head-on
        bounds = self.scenario.boundaries
        if bounds is not None and np.any((moved[:2] < bounds[:, 0] + 0.5) | (moved[:2] > bounds[:, 1] - 0.5)):
            return starts
        if np.linalg.norm(moved[0] - moved[1]) < 1.0 + 2 * self.uavs[0].safety_radius:
            return starts
        for obstacle in self.scenario.obstacles:
            if np.any(np.linalg.norm(moved[:2] - obstacle.position, axis=1) < obstacle.radius + 1.0):
                return starts
        return moved

    def place(self, positions: np.ndarray, copy: int = 0) -> None:
        """Put copy `copy`'s UAVs at rest at `positions` ((M, 3), hovering): a test's or a curriculum's start."""
        self.fleet.place(copy, positions)
        self._read()

    def fly(self, commands: np.ndarray) -> set[tuple[int, int]]:
        """Send velocity commands ((M, 3) for one copy, or (K, M, 3)), each saturated to its UAV's max speed, for
        one control step; the (copy, UAV) pairs that collided in it.

        A collision is what the UAV manager's evaluator counts in a `magna run` mission: at the end of the
        control step the UAV's safety sphere overlaps another UAV's or an obstacle's (a gap below zero). A
        physical touch in the simulator (the ground, or bodies meeting between two control steps) counts too.
        Training on bare physical contact would teach a policy to pass closer than the stack allows."""
        commands = np.asarray(commands, dtype=float).reshape(self.copies, len(self.uavs), 3)
        sent = np.array([[saturate(c, uav.max_speed) for c, uav in zip(row, self.uavs, strict=True)]
                         for row in commands])
        collided = {(touch.copy, touch.uav) for touch in self.fleet.control_step(sent)}
        self._read()
        collided |= {(c, j) for c in range(self.copies) for j in range(len(self.uavs)) if self.gap(j, c) < 0.0}
        return collided

    def _read(self) -> None:
        self._positions, self._velocities = self.fleet.positions(), self.fleet.velocities()
        self._views.clear()
        self._gaps.clear()

    def goal(self, j: int, copy: int = 0) -> np.ndarray:
        return self._goals[copy, j, self._next_goal[copy, j]]

    def next_goal(self, j: int, copy: int = 0) -> None:
        self._next_goal[copy, j] = min(self._next_goal[copy, j] + 1, GOALS_PER_EPISODE - 1)

    def arrive(self, j: int, radius: float, copy: int = 0) -> bool:
        """Whether UAV j is within `radius` of its goal; if so, it moves on to its next one (a mission's path)."""
        arrived = self.distance(j, copy) <= radius
        if arrived:
            self.next_goal(j, copy)
        return arrived

    def distance(self, j: int, copy: int = 0) -> float:
        return float(np.linalg.norm(self._positions[copy, j] - self.goal(j, copy)))

    def view(self, j: int, copy: int = 0) -> WorldView:
        """UAV j's WorldView in copy `copy`: every UAV's true state and the obstacles as the NAI has them."""
        view = self._views.get((copy, j))
        if view is None:
            positions, velocities = self._positions[copy], self._velocities[copy]
            view = WorldView(j + 1, self.scenario.boundaries)
            for k, uav in enumerate(self.uavs):
                view.update_agent(AgentState(k + 1, positions[k], velocity=velocities[k],
                                             safety_radius=uav.safety_radius))
            view.set_obstacles(self.scenario.obstacles)
            self._views[(copy, j)] = view
        return view

    def gap(self, j: int, copy: int = 0) -> float:
        """m from UAV j's safety sphere to the nearest other UAV's or obstacle's; inf when there is none."""
        gap = self._gaps.get((copy, j))
        if gap is None:
            view = self.view(j, copy)
            gaps = [gap for _, gap in view.nearest_agents(1)] + [gap for _, gap in view.nearest_obstacles(1)]
            gap = self._gaps[(copy, j)] = min(gaps) if gaps else float("inf")
        return gap

    def observation(self, j: int, copy: int = 0) -> np.ndarray:
        vector = build_inputs(self.view(j, copy), Goal(self.goal(j, copy)), ROLE, self.n_neighbors,
                              self.n_obstacles, self.neighbor_dist)
        return vector.astype(np.float32)

    def depth_image(self, j: int, camera, copy: int = 0) -> np.ndarray:
        """UAV j's forward depth image (metres, (height, width) float32) from `camera`, a magna_sim DepthCamera on
        this swarm's world: the sim node's camera model. Nothing reads beyond its `far` (20 m by default), and
        copies are 200 m apart, so a camera sees only its own copy."""
        vehicle = self.fleet.vehicle(copy, j)
        return camera.render(vehicle.position, vehicle.orientation)

    def orca(self, j: int) -> NavigationInterface:
        """An ORCA-3D NAI for UAV j with the mission's parameters (the UAVs no policy flies). The numpy reference
        solves it: the native solver is a ROS service, and the gym runs without ROS."""
        from magna_uav.nai.orca import ReferenceSolver

        nav = NavigationInterface(self.uavs[j].max_speed, self.uavs[j].safety_radius, solver=ReferenceSolver())
        nav.control("orca3d", "set", *self.scenario.orca_params)
        return nav
