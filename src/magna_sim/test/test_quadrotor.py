"""The dynamic flight model (magna_sim.quadrotor) flying real airframes in a headless pybullet world."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p
import pytest

from magna_common.airframes import AirframeError, load_airframe
from magna_sim import bodies
from magna_sim.quadrotor import QuadrotorModel, allocation_matrix, rotation_matrices
from magna_sim.vehicle import SetpointMode, Vehicle

DT = 1.0 / 240.0
MULTIROTORS = ["iris", "typhoon_h480", "f550", "crazyflie"]
TILT_MARGIN = 0.05  # rad the body may lean past limits.max_tilt while the attitude loop settles


@pytest.fixture
def client():
    c = p.connect(p.DIRECT)
    p.setGravity(0.0, 0.0, -9.81, physicsClientId=c)
    p.setTimeStep(DT, physicsClientId=c)
    bodies.create_ground(c)
    yield c
    p.disconnect(c)


@dataclass
class Log:
    position: np.ndarray  # (T, N, 3)
    velocity: np.ndarray  # (T, N, 3)
    yaw: np.ndarray  # (T, N), unwrapped
    tilt: np.ndarray  # (T, N), angle between body z and map z
    max_rotor: np.ndarray  # (T, N), the strongest rotor's thrust


class Flight:
    """A few vehicles flown the way the world flies them: apply_controls, stepSimulation, read_state."""

    def __init__(self, client: int, models: list[str], rng=None, wind_std: float = 0.0, spawn_z: float = 0.0,
                 spawn_yaw: float = 0.0):
        self.client = client
        self.model = QuadrotorModel(client, DT, rng=rng, wind_std=wind_std)
        self.vehicles = []
        for k, name in enumerate(models):
            airframe = load_airframe(name)
            vehicle = Vehicle(name=f"uav_{k + 1}", uav_id=k + 1, airframe=airframe, flight_model="dynamic")
            heading = p.getQuaternionFromEuler([0.0, 0.0, spawn_yaw])
            vehicle.body_id = bodies.create_uav_body(client, airframe, [3.0 * k, 0.0, spawn_z], heading)
            self.model.attach(vehicle)
            self.vehicles.append(vehicle)
        self.model.read_state(self.vehicles)

    def fly(self, seconds: float, velocity=(0.0, 0.0, 0.0), yaw_rate=0.0, modes=None) -> Log:
        n = len(self.vehicles)
        for vehicle, mode in zip(self.vehicles, modes or [SetpointMode.VELOCITY] * n, strict=True):
            vehicle.setpoint.mode = mode
        commands = np.tile(np.asarray(velocity, dtype=float), (n, 1))
        yaw_rates = np.full(n, float(yaw_rate))
        rows = []
        for _ in range(int(round(seconds / DT))):
            self.model.apply_controls(self.vehicles, commands, yaw_rates)
            p.stepSimulation(physicsClientId=self.client)
            self.model.read_state(self.vehicles)
            rows.append([(*v.position, *v.velocity, v.yaw, _tilt(v), self.model.rotor_thrusts(v).max())
                         for v in self.vehicles])
        data = np.array(rows)
        return Log(position=data[:, :, 0:3], velocity=data[:, :, 3:6], yaw=np.unwrap(data[:, :, 6], axis=0),
                   tilt=data[:, :, 7], max_rotor=data[:, :, 8])

    def take_off(self, height_speed: float = 1.0, seconds: float = 1.5, settle: float = 2.0) -> None:
        self.fly(seconds, velocity=(0.0, 0.0, height_speed))
        self.fly(settle)


def _tilt(vehicle: Vehicle) -> float:
    x, y, _, _ = vehicle.orientation
    return float(np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)))


# -- geometry ------------------------------------------------------------------------------------------


def test_rotation_matrices_match_pybullet():
    rng = np.random.default_rng(3)
    quaternions = rng.normal(size=(6, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    expected = [np.reshape(p.getMatrixFromQuaternion(q.tolist()), (3, 3)) for q in quaternions]
    np.testing.assert_allclose(rotation_matrices(quaternions), expected, atol=1e-12)


@pytest.mark.parametrize("rotors", [4, 6])
def test_allocation_matrix_x_layout(rotors):
    arm, torque_ratio = 0.25, 0.016
    a = allocation_matrix(rotors, arm, torque_ratio)
    assert a.shape == (4, rotors)
    # Equal thrusts: pure collective, no torque.
    np.testing.assert_allclose(a @ np.ones(rotors), [rotors, 0.0, 0.0, 0.0], atol=1e-12)
    # Every rotor on the arm circle, none on the x axis (X layout), spins alternating.
    np.testing.assert_allclose(np.hypot(a[1], a[2]), arm)
    assert np.all(np.abs(a[1]) > 1e-6)
    np.testing.assert_allclose(a[3], torque_ratio * np.where(np.arange(rotors) % 2 == 0, 1.0, -1.0))
    # Full rank: the pseudo-inverse gives back any wrench.
    wrench = np.array([12.0, 0.3, -0.2, 0.05])
    np.testing.assert_allclose(a @ (np.linalg.pinv(a) @ wrench), wrench, atol=1e-12)


# -- flight --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", MULTIROTORS)
def test_hover_holds_altitude(client, model):
    flight = Flight(client, [model])
    flight.take_off()
    log = flight.fly(5.0)
    z = log.position[:, 0, 2]
    assert z.min() > 1.0, f"{model} never lifted off: z = {z.min():.3f}"
    assert np.ptp(z) < 0.02, f"{model} drifted {np.ptp(z):.4f} m in altitude"
    horizontal = log.position[:, 0, :2] - log.position[0, 0, :2]
    assert np.abs(horizontal).max() < 0.02
    assert log.tilt.max() < 0.02


@pytest.mark.parametrize("model", MULTIROTORS)
def test_velocity_step_is_tracked_within_tilt_limit(client, model):
    # Facing away from map x, so the step needs roll and pitch together (and the torques the right frame).
    flight = Flight(client, [model], spawn_yaw=2.0)
    flight.take_off()
    log = flight.fly(4.0, velocity=(1.0, 0.0, 0.0))
    t = np.arange(len(log.velocity)) * DT
    vx = log.velocity[:, 0, 0]
    reached = t[np.argmax(vx > 0.95)]
    assert vx.max() > 0.95 and reached < 2.0, f"{model} reached 95% of 1 m/s only at {reached:.2f} s"
    assert vx.max() < 1.1, f"{model} overshot to {vx.max():.3f} m/s"
    late = t > 3.0
    assert np.abs(vx[late] - 1.0).max() < 0.02
    assert np.abs(log.velocity[late, 0, 1:]).max() < 0.02
    limit = flight.vehicles[0].airframe.limits.max_tilt
    assert log.tilt.max() > 0.1, "the step was taken without leaning"
    assert log.tilt.max() < limit + TILT_MARGIN


@pytest.mark.parametrize("model", MULTIROTORS)
def test_yaw_rate_turns_the_heading(client, model):
    flight = Flight(client, [model])
    flight.take_off()
    turn = flight.fly(2.0, yaw_rate=0.5)
    hold = flight.fly(2.0)
    turning = np.diff(turn.yaw[int(1.0 / DT):, 0]) / DT
    assert turning.mean() == pytest.approx(0.5, abs=0.03)
    assert np.abs(turning - 0.5).max() < 0.1, f"{model} turned at {turning.min():.3f}..{turning.max():.3f} rad/s"
    # Once the command stops, the heading settles where the integrated command put it: 0.5 rad/s * 2 s.
    turned = hold.yaw[-1, 0] - turn.yaw[0, 0]
    assert turned == pytest.approx(1.0, abs=0.02), f"{model} turned {turned:.3f} rad"
    assert np.ptp(hold.yaw[-int(0.5 / DT):, 0]) < 0.01
    assert np.abs(hold.position[:, 0, :2] - turn.position[0, 0, :2]).max() < 0.05
    assert np.ptp(np.concatenate([turn.position[:, 0, 2], hold.position[:, 0, 2]])) < 0.02


def test_motors_off_rest_on_the_ground_while_others_fly(client):
    flight = Flight(client, MULTIROTORS + ["iris"], spawn_z=0.02)
    off = [SetpointMode.OFF] * len(MULTIROTORS)
    log = flight.fly(2.0, velocity=(0.0, 0.0, 1.0), modes=off + [SetpointMode.VELOCITY])
    landed = slice(0, len(MULTIROTORS))
    np.testing.assert_allclose(log.position[-1, landed, 2], 0.0, atol=2e-3)
    np.testing.assert_allclose(log.position[-1, landed, :2], log.position[0, landed, :2], atol=1e-3)
    assert np.abs(log.velocity[-1, landed]).max() < 1e-2
    assert log.tilt[-1, landed].max() < 1e-3
    assert np.all(log.max_rotor[:, landed] == 0.0)
    # The one with motors on, flown in the same calls, climbed.
    assert log.position[-1, -1, 2] > 1.0


def test_landing_then_take_off_again_starts_clean(client):
    flight = Flight(client, ["iris"])
    flight.take_off()
    flight.fly(5.0, velocity=(0.0, 0.0, -0.6))  # down to the ground and pressing on it
    assert flight.vehicles[0].position[2] < 0.01
    rest = flight.fly(1.0, modes=[SetpointMode.OFF])
    assert rest.max_rotor.max() == 0.0
    climb = flight.fly(2.0, velocity=(0.0, 0.0, 1.0))
    assert climb.position[-1, 0, 2] > 1.0
    # Whatever the integrator learnt while pressing on the ground was forgotten: no lurch, no lean.
    assert climb.velocity[:, 0, 2].max() < 1.1
    assert climb.tilt.max() < 0.02


@pytest.mark.parametrize("model", MULTIROTORS)
def test_impossible_climb_saturates_rotors_but_stays_upright(client, model):
    flight = Flight(client, [model])
    airframe = flight.vehicles[0].airframe
    max_rotor = airframe.propulsion.max_rotor_thrust
    log = flight.fly(4.0, velocity=(0.0, 0.0, 50.0))
    assert log.max_rotor.max() <= max_rotor
    saturated = np.isclose(log.max_rotor[:, 0], max_rotor, rtol=1e-9)
    assert saturated[-int(1.0 / DT):].all(), "drag at climb speed should have saturated the rotors"
    assert log.tilt.max() < 0.02
    assert np.abs(log.position[:, 0, :2] - log.position[0, 0, :2]).max() < 0.05
    # The climb is nearly as fast as the airframe allows (full thrust against gravity and vertical drag from
    # the start), not as fast as the command asks.
    body = airframe.body
    full = body.rotors * max_rotor / body.mass - 9.81
    decay = airframe.propulsion.drag_coefficients[2] / body.mass
    fastest = full / decay * (1.0 - np.exp(-decay * 4.0))
    assert 0.85 * fastest < log.velocity[-1, 0, 2] < fastest


@pytest.mark.parametrize("model", MULTIROTORS)
def test_saturated_rotors_still_right_a_tilted_body(client, model):
    # Spawned rolled and pitched in the air and asked to climb flat out: the mixer gives up collective
    # thrust, not attitude, so the body rights itself with every rotor within its range.
    flight = Flight(client, [model], spawn_z=5.0)
    tilted = p.getQuaternionFromEuler([0.7, -0.5, 0.3])
    p.resetBasePositionAndOrientation(flight.vehicles[0].body_id, [0.0, 0.0, 5.0], tilted, physicsClientId=client)
    flight.model.read_state(flight.vehicles)
    max_rotor = flight.vehicles[0].airframe.propulsion.max_rotor_thrust
    log = flight.fly(1.5, velocity=(0.0, 0.0, 50.0))
    assert log.max_rotor.max() <= max_rotor
    assert log.max_rotor.max() == pytest.approx(max_rotor, rel=1e-9)
    tilt = log.tilt[:, 0]
    assert tilt[0] > 0.8
    righted = np.argmax(tilt < 0.2) * DT
    assert 0.0 < righted < 0.25, f"{model} took {righted:.2f} s to right itself"
    # Then it only leans to stop the sideways drift the tilted start gave it, within the tilt limit.
    assert tilt[int(0.3 / DT):].max() < flight.vehicles[0].airframe.limits.max_tilt
    assert tilt[-int(0.5 / DT):].max() < 0.03
    assert np.abs(log.velocity[-1, 0, :2]).max() < 0.2
    assert log.velocity[-1, 0, 2] > 5.0


@pytest.mark.parametrize("model", ["iris", "crazyflie"])
def test_impossible_dash_keeps_the_tilt_limit(client, model):
    flight = Flight(client, [model], spawn_yaw=-1.0)
    flight.take_off()
    log = flight.fly(3.0, velocity=(30.0, 30.0, 10.0))
    assert log.max_rotor.max() <= flight.vehicles[0].airframe.propulsion.max_rotor_thrust
    assert log.tilt.max() < flight.vehicles[0].airframe.limits.max_tilt + TILT_MARGIN
    assert log.velocity[-1, 0, 0] > 2.0 and log.velocity[-1, 0, 2] > 2.0


@pytest.mark.parametrize("model", MULTIROTORS)
def test_a_violent_kick_is_fought_back_at_the_tilt_limit(client, model):
    flight = Flight(client, [model], spawn_yaw=0.7)
    flight.take_off()
    vehicle = flight.vehicles[0]
    p.resetBaseVelocity(vehicle.body_id, [-6.0, 4.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=client)
    log = flight.fly(4.0)
    limit = vehicle.airframe.limits.max_tilt
    assert limit - 0.1 < log.tilt.max() < limit + TILT_MARGIN, f"{model} leant {log.tilt.max():.3f} rad"
    assert np.abs(log.velocity[-1, 0]).max() < 0.05


def test_fixed_wing_is_refused(client):
    airframe = load_airframe("plane")
    vehicle = Vehicle(name="uav_1", uav_id=1, airframe=airframe, flight_model="dynamic")
    vehicle.body_id = bodies.create_uav_body(client, airframe, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    model = QuadrotorModel(client, DT)
    with pytest.raises(ValueError) as refused:
        model.attach(vehicle)
    assert isinstance(refused.value, AirframeError)
    assert "plane.json" in str(refused.value) and "body.rotors" in str(refused.value)


def test_seeded_wind_is_reproducible(client):
    def gusty_flight(seed: int | None, wind_std: float) -> np.ndarray:
        rng = None if seed is None else np.random.default_rng(seed)
        flight = Flight(client, ["iris", "crazyflie"], rng=rng, wind_std=wind_std)
        flight.fly(1.0, velocity=(0.0, 0.0, 1.0))
        positions = flight.fly(3.0, velocity=(0.5, 0.0, 0.0)).position
        for vehicle in flight.vehicles:
            p.removeBody(vehicle.body_id, physicsClientId=client)
        return positions

    first, second = gusty_flight(7, 2.0), gusty_flight(7, 2.0)
    np.testing.assert_array_equal(first, second)
    other_seed, calm = gusty_flight(8, 2.0), gusty_flight(None, 0.0)
    assert np.abs(first - other_seed).max() > 1e-3
    assert np.abs(first - calm).max() > 1e-3
