"""SimWorld without ROS: UAL manoeuvres in both flight models, contacts, spawn checks, seeds, batteries."""
import numpy as np
import pytest

from magna_sim.ual_logic import UalSettings, UalState
from magna_sim.world import SimWorld, SpawnError


@pytest.fixture
def world():
    sim = SimWorld(physics_rate=240.0, seed=5)
    yield sim
    sim.close()


def run(world, seconds):
    for _ in range(round(seconds / world.dt)):
        world.step()


def run_until(world, condition, seconds):
    contacts = []
    for _ in range(round(seconds / world.dt)):
        contacts += world.step()
        if condition():
            return contacts
    raise AssertionError(f"not reached within {seconds} s of sim time")


def airborne(world, airframe, height, uav_id=1, position=(0.0, 0.0, 0.0), flight_model="light"):
    """Spawn a UAV, take it off and return (vehicle, its UAL logic) once FLYING_AUTO."""
    uav = world.spawn_uav(f"uav_{uav_id}", uav_id, airframe, flight_model, list(position))
    ual = world.ual[uav_id]
    world.step()
    ual.take_off(height)
    run_until(world, lambda: ual.state == UalState.FLYING_AUTO, 10)
    return uav, ual


@pytest.mark.parametrize("flight_model", ["light", "dynamic"])
def test_take_off_go_to_and_land(world, flight_model):
    uav = world.spawn_uav("uav_1", 1, "iris", flight_model, [1.0, -1.0, 0.0])
    ual = world.ual[1]
    run(world, 0.5)
    assert ual.state == UalState.LANDED_ARMED
    ual.take_off(2.0)
    run_until(world, lambda: ual.state == UalState.FLYING_AUTO, 10)
    assert uav.position[2] == pytest.approx(2.0, abs=0.2)
    assert np.linalg.norm(uav.position[:2] - [1.0, -1.0]) < 0.1
    ual.go_to([4.0, 3.0, 2.5], np.pi / 2)
    run_until(world, ual.reached, 20)
    run(world, 3.0)
    assert np.linalg.norm(uav.position - [4.0, 3.0, 2.5]) < 0.1
    assert uav.yaw == pytest.approx(np.pi / 2, abs=0.05)
    ual.land()
    run_until(world, lambda: ual.state == UalState.LANDED_ARMED, 20)
    assert uav.position[2] < 0.05
    assert np.linalg.norm(uav.position[:2] - [4.0, 3.0]) < 0.2


def test_light_velocity_follows_a_first_order_lag(world):
    uav, ual = airborne(world, "iris", 1.0)
    run(world, 2.0)
    ual.set_velocity([1.0, 0.0, 0.0], 0.0)
    tau = uav.airframe.limits.velocity_time_constant
    run(world, tau)
    assert uav.velocity[0] == pytest.approx(1.0 - np.exp(-1.0), abs=0.02)  # 63% after one time constant
    for _ in range(5):  # keep streaming, as a commander does, or the velocity timeout holds position
        ual.set_velocity([1.0, 0.0, 0.0], 0.0)
        run(world, tau)
    assert uav.velocity[0] == pytest.approx(1.0, abs=0.01)
    run(world, 1.5)  # silence: the velocity times out into a hover
    assert abs(uav.velocity[0]) < 0.2 and ual.vehicle.setpoint.mode.name == "POSITION"


def test_speed_limits_cap_a_far_waypoint(world):
    uav, ual = airborne(world, "crazyflie", 1.0)
    ual.go_to([100.0, 0.0, 1.0], 0.0)
    peak = 0.0
    for _ in range(240 * 5):
        world.step()
        peak = max(peak, np.linalg.norm(uav.velocity[:2]))
    assert peak == pytest.approx(uav.airframe.limits.max_horizontal_speed, rel=0.01)


def test_uav_uav_contact_is_reported_once_for_each_uav(world):
    world.spawn_uav("uav_1", 1, "iris", "light", [0, 0, 0])
    world.spawn_uav("uav_2", 2, "iris", "light", [3, 0, 0])
    world.step()
    for uav_id in (1, 2):
        world.ual[uav_id].take_off(2.0)
    run_until(world, lambda: all(world.ual[i].state == UalState.FLYING_AUTO for i in (1, 2)), 10)
    world.ual[1].go_to([3.0, 0.0, 2.0], 0.0)
    contacts = run_until(world, world.ual[1].reached, 20)
    run(world, 1.0)
    pairs = sorted((c.uav_id, c.other_kind, c.other_name) for c in contacts)
    assert pairs == [(1, "uav", "2"), (2, "uav", "1")]
    assert all(c.distance < 0.6 + 1e-6 for c in contacts)  # two radii of 0.3 m


def test_obstacle_contact_and_gentle_landing_is_not_a_collision(world):
    world.spawn_obstacle("pillar", "cylinder", [1.0, 1.0, 4.0], None, [2.0, 0.0, 2.0], [0, 0, 0, 1])
    world.spawn_uav("uav_1", 1, "iris", "light", [0, 0, 0])
    ual = world.ual[1]
    world.step()
    ual.take_off(1.5)
    contacts = run_until(world, lambda: ual.state == UalState.FLYING_AUTO, 10)
    ual.go_to([4.0, 0.0, 1.5], 0.0)
    contacts += run_until(world, ual.reached, 20)
    ual.land()
    contacts += run_until(world, lambda: ual.state == UalState.LANDED_ARMED, 20)
    assert [(c.other_kind, c.other_name) for c in contacts] == [("obstacle", "pillar")]


def test_hitting_the_ground_fast_is_a_collision():
    world = SimWorld(ual_settings=UalSettings(velocity_timeout=0.0))  # the dive must not time out
    _, ual = airborne(world, "iris", 3.0)
    ual.set_velocity([0.0, 0.0, -3.0], 0.0)
    contacts = run_until(world, lambda: world.vehicles[1].position[2] <= 0.0, 10)
    contacts += world.step()
    world.close()
    assert [c.other_kind for c in contacts] == ["ground"]
    assert contacts[0].speed > 1.0


@pytest.mark.parametrize("kwargs, message", [
    (dict(name="uav_1"), "name: 'uav_1' is taken"),
    (dict(uav_id=1), "uav_id: 1 is already flying as 'uav_1'"),
    (dict(airframe="zeppelin"), "airframe: .*no such airframe"),
    (dict(flight_model="rocket"), "flight_model: 'rocket' is not one of light, dynamic"),
    (dict(airframe="plane", flight_model="dynamic"), "flight_model: 'plane' has no rotors"),
    (dict(position=[0, np.nan, 0]), r"pose.position: \[0.0, nan, 0.0\] must be 3 finite"),
    (dict(name="bad name!"), "name: 'bad name!' must be"),
])
def test_spawn_refusals_name_the_field(world, kwargs, message):
    world.spawn_uav("uav_1", 1, "iris", "light", [0, 0, 0])
    request = dict(name="uav_2", uav_id=2, airframe="iris", flight_model="light", position=[2, 0, 0])
    request.update(kwargs)
    with pytest.raises(SpawnError, match=message):
        world.spawn_uav(**request)
    assert sorted(world.vehicles) == [1]
    world.step()  # and the world still runs


def test_obstacle_errors_and_delete(world):
    with pytest.raises(SpawnError, match="dimensions"):
        world.spawn_obstacle("box", "cube", [1.0, -1.0, 1.0], None, [0, 0, 1], [0, 0, 0, 1])
    with pytest.raises(SpawnError, match="pose.orientation: the quaternion is zero"):
        world.spawn_obstacle("box", "cube", [1.0, 1.0, 1.0], None, [0, 0, 1], [0, 0, 0, 0])
    world.spawn_obstacle("box", "cube", [1.0, 1.0, 1.0], None, [0, 0, 1], [0, 0, 0, 1])
    world.spawn_uav("uav_1", 1, "iris", "light", [3, 0, 0])
    assert world.names() == ["box", "uav_1"]
    assert world.delete("box") == "obstacle" and world.delete("uav_1") == "uav"
    assert world.names() == [] and world.vehicles == {} and world.ual == {}
    with pytest.raises(SpawnError, match="name: no model called 'box'"):
        world.delete("box")
    world.step()


def _gusty_flight(seed):
    sim = SimWorld(seed=seed, wind_std=2.0)
    try:
        sim.spawn_uav("uav_1", 1, "iris", "dynamic", [0, 0, 0])
        sim.step()
        sim.ual[1].take_off(2.0)
        run(sim, 4.0)
        return sim.vehicles[1].position.copy()
    finally:
        sim.close()


def test_a_seed_makes_wind_reproducible():
    first, again, other = _gusty_flight(11), _gusty_flight(11), _gusty_flight(12)
    assert first.tolist() == again.tolist()
    assert first.tolist() != other.tolist()


def test_an_empty_battery_makes_the_uav_land(world):
    _, ual = airborne(world, "iris", 2.0)
    world.drain_batteries(0.5 * 3600)  # half an hour at hover: more than an iris battery holds
    assert world.batteries[1].depleted
    assert ual.state == UalState.LANDING
    run_until(world, lambda: ual.state == UalState.LANDED_ARMED, 20)


@pytest.mark.parametrize(("airframe", "flight_model"), [("iris", "light"), ("iris", "dynamic"),
                                                         ("crazyflie", "dynamic"), ("f550", "light")])
def test_take_off_and_waypoint_end_within_the_arrival_radius(world, airframe, flight_model):
    uav, ual = airborne(world, airframe, 2.0, flight_model=flight_model)
    radius = ual.arrival_radius
    assert radius <= uav.airframe.accepted_target_radius and radius <= 0.33 / 2
    assert np.linalg.norm(uav.position - [0.0, 0.0, 2.0]) <= radius
    ual.go_to([3.0, 0.0, 2.0], 0.0)
    run_until(world, ual.reached, 20)
    assert np.linalg.norm(uav.position - [3.0, 0.0, 2.0]) <= radius


def test_a_wall_in_the_way_of_a_dynamic_uav_makes_its_waypoint_stuck(world):
    uav, ual = airborne(world, "iris", 2.0, flight_model="dynamic")
    world.spawn_obstacle("wall", "cube", [0.4, 6.0, 6.0], None, [3.0, 0.0, 3.0], [0.0, 0.0, 0.0, 1.0])
    ual.go_to([6.0, 0.0, 2.0], 0.0)
    run_until(world, lambda: ual.stuck is not None, 30)
    assert not ual.reached()
    assert uav.position[0] < 2.8  # pressed against the wall's near face
    assert "has come no nearer in 10 s of simulated time" in ual.stuck


def _crossing_with_wind(sim):
    """A dynamic UAV in gusts and a light one fly past a pillar, sensors read with noise: everything per step."""
    sim.spawn_obstacle("pillar", "cylinder", [1.0, 1.0, 4.0], None, [3.0, 0.0, 2.0], [0, 0, 0, 1])
    sim.spawn_uav("uav_1", 1, "iris", "dynamic", [0.0, -0.5, 0.0])
    sim.spawn_uav("uav_2", 2, "iris", "light", [0.0, 1.5, 0.0])
    sim.step()
    for uav_id in (1, 2):
        sim.ual[uav_id].take_off(2.0)
    trace, crossing = [], False
    for step in range(round(6.0 / sim.dt)):
        if not crossing and all(sim.ual[i].state == UalState.FLYING_AUTO for i in (1, 2)):
            crossing = True
            sim.ual[1].go_to([6.0, -0.5, 2.0], 0.0)
            sim.ual[2].go_to([6.0, 1.5, 2.0], 0.5)
        contacts = sim.step()
        if step % 8 == 0:
            sim.drain_batteries(8 * sim.dt)
            readings = sim.sensor_readings([1, 2], 0.05, 0.02)
            trace.append([value.tolist() for pair in readings.values() for value in pair])
        trace.append([(c.uav_id, c.other_kind, c.other_name, c.position.tolist()) for c in contacts])
        trace.append([v.position.tolist() + v.velocity.tolist() + v.orientation.tolist()
                      for v in sim.vehicles.values()])
    trace.append([(b.percentage, int(sim.ual[i].state)) for i, b in sim.batteries.items()])
    assert crossing, "the UAVs never took off"
    return trace


def test_a_renewed_world_flies_exactly_as_a_cold_one_with_its_seed():
    cold = SimWorld(seed=21, wind_std=1.5)
    try:
        expected = _crossing_with_wind(cold)
    finally:
        cold.close()
    used = SimWorld(seed=4, wind_std=1.5)
    try:
        before = _crossing_with_wind(used)  # UAVs, an obstacle, contacts and rng draws to leave behind
        renewed = used.renewed(21)
    finally:
        used.close()
    try:
        assert renewed.time == 0.0 and renewed.names() == [] and renewed.wind_std == 1.5
        flown = _crossing_with_wind(renewed)
    finally:
        renewed.close()
    assert flown == expected  # bit for bit: body ids, gusts, noise, contacts, batteries
    assert before != expected  # another seed flies otherwise: the comparison can tell


def test_sensor_readings_draw_position_then_velocity_noise_uav_by_uav():
    sim = SimWorld(seed=8)
    try:
        for uav_id, y in ((3, 0.0), (1, 2.0)):
            sim.spawn_uav(f"uav_{uav_id}", uav_id, "iris", "light", [1.0, y, 0.0])
        readings = sim.sensor_readings([3, 1], 0.1, 0.2)
        same_seed = np.random.default_rng(8)  # the order a seeded run has always drawn its noise in
        for uav_id in (3, 1):
            vehicle = sim.vehicles[uav_id]
            position, velocity = readings[uav_id]
            assert position.tolist() == (vehicle.position + same_seed.normal(0.0, 0.1, 3)).tolist()
            assert velocity.tolist() == (vehicle.velocity + same_seed.normal(0.0, 0.2, 3)).tolist()
        assert list(readings) == [3, 1]
        exact = sim.sensor_readings([1], 0.0, 0.0)[1]  # no noise: the true state, and no draw
        assert exact[0] is sim.vehicles[1].position and exact[1] is sim.vehicles[1].velocity
        assert sim.rng.bit_generator.state == same_seed.bit_generator.state
    finally:
        sim.close()


def test_a_light_uav_placed_in_the_air_holds_there_then_flies_as_one_that_took_off(world):
    flown, flown_ual = airborne(world, "iris", 3.0, uav_id=1, position=(0.0, 0.0, 0.0))
    placed = world.spawn_uav("uav_2", 2, "iris", "light", [10.0, 0.0, 0.0])
    world.step()
    world.place_airborne(2, flown.position + [10.0, 0.0, 0.0], flown.yaw)
    assert world.ual[2].state == UalState.FLYING_AUTO and not placed.velocity.any()
    run(world, 2.0)  # both hold: the placed one stays where it was put
    np.testing.assert_allclose(placed.position - flown.position, [10.0, 0.0, 0.0], atol=0.05)
    for ual in (flown_ual, world.ual[2]):
        ual.set_velocity([1.0, 0.5, 0.0], 0.0)
    run(world, 1.0)  # the same commands from rest: the same motion
    np.testing.assert_allclose(placed.velocity, flown.velocity, atol=0.02)
    np.testing.assert_allclose(placed.position - flown.position, [10.0, 0.0, 0.0], atol=0.05)


def test_placing_is_refused_for_an_unknown_uav_and_the_dynamic_model(world):
    world.spawn_uav("uav_1", 1, "iris", "dynamic", [0.0, 0.0, 0.0])
    with pytest.raises(SpawnError, match="uav_id: 7 is not flying here"):
        world.place_airborne(7, [0.0, 0.0, 3.0])
    with pytest.raises(SpawnError, match="only a light UAV can be placed"):
        world.place_airborne(1, [0.0, 0.0, 3.0])
