"""Battery drain and voltage, with the iris airframe's battery block."""
import math

import pytest

from magna_common.airframes import Battery, load_airframe
from magna_sim.battery import SPEED_POWER_FACTOR, BatteryModel

IRIS = load_airframe("iris").battery


def seconds_until_depleted(battery, flying=True, speed=0.0, dt=1.0, limit=10**6):
    t = 0.0
    while not battery.depleted and t < limit:
        battery.update(dt, flying, speed)
        t += dt
    return t


def test_full_battery_at_rest():
    battery = BatteryModel(IRIS)
    assert battery.percentage == 1.0
    assert battery.capacity_ah == battery.charge_ah == pytest.approx(IRIS.capacity_mah / 1000.0)
    assert battery.voltage == pytest.approx(12.6)  # 3 cells of 4.2 V for an 11.1 V pack
    assert battery.current == 0.0 and not battery.depleted


def test_hover_lasts_about_capacity_times_voltage_over_power():
    expected = IRIS.capacity_mah / 1000.0 * IRIS.voltage / IRIS.hover_power_w * 3600.0  # ~1132 s for the iris
    assert seconds_until_depleted(BatteryModel(IRIS)) == pytest.approx(expected, rel=0.10)


def test_hover_current_is_power_over_voltage():
    battery = BatteryModel(IRIS)
    battery.update(0.1, flying=True)
    assert battery.power == IRIS.hover_power_w
    assert battery.current == pytest.approx(IRIS.hover_power_w / 12.6)
    assert battery.charge_ah == pytest.approx(battery.capacity_ah - battery.current * 0.1 / 3600.0)


def test_landed_drains_far_slower():
    landed, flying = BatteryModel(IRIS), BatteryModel(IRIS)
    for _ in range(600):
        landed.update(1.0, flying=False)
        flying.update(1.0, flying=True)
    assert landed.power == IRIS.idle_power_w
    used_landed, used_flying = 1.0 - landed.percentage, 1.0 - flying.percentage
    assert used_landed > 0.0
    assert used_flying > 20 * used_landed


def test_faster_flight_drains_faster():
    used = []
    for speed in (0.0, 2.0, 5.0, 10.0):
        battery = BatteryModel(IRIS)
        battery.update(60.0, flying=True, speed=speed)
        used.append(1.0 - battery.percentage)
    assert used == sorted(used) and len(set(used)) == 4
    assert used[3] / used[0] == pytest.approx(1.0 + SPEED_POWER_FACTOR * 100.0)
    # Speed means nothing on the ground.
    a, b = BatteryModel(IRIS), BatteryModel(IRIS)
    a.update(60.0, flying=False, speed=0.0)
    b.update(60.0, flying=False, speed=10.0)
    assert a.percentage == b.percentage


def test_percentage_never_below_zero_and_voltage_falls_to_empty():
    battery = BatteryModel(IRIS, capacity_fraction=0.01)
    voltages = []
    for _ in range(100):
        battery.update(5.0, flying=True, speed=10.0)
        voltages.append(battery.voltage)
        assert 0.0 <= battery.percentage <= 1.0
    assert battery.depleted and battery.percentage == 0.0 and battery.charge_ah == 0.0
    assert battery.current == 0.0 and battery.power == 0.0
    assert voltages == sorted(voltages, reverse=True)
    assert battery.voltage == pytest.approx(3 * 3.3)


def test_voltage_follows_the_lipo_curve():
    assert BatteryModel(IRIS, capacity_fraction=0.5).voltage == pytest.approx(3 * 3.84)
    assert BatteryModel(IRIS, capacity_fraction=0.0).voltage == pytest.approx(3 * 3.3)
    one_cell = Battery(capacity_mah=250, voltage=3.7, hover_power_w=8.0, idle_power_w=0.3)
    assert BatteryModel(one_cell).voltage == pytest.approx(4.2)
    curve = [BatteryModel(IRIS, capacity_fraction=f / 20).voltage for f in range(21)]
    assert all(b > a for a, b in zip(curve, curve[1:], strict=False))


def test_a_test_mission_can_run_low_quickly():
    battery = BatteryModel(IRIS, capacity_fraction=0.3, drain_factor=100.0)
    assert battery.percentage == pytest.approx(0.3)
    t = 0.0
    while battery.percentage > 0.2:
        battery.update(0.1, flying=True)
        t += 0.1
    assert t < 10.0
    normal = BatteryModel(IRIS, capacity_fraction=0.3)
    normal.update(1.0, flying=True)
    fast = BatteryModel(IRIS, capacity_fraction=0.3, drain_factor=100.0)
    fast.update(1.0, flying=True)
    assert (0.3 - fast.percentage) == pytest.approx(100.0 * (0.3 - normal.percentage))


@pytest.mark.parametrize("kwargs", [{"capacity_fraction": 1.5}, {"capacity_fraction": -0.1},
                                    {"drain_factor": 0.0}, {"drain_factor": math.nan}])
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        BatteryModel(IRIS, **kwargs)


@pytest.mark.parametrize("dt, speed, field", [(-1.0, 0.0, "dt"), (math.nan, 0.0, "dt"), (0.1, math.inf, "speed")])
def test_bad_update_is_refused(dt, speed, field):
    battery = BatteryModel(IRIS)
    with pytest.raises(ValueError, match=field):
        battery.update(dt, True, speed)
    assert battery.percentage == 1.0


def test_a_floor_keeps_the_charge_as_px4_sitls_battery_does():
    battery = BatteryModel(IRIS, floor_fraction=0.5)
    for _ in range(3600):  # an hour of hover: a real iris runs empty long before
        battery.update(1.0, flying=True)
    assert battery.percentage == pytest.approx(0.5) and not battery.depleted
    assert BatteryModel(IRIS).percentage == 1.0
    started_low = BatteryModel(IRIS, capacity_fraction=0.3, floor_fraction=0.5)
    started_low.update(60.0, flying=True)
    assert started_low.percentage == pytest.approx(0.3)  # below its floor from the start: it stays there
    with pytest.raises(ValueError, match="floor_fraction"):
        BatteryModel(IRIS, floor_fraction=1.0)
