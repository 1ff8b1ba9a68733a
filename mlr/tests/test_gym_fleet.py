"""mlr.gym.fleet: copies of a scenario in one magna_sim world, each in its own frame."""
from __future__ import annotations

import numpy as np
import pytest

from mlr.gym.fleet import Fleet, FleetError
from mlr.gym.scenario import load_scenario
from tests.support import CORPUS


@pytest.fixture(scope="module")
def central():
    return load_scenario("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [CORPUS])


@pytest.fixture
def fleet(central):
    made = Fleet(central, copies=3)
    yield made
    made.close()


def test_each_copy_flies_its_own_commands_in_the_scenarios_frame(fleet):
    starts = np.array([[-2.5, 0.0, 3.0], [2.5, 0.0, 3.0]])
    for c in range(3):
        fleet.place(c, starts)
    np.testing.assert_allclose(fleet.positions(), np.broadcast_to(starts, (3, 2, 3)), atol=1e-9)
    commands = np.zeros((3, 2, 3))
    commands[1, 0] = [0.0, 1.0, 0.0]  # copy 1's first UAV flies +y; everything else holds
    for _ in range(20):  # 2 s
        assert fleet.control_step(commands) == []
    moved = fleet.positions() - starts
    assert moved[1, 0, 1] > 1.5 and np.allclose(moved[1, 0, [0, 2]], 0.0, atol=0.02)
    others = np.ones((3, 2), dtype=bool)
    others[1, 0] = False
    assert np.abs(moved[others]).max() < 0.02
    np.testing.assert_allclose(fleet.velocities()[1, 0], [0.0, 1.0, 0.0], atol=0.05)


def test_a_touch_names_the_copy_the_uav_and_what_it_hit(fleet, central):
    sphere = central.solids[0]
    starts = np.array([sphere.position - [1.5, 0.0, 0.0], [5.0, 5.0, 3.0]])
    for c in range(3):
        fleet.place(c, starts)
    commands = np.zeros((3, 2, 3))
    commands[2, 0] = [1.0, 0.0, 0.0]  # copy 2's first UAV flies into the sphere
    touches = [t for _ in range(30) for t in fleet.control_step(commands)]
    assert [(t.copy, t.uav, t.other_kind) for t in touches] == [(2, 0, "obstacle")]


def test_bad_settings_are_refused_naming_them(central):
    with pytest.raises(FleetError, match="copies: 0"):
        Fleet(central, copies=0)
    with pytest.raises(FleetError, match="control_rate: 7"):
        Fleet(central, control_rate=7.0)
    with pytest.raises(FleetError, match="spacing: 10 m"):
        Fleet(central, copies=2, spacing=10.0)
