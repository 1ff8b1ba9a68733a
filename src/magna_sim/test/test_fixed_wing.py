"""The fixed-wing flight model without ROS: a plane cannot hover, turns no tighter than its bank allows,
never flies below stall, circles what it holds, climbs out to take off, glides down to land, and its
battery lasts as a small electric plane's does."""
import math

import numpy as np
import pytest

from magna_common.airframes import GRAVITY, load_airframe
from magna_sim import fixed_wing
from magna_sim.ual_logic import UalState
from magna_sim.world import SimWorld, SpawnError

PLANE = load_airframe("plane")
FW = PLANE.fixed_wing


class Flight:
    """A world with one plane; every step is logged while the plane is airborne."""

    def __init__(self, start=(0.0, 0.0, 0.0)):
        self.world = SimWorld(physics_rate=240.0, seed=3)
        self.uav = self.world.spawn_uav("uav_1", 1, "plane", "light", list(start))
        self.ual = self.world.ual[1]
        self.model = self.world.models["fixed_wing"]
        self.contacts = []
        self.log = []  # (position, velocity, turn rate, airborne, state) per step
        self.world.step()

    def step(self):
        self.contacts += self.world.step()
        self.world.drain_batteries(self.world.dt)
        plane = self.model.state(self.uav)
        self.log.append((self.uav.position.copy(), self.uav.velocity.copy(), plane.turn_rate,
                         self.uav.position[2] > 0.05, self.ual.state))

    def run(self, seconds):
        for _ in range(round(seconds / self.world.dt)):
            self.step()

    def run_until(self, condition, seconds):
        for _ in range(round(seconds / self.world.dt)):
            self.step()
            if condition():
                return
        raise AssertionError(f"not reached within {seconds} s of sim time; at {self.uav.position}")

    def take_off(self, height):
        self.ual.take_off(height)
        self.run_until(lambda: self.ual.state == UalState.FLYING_AUTO, 60)

    def airborne_speeds(self, since=0):
        return np.array([np.linalg.norm(v) for _, v, _, up, _ in self.log[since:] if up])

    def close(self):
        self.world.close()


@pytest.fixture
def flight():
    f = Flight()
    yield f
    f.close()


def test_a_plane_flies_the_fixed_wing_model_whatever_the_spawner_asks():
    world = SimWorld()
    try:
        assert world.spawn_uav("uav_1", 1, "plane", "light", [0, 0, 0]).flight_model == "fixed_wing"
        assert world.spawn_uav("uav_2", 2, "plane", "fixed_wing", [0, 5, 0]).flight_model == "fixed_wing"
        with pytest.raises(SpawnError, match="'plane' has no rotors.*fixed_wing"):
            world.spawn_uav("uav_3", 3, "plane", "dynamic", [0, 10, 0])
        with pytest.raises(SpawnError, match="'iris' is a multirotor.*body.rotors = 4"):
            world.spawn_uav("uav_3", 3, "iris", "fixed_wing", [0, 10, 0])
    finally:
        world.close()


def test_take_off_is_a_climb_out_along_the_heading(flight):
    flight.ual.take_off(10.0)
    assert flight.ual.state == UalState.TAKING_OFF
    flight.run_until(lambda: flight.ual.state == UalState.FLYING_AUTO, 60)
    position = flight.uav.position
    assert position[2] == pytest.approx(10.0, abs=0.2)
    # straight ahead along +x (the spawn heading), a climb of at most max_climb_rate at cruise speed
    assert abs(position[1]) < 1.0
    assert position[0] > 10.0 / FW.max_climb_rate * FW.min_speed * 0.9
    assert flight.airborne_speeds().min() >= FW.min_speed - 1e-6
    assert flight.contacts == []  # leaving the ground at speed is no crash


def test_it_cannot_hover_a_hold_is_a_loiter_circle(flight):
    flight.take_off(20.0)
    flight.ual.set_velocity([0.0, 0.0, 0.0], 0.0)  # a stop... and then silence: the UAL holds "here"
    held = flight.uav.position.copy()
    flight.run(1.5)
    assert flight.uav.setpoint.mode.name == "POSITION"
    centre = flight.uav.setpoint.position
    start = len(flight.log)
    flight.run(60.0)
    tail = flight.log[start + 240 * 20:]  # once it joined the circle
    radii = [np.linalg.norm(p[:2] - centre[:2]) for p, *_ in tail]
    assert min(radii) == pytest.approx(FW.loiter_radius, abs=1.0)
    assert max(radii) == pytest.approx(FW.loiter_radius, abs=1.0)
    assert all(abs(p[2] - centre[2]) < 0.5 for p, *_ in tail)
    turns = np.array([w for *_, w, _, _ in tail])
    assert (turns < 0).all(), "a loiter goes clockwise, as PX4's does"
    assert flight.airborne_speeds(start).min() >= FW.min_speed - 1e-6
    assert np.linalg.norm(held[:2] - centre[:2]) < 20.0  # it circles where it was told to stop


def test_turns_are_never_tighter_than_the_bank_angle_allows(flight):
    flight.take_off(15.0)
    start = len(flight.log)
    flight.ual.go_to([-30.0, 10.0, 15.0], 0.0)  # behind it and off to the side: a hard turn
    flight.run_until(flight.ual.reached, 120)
    flight.run(20.0)
    positions = np.array([p for p, *_ in flight.log[start:]])
    speeds = flight.airborne_speeds(start)
    turns = np.array([w for *_, w, _, _ in flight.log[start:]])
    horizontal = np.linalg.norm(np.array([v[:2] for _, v, *_ in flight.log[start:]]), axis=1)
    # the state: turn rate within g tan(bank) / speed, i.e. radius >= speed^2 / (g tan(bank))
    assert np.all(np.abs(turns) * horizontal <= GRAVITY * math.tan(FW.max_bank_angle) + 1e-6)
    assert np.abs(turns).max() > 0.9 * GRAVITY * math.tan(FW.max_bank_angle) / horizontal.max()  # it did bank hard
    # the path itself: the radius through three points 0.5 s apart
    a, b, c = positions[:-240:120, :2], positions[120:-120:120, :2], positions[240::120, :2]
    ab, bc, ca = (np.linalg.norm(x - y, axis=1) for x, y in ((a, b), (b, c), (c, a)))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    radius = ab * bc * ca / np.maximum(2.0 * cross, 1e-9)
    tightest = FW.min_turn_radius(FW.min_speed)
    assert radius.min() >= 0.97 * tightest, f"a {radius.min():.1f} m turn; the tightest at min_speed is {tightest:.1f}"
    assert speeds.min() >= FW.min_speed - 1e-6 > FW.stall_speed


def test_a_waypoint_is_reached_on_its_loiter_circle_and_the_accepted_radius_covers_it(flight):
    flight.take_off(10.0)
    target = np.array([250.0, 150.0, 30.0])
    flight.ual.go_to(target, 0.0)
    assert not flight.ual.reached()
    flight.run_until(flight.ual.reached, 120)
    flight.run(40.0)
    distance = np.linalg.norm(flight.uav.position - target)
    assert distance == pytest.approx(FW.loiter_radius, abs=1.5)
    assert distance < PLANE.accepted_target_radius  # a path role sees it arrive
    assert flight.ual.reached()


def test_a_waypoint_at_ground_level_is_circled_at_min_flight_height(flight):
    flight.take_off(10.0)
    flight.ual.go_to([60.0, -60.0, 0.0], 0.0)
    flight.run_until(flight.ual.reached, 120)
    flight.run(30.0)
    assert flight.uav.position[2] == pytest.approx(FW.min_flight_height, abs=0.1)
    assert flight.contacts == []


def test_velocity_commands_are_tracked_within_the_airspeed_and_turn_limits(flight):
    flight.take_off(20.0)

    def stream(velocity, seconds):
        for _ in range(round(seconds / 0.1)):
            flight.ual.set_velocity(velocity, 0.3)
            flight.run(0.1)

    stream([0.0, 2.0, 0.0], 15.0)  # slow, to the north: it turns there, at min_speed
    assert flight.uav.velocity[:2] / np.linalg.norm(flight.uav.velocity[:2]) == pytest.approx([0, 1], abs=0.02)
    assert np.linalg.norm(flight.uav.velocity) == pytest.approx(FW.min_speed, abs=0.05)
    stream([40.0, 0.0, 0.0], 15.0)  # too fast, to the east: max_speed
    assert flight.uav.velocity[0] == pytest.approx(FW.max_speed, abs=0.1)
    stream([15.0, 0.0, 10.0], 3.0)  # a steep climb: max_climb_rate
    assert flight.uav.velocity[2] == pytest.approx(FW.max_climb_rate, abs=0.01)
    stream([0.0, 0.0, 0.0], 3.0)  # "stop": it flies on, it cannot hover
    assert np.linalg.norm(flight.uav.velocity) >= FW.min_speed - 1e-6
    assert flight.uav.velocity[0] > 0.9 * FW.min_speed
    assert flight.airborne_speeds().min() >= FW.min_speed - 1e-6


def test_landing_spirals_down_then_glides_to_a_stop_in_landed_armed(flight):
    flight.take_off(40.0)
    flight.ual.land()
    assert flight.ual.state == UalState.LANDING
    start = len(flight.log)
    flight.run_until(lambda: flight.ual.state == UalState.LANDED_ARMED, 200)
    assert flight.uav.position[2] < 0.05 and np.linalg.norm(flight.uav.velocity) < 0.2
    assert not flight.uav.motors_on
    log = flight.log[start:]
    assert all(state == UalState.LANDING for *_, state in log[:-1])
    # the straight final approach follows the glide path at landing_slope
    final = [(p, v) for p, v, w, up, _ in log if up and p[2] < 0.8 * fixed_wing.final_approach_height(FW) and
             p[2] > 2.0]
    slopes = [math.atan2(-v[2], np.linalg.norm(v[:2])) for _, v in final]
    assert slopes and np.allclose(slopes, FW.landing_slope, atol=0.01)
    assert min(np.linalg.norm(v) for p, v, *_ in log if p[2] > 0.05) >= FW.min_speed - 1e-6
    touchdown = next(i for i, (p, *_) in enumerate(log) if p[2] <= 0.0)
    assert -log[touchdown - 1][1][2] < 1.0  # flared: a gentle touchdown, below the ground-impact speed
    assert flight.contacts == []  # so no collision is reported


def test_an_empty_battery_lands_the_plane():
    flight = Flight()
    try:
        flight.take_off(10.0)
        flight.world.batteries[1].charge_ah = 0.0
        flight.world.drain_batteries(0.1)
        assert flight.ual.state == UalState.LANDING
        flight.run_until(lambda: flight.ual.state == UalState.LANDED_ARMED, 200)
    finally:
        flight.close()


def test_a_900_m_path_uses_a_small_part_of_the_battery(flight):
    flight.take_off(10.0)
    start_charge = flight.world.batteries[1].charge_ah
    start_time, flown = flight.world.time, 0.0
    last = flight.uav.position.copy()
    for waypoint in ([400.0, 0.0, 10.0], [400.0, 400.0, 10.0], [0.0, 400.0, 10.0]):
        flight.ual.go_to(waypoint, 0.0)
        while not (flight.ual.reached() and flight.world.time > start_time):
            flight.step()
            flown += np.linalg.norm(flight.uav.position - last)
            last = flight.uav.position.copy()
    assert flown > 900.0
    used = (start_charge - flight.world.batteries[1].charge_ah) / flight.world.batteries[1].capacity_ah
    seconds = flight.world.time - start_time
    assert seconds == pytest.approx(flown / FW.cruise_speed, rel=0.1)  # it cruised
    # level cruise draws cruise_power_w: the energy is cruise power x time, within the turns' extra
    energy_wh = PLANE.battery.cruise_power_w * seconds / 3600.0
    capacity_wh = PLANE.battery.capacity_mah / 1000.0 * PLANE.battery.voltage
    assert used == pytest.approx(energy_wh / capacity_wh, rel=0.15)
    assert used < 0.10, f"{used:.1%} of the battery for {flown:.0f} m"


def test_cruise_speed_is_the_speed_of_longest_range():
    power = fixed_wing.flying_power(PLANE)
    assert power(FW.cruise_speed, 0.0) == pytest.approx(PLANE.battery.cruise_power_w)
    per_metre = {v: power(v, 0.0) / v for v in np.linspace(FW.min_speed, FW.max_speed, 41)}
    assert min(per_metre, key=per_metre.get) == pytest.approx(FW.cruise_speed, abs=0.3)
    climb = power(FW.cruise_speed, FW.max_climb_rate) - power(FW.cruise_speed, 0.0)
    assert climb == pytest.approx(PLANE.body.mass * GRAVITY * FW.max_climb_rate / fixed_wing.PROPULSIVE_EFFICIENCY)
    assert power(FW.cruise_speed, -FW.max_sink_rate) >= PLANE.battery.idle_power_w
