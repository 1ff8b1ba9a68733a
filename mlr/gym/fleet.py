"""Copies of one scenario flown together in a single magna_sim world: the gym's physics.

magna_sim's SimWorld steps every UAV of a world in one vectorised guidance call, so K copies of a
2-UAV scenario side by side cost far less than K worlds (docs: mlr/gym README, "How fast"). Copy c is
the scenario moved `spacing` metres along x times c; nothing of one copy comes near another's. Every
position this module gives or takes is in the scenario's own frame (the copy's offset removed).

A control step sends each UAV's velocity command through its UAL, as the UAV manager does, and runs
physics_rate / control_rate physics steps. Episodes start in the air (SimWorld.place_airborne), where
the mission's take-off would have left the UAV, so the light flight model is the one used.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magna_sim.world import Contact, SimWorld
from mlr.gym.scenario import Scenario

FLIGHT_MODEL = "light"  # magna_sim's default; the only one a UAV can start airborne in
DEFAULT_SPACING = 200.0  # m between copies


class FleetError(ValueError):
    """A scenario or setting the fleet cannot fly; the message says which and what to change."""


@dataclass(frozen=True)
class Touch:
    """A UAV of a copy started touching something in the last control step."""

    copy: int
    uav: int  # index in scenario.uavs
    other_kind: str  # "uav", "obstacle" or "ground"


class Fleet:
    def __init__(self, scenario: Scenario, copies: int = 1, physics_rate: float = 240.0, control_rate: float = 10.0,
                 seed: int = 0, spacing: float = DEFAULT_SPACING):
        if copies < 1:
            raise FleetError(f"copies: {copies}; give 1 or more")
        steps = physics_rate / control_rate
        if not (control_rate > 0 and abs(steps - round(steps)) < 1e-9 and steps >= 1):
            raise FleetError(f"control_rate: {control_rate} Hz must divide the physics rate {physics_rate} Hz")
        self.scenario = scenario
        self.copies = copies
        self.steps_per_control = int(round(steps))
        self.control_dt = 1.0 / control_rate
        self.offsets = np.array([[spacing * c, 0.0, 0.0] for c in range(copies)])
        _check_spacing(scenario, spacing)
        self.world = SimWorld(physics_rate, seed=seed)
        n = len(scenario.uavs)
        self._ids = np.arange(copies * n).reshape(copies, n) + 1  # SimWorld ids, copy-major
        for c, offset in enumerate(self.offsets):
            for j, uav in enumerate(scenario.uavs):
                uav_id = int(self._ids[c, j])
                self.world.spawn_uav(f"c{c}_uav_{uav.id}", uav_id, uav.airframe.model, FLIGHT_MODEL,
                                     uav.start + offset)
            for solid in scenario.solids:
                vertices = [[x, y, 0.0] for x, y in solid.polygon] or None
                self.world.spawn_obstacle(f"c{c}_{solid.name}", solid.shape, list(solid.dimensions), vertices,
                                          solid.position + offset, solid.quaternion)
        self._by_id = {int(self._ids[c, j]): (c, j) for c in range(copies) for j in range(n)}
        self.world.step()  # every UAL leaves UNINITIALIZED
        self._vehicles = [[self.world.vehicles[int(self._ids[c, j])] for j in range(n)] for c in range(copies)]

    @property
    def uav_count(self) -> int:
        return len(self.scenario.uavs)

    def close(self) -> None:
        self.world.close()

    def place(self, copy: int, positions: np.ndarray, yaws: np.ndarray | None = None) -> None:
        """Put copy `copy`'s UAVs at rest at `positions` ((M, 3), scenario frame), flying and holding there."""
        positions = np.asarray(positions, dtype=float).reshape(self.uav_count, 3)
        for j in range(self.uav_count):
            yaw = 0.0 if yaws is None else float(yaws[j])
            self.world.place_airborne(int(self._ids[copy, j]), positions[j] + self.offsets[copy], yaw)

    def vehicle(self, copy: int, j: int):
        """The magna_sim vehicle of UAV j of `copy` (world frame: its position includes the copy's offset)."""
        return self._vehicles[copy][j]

    def positions(self) -> np.ndarray:
        """(K, M, 3) in the scenario frame."""
        return np.array([[v.position for v in row] for row in self._vehicles]) - self.offsets[:, None, :]

    def velocities(self) -> np.ndarray:
        """(K, M, 3) m/s."""
        return np.array([[v.velocity for v in row] for row in self._vehicles])

    def control_step(self, velocities: np.ndarray, copies: np.ndarray | None = None) -> list[Touch]:
        """Command (K, M, 3) velocities (only to `copies`, a boolean mask, when given; the others hold), run one
        control period, and return what began touching during it."""
        velocities = np.asarray(velocities, dtype=float).reshape(self.copies, self.uav_count, 3)
        for c in range(self.copies):
            if copies is not None and not copies[c]:
                continue
            for j in range(self.uav_count):
                self.world.ual[int(self._ids[c, j])].set_velocity(velocities[c, j], 0.0)
        touches: list[Touch] = []
        for _ in range(self.steps_per_control):
            touches += [self._touch(contact) for contact in self.world.step()]
        return touches

    def _touch(self, contact: Contact) -> Touch:
        c, j = self._by_id[contact.uav_id]
        return Touch(c, j, contact.other_kind)


def _check_spacing(scenario: Scenario, spacing: float) -> None:
    """Copies must never meet: the starts and obstacles (and so the region flown) must fit well inside."""
    points = [u.start for u in scenario.uavs] + [s.position for s in scenario.solids]
    reach = max(float(np.max(np.abs(np.asarray(p)[:2]))) for p in points) if points else 0.0
    if 4.0 * reach + 20.0 > spacing:
        raise FleetError(f"spacing: {spacing:g} m between copies is too small for scenario {scenario.world_name} "
                         f"(its starts and obstacles reach {reach:g} m from the origin); give more than "
                         f"{4.0 * reach + 20.0:g} m")
