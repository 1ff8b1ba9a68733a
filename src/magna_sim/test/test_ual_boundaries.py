"""A position target beyond the world's boundaries is refused by the simulated UAL, with the reason, and changes
nothing (issue 26, item 6); before a world is there (no boundaries), targets are not limited."""
import numpy as np
import pytest

from magna_common.airframes import load_airframe
from magna_sim.ual_logic import CommandRefused, UalLogic, UalSettings, UalState
from magna_sim.vehicle import Vehicle

BOX = np.array([[-10.0, 10.0], [-10.0, 10.0], [0.0, 8.0]])


def ual(state=UalState.FLYING_AUTO, boundaries=BOX):
    logic = UalLogic(Vehicle("uav_1", 1, load_airframe("iris"), "light", position=np.array([0.0, 0.0, 2.0])),
                     UalSettings())
    logic.update(0.0)
    logic.state, logic.boundaries = state, boundaries
    return logic


@pytest.mark.parametrize("command", [
    lambda logic: logic.go_to([1e6, 0.0, 3.0], 0.0),
    lambda logic: logic.go_to([0.0, 0.0, -0.5], 0.0),
    lambda logic: logic.set_pose([0.0, 10.5, 3.0], 0.0),
    lambda logic: logic.set_pose([1e308, -1e308, 3.0], 0.0),
])
def test_targets_outside_the_world_are_refused_and_change_nothing(command):
    logic = ual()
    before, command_id = logic.vehicle.setpoint, logic.command_id
    with pytest.raises(CommandRefused, match=r"outside the world's boundaries \(x -10..10, y -10..10, z 0..8 m\)"):
        command(logic)
    assert logic.vehicle.setpoint is before and logic.command_id == command_id
    assert logic.state == UalState.FLYING_AUTO


def test_a_take_off_above_the_ceiling_is_refused():
    logic = ual(UalState.LANDED_ARMED)
    with pytest.raises(CommandRefused, match=r"take_off to 7 m refused: the target \(0, 0, 9\) is outside"):
        logic.take_off(7.0)
    assert logic.state == UalState.LANDED_ARMED
    logic.take_off(5.0)
    assert logic.state == UalState.TAKING_OFF


def test_targets_inside_or_without_a_world_are_flown():
    ual().go_to([10.0, -10.0, 8.0], 0.0)  # on the boundary counts as inside
    ual(boundaries=None).go_to([1e6, 0.0, 3.0], 0.0)
