"""A position target far beyond the world's boundaries is refused by the simulated UAL, with the reason, and changes
nothing (issue 26, item 6); one just outside is flown with a warning, as the original's UAL flew it; before a world
is there (no boundaries), targets are not limited."""
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
    lambda logic: logic.go_to([0.0, 0.0, -20.5], 0.0),
    lambda logic: logic.set_pose([0.0, 30.5, 3.0], 0.0),
    lambda logic: logic.set_pose([1e308, -1e308, 3.0], 0.0),
])
def test_targets_far_outside_the_world_are_refused_and_change_nothing(command):
    logic = ual()
    before, command_id = logic.vehicle.setpoint, logic.command_id
    with pytest.raises(CommandRefused, match=r"m outside the world's boundaries \(x -10..10, y -10..10, z 0..8 m\), "
                                             r"more than the world's size \(20 m\)"):
        command(logic)
    assert logic.vehicle.setpoint is before and logic.command_id == command_id
    assert logic.state == UalState.FLYING_AUTO


def test_a_target_just_outside_the_world_is_flown_with_a_warning():
    logic, warnings = ual(), []
    logic.on_warning = warnings.append
    logic.set_pose([0.0, 10.5, 3.0], 0.0)
    assert np.allclose(logic.vehicle.setpoint.position, [0.0, 10.5, 3.0])
    assert warnings == ["set_pose: the target (0, 10.5, 3) is 0.5 m outside the world's boundaries "
                        "(x -10..10, y -10..10, z 0..8 m); flown all the same"]


def test_a_take_off_far_above_the_ceiling_is_refused():
    logic = ual(UalState.LANDED_ARMED)
    with pytest.raises(CommandRefused, match=r"take_off to 27 m refused: the target \(0, 0, 29\) is 21 m outside"):
        logic.take_off(27.0)
    assert logic.state == UalState.LANDED_ARMED
    logic.take_off(7.0)  # 1 m above the ceiling: flown
    assert logic.state == UalState.TAKING_OFF


def test_targets_inside_or_without_a_world_are_flown():
    ual().go_to([10.0, -10.0, 8.0], 0.0)  # on the boundary counts as inside
    ual(boundaries=None).go_to([1e6, 0.0, 3.0], 0.0)
