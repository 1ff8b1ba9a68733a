"""The UAL state machine and command checks, without physics: the vehicle is moved by hand."""
import math

import numpy as np
import pytest

from magna_common.airframes import load_airframe
from magna_sim.ual_logic import CommandRefused, UalLogic, UalSettings, UalState
from magna_sim.vehicle import SetpointMode, Vehicle


@pytest.fixture
def logic():
    vehicle = Vehicle("uav_1", 1, load_airframe("iris"), "light", position=np.array([1.0, 2.0, 0.0]))
    ual = UalLogic(vehicle, UalSettings(velocity_timeout=1.0))
    ual.update(0.0)
    return ual


def test_starts_uninitialized_then_landed_armed():
    vehicle = Vehicle("uav_1", 1, load_airframe("iris"), "light")
    ual = UalLogic(vehicle)
    assert ual.state == UalState.UNINITIALIZED
    ual.update(0.01)
    assert ual.state == UalState.LANDED_ARMED


def test_full_cycle_take_off_fly_land(logic):
    vehicle = logic.vehicle
    logic.take_off(3.0)
    assert logic.state == UalState.TAKING_OFF
    assert vehicle.setpoint.mode == SetpointMode.POSITION
    assert vehicle.setpoint.position.tolist() == [1.0, 2.0, 3.0]
    vehicle.position = np.array([1.0, 2.0, 1.5])
    logic.update(1.0)
    assert logic.state == UalState.TAKING_OFF
    vehicle.position = np.array([1.0, 2.0, 2.95])
    logic.update(2.0)
    assert logic.state == UalState.TAKING_OFF  # there, but not yet for hold_time
    logic.update(3.0)
    assert logic.state == UalState.FLYING_AUTO
    logic.go_to([4.0, 5.0, 6.0], 0.0)
    assert not logic.reached()
    vehicle.position = np.array([4.0, 5.1, 6.0])
    logic.update(3.5)
    assert not logic.reached()
    logic.update(4.5)
    assert logic.reached()
    logic.land()
    assert logic.state == UalState.LANDING
    vehicle.position, vehicle.velocity = np.array([4.0, 5.1, 0.01]), np.zeros(3)
    logic.update(3.0)
    assert logic.state == UalState.LANDED_ARMED
    assert vehicle.setpoint.mode == SetpointMode.OFF


@pytest.mark.parametrize("command", [
    lambda ual: ual.land(),
    lambda ual: ual.go_to([0, 0, 1], 0.0),
    lambda ual: ual.set_pose([0, 0, 1], 0.0),
    lambda ual: ual.set_velocity([0, 0, 1], 0.0),
    lambda ual: ual.recover_from_manual(),
])
def test_commands_that_need_flight_are_refused_on_the_ground(logic, command):
    with pytest.raises(CommandRefused, match="UAV 1 is LANDED_ARMED"):
        command(logic)
    assert logic.vehicle.setpoint.mode == SetpointMode.OFF
    assert logic.command_id == 0


def test_take_off_while_flying_is_refused(logic):
    logic.take_off(2.0)
    with pytest.raises(CommandRefused, match="take_off refused: UAV 1 is TAKING_OFF; take_off needs LANDED_ARMED"):
        logic.take_off(2.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -1.0, 0.0])
def test_bad_take_off_heights(logic, bad):
    with pytest.raises(CommandRefused, match="height"):
        logic.take_off(bad)
    assert logic.state == UalState.LANDED_ARMED


def test_non_finite_setpoints_are_refused_and_change_nothing(logic):
    logic.state = UalState.FLYING_AUTO
    logic.go_to([1, 1, 1], 0.0)
    before = logic.vehicle.setpoint
    for command in (lambda: logic.set_pose([math.nan, 0, 1], 0.0), lambda: logic.set_pose([0, 0, 1], math.inf),
                    lambda: logic.set_velocity([0, math.inf, 0], 0.0), lambda: logic.go_to([0, 0], 0.0)):
        with pytest.raises(CommandRefused, match="finite"):
            command()
    assert logic.vehicle.setpoint is before


def test_velocity_commands_time_out_into_a_hover(logic):
    logic.state = UalState.FLYING_AUTO
    logic.update(10.0)
    logic.set_velocity([1.0, 0.0, 0.0], 0.1)
    logic.update(10.5)
    assert logic.vehicle.setpoint.mode == SetpointMode.VELOCITY
    logic.vehicle.position = np.array([3.0, 2.0, 2.0])
    logic.update(11.2)
    assert logic.vehicle.setpoint.mode == SetpointMode.POSITION
    assert logic.vehicle.setpoint.position.tolist() == [3.0, 2.0, 2.0]


def test_set_home_keeps_z_unless_asked(logic):
    logic.vehicle.position = np.array([5.0, 6.0, 7.0])
    logic.set_home(False)
    assert logic.home.tolist() == [5.0, 6.0, 0.0]
    logic.set_home(True)
    assert logic.home.tolist() == [5.0, 6.0, 7.0]


def test_failsafe_land_overrides_what_was_commanded(logic):
    logic.take_off(2.0)
    logic.failsafe_land()
    assert logic.state == UalState.LANDING


def flying(airframe="iris", **settings):
    vehicle = Vehicle("uav_1", 1, load_airframe(airframe), "light", position=np.array([0.0, 0.0, 2.0]))
    ual = UalLogic(vehicle, UalSettings(**settings))
    ual.update(0.0)
    ual.state = UalState.FLYING_AUTO
    return ual


def test_arrival_radius_is_half_of_position_th_and_never_beyond_the_accepted_target_radius():
    assert flying("iris").arrival_radius == pytest.approx(0.165)  # iris accepts 0.9 m: UAL's 0.33 / 2 rules
    assert flying("iris", position_th=4.0).arrival_radius == pytest.approx(0.9)  # capped by iris's 0.9 m
    assert flying("crazyflie").arrival_radius == pytest.approx(load_airframe("crazyflie").accepted_target_radius)


def test_a_waypoint_counts_only_after_holding_within_the_radius_and_heading():
    ual = flying(hold_time=1.0)
    ual.go_to([3.0, 0.0, 2.0], math.pi / 2)
    vehicle = ual.vehicle
    vehicle.position = np.array([2.75, -0.17, 2.0])  # 0.30 m off: UAL's old 0.33 m said "arrived" here
    for t in (1.0, 2.0, 3.0):
        ual.update(t)
    assert not ual.reached()
    vehicle.position = np.array([2.9, 0.0, 2.0])  # within 0.165 m, but still facing east
    ual.update(4.0)
    ual.update(5.5)
    assert not ual.reached()
    vehicle.orientation = np.array([0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)])
    ual.update(6.0)
    vehicle.position = np.array([3.5, 0.0, 2.0])  # blown out again: the hold starts over
    ual.update(6.5)
    vehicle.position = np.array([3.05, 0.0, 2.0])
    ual.update(7.0)
    ual.update(7.9)
    assert not ual.reached()
    ual.update(8.0)
    assert ual.reached() and ual.stuck is None


def test_a_target_that_comes_no_nearer_is_given_up_with_the_reason():
    ual = flying(stuck_time=10.0)
    ual.go_to([3.0, 0.0, -1.0], 0.0)
    vehicle = ual.vehicle
    for t, x in ((0.0, 0.0), (2.0, 1.5), (4.0, 3.0)):
        vehicle.position = np.array([x, 0.0, 0.0])  # down on the ground, under the target
        ual.update(t)
    for t in (8.0, 13.9):
        ual.update(t)
        assert ual.stuck is None
    ual.update(14.1)
    assert not ual.reached()
    assert ual.stuck.startswith("UAV 1 is at (3.00, 0.00, 0.00), 1.00 m from (3.00, 0.00, -1.00), "
                                "and has come no nearer in 10 s of simulated time")
    ual.go_to([3.0, 0.0, 2.0], 0.0)  # a new command starts afresh
    assert ual.stuck is None


def test_stuck_time_zero_waits_for_ever():
    ual = flying(stuck_time=0.0)
    ual.go_to([3.0, 0.0, -1.0], 0.0)
    for t in (0.0, 100.0, 1000.0):
        ual.update(t)
    assert ual.stuck is None and not ual.reached()


def test_start_airborne_holds_where_the_vehicle_is_and_a_plane_may_not():
    vehicle = Vehicle("uav_1", 1, load_airframe("iris"), "light", position=np.array([1.0, 2.0, 3.0]))
    ual = UalLogic(vehicle)
    ual.start_airborne()
    assert ual.state == UalState.FLYING_AUTO
    assert vehicle.setpoint.mode == SetpointMode.POSITION
    np.testing.assert_array_equal(vehicle.setpoint.position, [1.0, 2.0, 3.0])
    ual.set_velocity([1.0, 0.0, 0.0], 0.0)  # accepted, as from any UAV flying auto
    plane = UalLogic(Vehicle("uav_2", 2, load_airframe("plane"), "fixed_wing", position=np.array([0.0, 0.0, 50.0])))
    with pytest.raises(CommandRefused, match="fixed wing"):
        plane.start_airborne()
    assert plane.state == UalState.UNINITIALIZED
