"""The dynamic flight model: multirotors flown by a cascaded controller through their rotors.

Each physics step, for all motors-on vehicles at once (numpy arrays of shape (N, ...)):

    velocity command -> first-order reference (the airframe's velocity_time_constant, as the light model)
    -> PI on the velocity error (+ reference acceleration, gravity, drag feed-forward; conditional
       anti-windup) -> desired force, thrust- and tilt-limited (limits.max_tilt)
    -> desired attitude (body z along the force, yaw integrated from the yaw-rate command)
    -> geometric attitude control on SO(3) (Lee, Leok & McClamroch 2010) -> wrench [T, tau_x, tau_y, tau_z]
    -> rotor thrusts through the pseudo-inverse of the allocation matrix, shifted to fit (mixer)
    -> clipped to [0, max_rotor_thrust]: the physics, where saturation happens
    -> the wrench the clipped rotors really make, plus body-axis linear drag on the air-relative velocity
       and, with wind_std > 0, Ornstein-Uhlenbeck wind gusts (m/s) from the model's rng -> pybullet.

Gains come from each airframe: attitude k_R = J w^2, k_W = 2 zeta J w with w such that an error of
AUTHORITY_ERROR uses the rotors' torque authority at hover; velocity gains from velocity_time_constant,
kept VELOCITY_BANDWIDTH_RATIO below the roll/pitch bandwidth. The only per-vehicle Python work is the
pybullet get/apply calls.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pybullet as p

from magna_common.airframes import Airframe, AirframeError, Body, Limits, Propulsion
from magna_sim.vehicle import Vehicle

GRAVITY = 9.81  # m/s^2, the world's gravity

# Attitude gains per axis: k_R = J w^2, k_W = 2 zeta J w, with w chosen so that an attitude error of
# AUTHORITY_ERROR asks for all the torque the rotors can give around hover (stiff, yet rarely saturated).
AUTHORITY_ERROR = 0.3  # rad
ATTITUDE_DAMPING = 0.9
# A discrete loop stays well-behaved while bandwidth * dt stays small; coarser steps get softer gains.
MAX_BANDWIDTH_STEP_PRODUCT = 0.15
VELOCITY_BANDWIDTH_RATIO = 3.0  # the velocity loop stays this much slower than roll and pitch
# Velocity loop: the command is shaped by a first-order reference with the airframe's velocity_time_constant
# (the light model's lag), so both models answer alike; the PI loop only fights what the reference did not
# foresee. Gains in units of that time constant tau: kp = VELOCITY_GAIN / tau, ki = VELOCITY_INTEGRAL * kp^2.
VELOCITY_GAIN = 2.0
VELOCITY_INTEGRAL = 0.05
REFERENCE_ACCEL_MARGIN = 0.7  # share of the tilt / thrust limited acceleration the reference may plan with
MAX_INTEGRAL_VERTICAL = 0.5 * GRAVITY  # m/s^2 the integrator may add vertically
MIN_THRUST_RATIO = 0.2  # of the weight: the controller never asks for free fall
HORIZONTAL_THRUST_MARGIN = 0.3  # of the maximum thrust, kept for steering even in a flat-out climb
MAX_YAW_ERROR = 0.5  # rad the yaw reference may lead the heading, so a slow yaw does not wind up
GUST_TIME_CONSTANT = 2.0  # s, correlation time of the wind gusts


def allocation_matrix(rotors: int, arm_length: float, torque_to_thrust: float) -> np.ndarray:
    """(4, rotors) map from rotor thrusts to [collective thrust, tau_x, tau_y, tau_z] in the body frame.

    Rotors sit evenly on a circle of `arm_length`, the first at pi/rotors from the nose (X layout),
    spinning alternately so that rotor i adds +-torque_to_thrust * thrust about body z.
    """
    angles = np.pi / rotors + 2.0 * np.pi * np.arange(rotors) / rotors
    x, y = arm_length * np.cos(angles), arm_length * np.sin(angles)
    spin = np.where(np.arange(rotors) % 2 == 0, 1.0, -1.0)
    # A thrust f along body z at (x, y, 0) gives the torque (y f, -x f, 0).
    return np.vstack([np.ones(rotors), y, -x, spin * torque_to_thrust])


def _multirotor_blocks(airframe: Airframe) -> tuple[Body, Propulsion, Limits]:
    """The blocks the dynamic model flies a multirotor with; AirframeError unless they make one it can fly."""
    airframe.require_physics()
    body, prop, limits = airframe.body, airframe.propulsion, airframe.limits
    assert body is not None  # require_physics: every kind of airframe has one
    rotors = body.rotors
    if rotors == 0:
        raise AirframeError(f"{airframe.source}: 'body.rotors': 0 (a fixed wing); the dynamic flight model "
                            f"flies multirotors only, use the fixed_wing model for '{airframe.model}'")
    if rotors < 4 or rotors % 2:
        raise AirframeError(f"{airframe.source}: 'body.rotors': {rotors}; the dynamic flight model needs an even "
                            f"number of rotors, 4 or more (alternate spin directions cancel the yaw torque)")
    assert prop is not None and limits is not None  # require_physics: a multirotor has both
    if body.arm_length <= 0 or prop.torque_to_thrust <= 0:
        raise AirframeError(f"{airframe.source}: 'body.arm_length' and 'propulsion.torque_to_thrust' must be "
                            f"positive for a multirotor")
    hover = body.mass * GRAVITY
    if rotors * prop.max_rotor_thrust <= hover:
        raise AirframeError(f"{airframe.source}: 'propulsion.max_rotor_thrust': {rotors} rotors of "
                            f"{prop.max_rotor_thrust} N cannot lift {hover:.3g} N")
    return body, prop, limits


@dataclass
class _Craft:
    """One attached vehicle: constants from its airframe and the controller state kept between batches."""

    rotors: int
    mass: float
    inertia: np.ndarray  # (3,)
    k_attitude: np.ndarray  # (3,) N m / rad
    k_rate: np.ndarray  # (3,) N m / (rad/s)
    time_constant: float  # s, of the velocity reference
    accel_limits: tuple[float, float, float]  # m/s^2 the reference may use: horizontal, up, down
    k_velocity: float  # 1/s
    k_integral: float  # 1/s^2
    tan_tilt: float
    max_thrust: float  # N, all rotors at their maximum
    rotor_max: float  # N
    drag: np.ndarray  # (3,) N/(m/s), body axes
    allocation: np.ndarray  # (4, rotors)
    mixer: np.ndarray  # (rotors, 4), pseudo-inverse of the allocation
    integral: np.ndarray = field(default_factory=lambda: np.zeros(3))  # m/s^2
    velocity_reference: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))  # nan: start from the body's
    yaw_reference: float = math.nan  # nan: take the current heading when the motors start
    wind: np.ndarray = field(default_factory=lambda: np.zeros(3))  # m/s, map frame
    thrusts: np.ndarray = field(default_factory=lambda: np.zeros(0))  # N, last applied per rotor
    armed: bool = False  # flew since its motors were last off


class _Batch:
    """The motors-on vehicles of a step, stacked into (N, ...) arrays; rebuilt only when that set changes."""

    def __init__(self, key: tuple[int, ...], crafts: list[_Craft], dt: float):
        self.key = key
        self.crafts = crafts
        n = len(crafts)

        def column(values) -> np.ndarray:
            return np.array(values, dtype=float).reshape(n, 1)

        mass = np.array([c.mass for c in crafts])
        self.mass = mass[:, None]
        self.weight = np.zeros((n, 3))
        self.weight[:, 2] = mass * GRAVITY
        self.inertia = np.array([c.inertia for c in crafts])
        # Negated (and for e_R halved, the 1/2 of the vee map) so the torque law is two multiply-adds.
        self.neg_half_k_attitude = -0.5 * np.array([c.k_attitude for c in crafts])
        self.neg_k_rate = -np.array([c.k_rate for c in crafts])
        self.inv_time_constant = column([1.0 / c.time_constant for c in crafts])
        self.accel_horizontal, self.accel_up, self.accel_down = np.array([c.accel_limits for c in crafts]).T
        self.k_velocity = column([c.k_velocity for c in crafts])
        self.k_integral_dt = column([c.k_integral * dt for c in crafts])
        self.integral_limit = np.array([[GRAVITY * c.tan_tilt] * 2 + [MAX_INTEGRAL_VERTICAL] for c in crafts])
        self.tan_tilt = np.array([c.tan_tilt for c in crafts])
        self.min_thrust = MIN_THRUST_RATIO * mass * GRAVITY
        self.max_thrust = np.array([c.max_thrust for c in crafts])
        self.max_thrust_sq = self.max_thrust ** 2
        self.margin_sq = (HORIZONTAL_THRUST_MARGIN * self.max_thrust) ** 2
        self.drag = np.array([c.drag for c in crafts])
        self.rotor_max = column([c.rotor_max for c in crafts])
        # Pad to the widest airframe. A missing rotor copies rotor 0's mixer row, so it never changes the
        # highest or lowest rotor, and has a zero allocation column, so it adds nothing to the wrench.
        width = max(c.rotors for c in crafts)
        self.allocation = np.zeros((n, 4, width))
        self.mixer = np.zeros((n, width, 4))
        for i, c in enumerate(crafts):
            self.allocation[i, :, :c.rotors] = c.allocation
            self.mixer[i] = c.mixer[np.where(np.arange(width) < c.rotors, np.arange(width), 0)]
        self.integral = np.array([c.integral for c in crafts])
        self.velocity_reference = np.array([c.velocity_reference for c in crafts])
        self.yaw_reference = np.array([c.yaw_reference for c in crafts])
        self.starting = bool(np.isnan(self.yaw_reference).any())  # some vehicle takes its references from its state
        self.wind = np.array([c.wind for c in crafts])
        self.thrusts = np.zeros((n, width))
        for i, c in enumerate(crafts):
            self.thrusts[i, :c.rotors] = c.thrusts

    def store(self) -> None:
        """Hand the controller state back to the crafts before the batch is dropped."""
        for i, c in enumerate(self.crafts):
            c.integral = self.integral[i].copy()
            c.velocity_reference = self.velocity_reference[i].copy()
            c.yaw_reference = float(self.yaw_reference[i])
            c.wind = self.wind[i].copy()
            c.thrusts = self.thrusts[i, :c.rotors].copy()


class QuadrotorModel:
    """Multirotor rigid-body flight through rotor forces (4, 6, ... rotors); see the module docstring."""

    name = "dynamic"
    follows_guidance: Literal[True] = True

    def __init__(self, client: int, physics_dt: float, rng: np.random.Generator | None = None,
                 wind_std: float = 0.0):
        if physics_dt <= 0:
            raise ValueError(f"physics_dt must be positive, got {physics_dt}")
        if wind_std < 0:
            raise ValueError(f"wind_std must be zero or more, got {wind_std}")
        self.client = client
        self.dt = float(physics_dt)
        self.rng = rng if rng is not None else np.random.default_rng()
        self.wind_std = float(wind_std)  # m/s, standard deviation of each gust velocity component
        self._crafts: dict[int, _Craft] = {}  # by pybullet body id
        self._batch: _Batch | None = None
        self._gust_decay = math.exp(-self.dt / GUST_TIME_CONSTANT)

    # -- FlightModel ---------------------------------------------------------------------------------

    def attach(self, vehicle: Vehicle) -> None:
        body, prop, limits = _multirotor_blocks(vehicle.airframe)
        inertia = np.array(body.inertia, dtype=float)
        allocation = allocation_matrix(body.rotors, body.arm_length, prop.torque_to_thrust)
        # Torque authority at hover: every rotor may move by the smaller of its hover thrust and its headroom.
        hover = body.mass * GRAVITY / body.rotors
        authority = np.abs(allocation[1:]).sum(axis=1) * min(hover, prop.max_rotor_thrust - hover)
        omega = np.minimum(np.sqrt(authority / (inertia * AUTHORITY_ERROR)), MAX_BANDWIDTH_STEP_PRODUCT / self.dt)
        time_constant = max(limits.velocity_time_constant, 4.0 * self.dt)
        k_velocity = min(VELOCITY_GAIN / time_constant, omega[:2].min() / VELOCITY_BANDWIDTH_RATIO)
        tan_tilt = math.tan(min(limits.max_tilt, 1.4))
        max_thrust = body.rotors * prop.max_rotor_thrust
        accel_limits = (REFERENCE_ACCEL_MARGIN * GRAVITY * tan_tilt,
                        REFERENCE_ACCEL_MARGIN * (max_thrust / body.mass - GRAVITY),
                        REFERENCE_ACCEL_MARGIN * (1.0 - MIN_THRUST_RATIO) * GRAVITY)
        self._crafts[vehicle.body_id] = _Craft(
            rotors=body.rotors, mass=body.mass, inertia=inertia,
            k_attitude=inertia * omega ** 2, k_rate=inertia * 2.0 * ATTITUDE_DAMPING * omega,
            time_constant=time_constant, accel_limits=accel_limits,
            k_velocity=k_velocity, k_integral=VELOCITY_INTEGRAL * k_velocity ** 2,
            tan_tilt=tan_tilt, max_thrust=max_thrust,
            rotor_max=prop.max_rotor_thrust, drag=np.array(prop.drag_coefficients, dtype=float),
            allocation=allocation, mixer=np.linalg.pinv(allocation), thrusts=np.zeros(body.rotors))
        self._drop_batch()

    def detach(self, vehicle: Vehicle) -> None:
        self._drop_batch()
        self._crafts.pop(vehicle.body_id, None)

    def apply_controls(self, vehicles: Sequence[Vehicle], velocity_commands: np.ndarray,
                       yaw_rate_commands: np.ndarray) -> None:
        on = []
        for i, v in enumerate(vehicles):
            if v.motors_on:
                on.append(i)
            else:
                self._disarm(v.body_id)  # landed: no forces, and the next take-off starts clean
        if not on:
            return
        velocity_commands = np.asarray(velocity_commands, dtype=float).reshape(-1, 3)
        yaw_rate_commands = np.asarray(yaw_rate_commands, dtype=float).reshape(-1)
        if len(on) < len(vehicles):
            velocity_commands, yaw_rate_commands = velocity_commands[on], yaw_rate_commands[on]
            vehicles = [vehicles[i] for i in on]
        ids = [v.body_id for v in vehicles]
        batch = self._batch_for(tuple(ids))

        c = self.client
        poses = [p.getBasePositionAndOrientation(b, physicsClientId=c) for b in ids]
        twists = [p.getBaseVelocity(b, physicsClientId=c) for b in ids]
        positions, quaternions = zip(*poses, strict=True)
        velocities, rates = zip(*twists, strict=True)
        force, torque = self._control(batch, np.array(quaternions), np.array(velocities), np.array(rates),
                                      velocity_commands, yaw_rate_commands)
        for b, f, t, at in zip(ids, force.tolist(), torque.tolist(), positions, strict=True):
            # The frame origin is the centre of mass, so the force there adds no torque.
            p.applyExternalForce(b, -1, f, at, p.WORLD_FRAME, physicsClientId=c)
            p.applyExternalTorque(b, -1, t, p.WORLD_FRAME, physicsClientId=c)

    def read_state(self, vehicles: Sequence[Vehicle]) -> None:
        if not vehicles:
            return
        c = self.client
        poses = [p.getBasePositionAndOrientation(v.body_id, physicsClientId=c) for v in vehicles]
        twists = [p.getBaseVelocity(v.body_id, physicsClientId=c) for v in vehicles]
        positions, quaternions = map(np.array, zip(*poses, strict=True))
        velocities, rates = map(np.array, zip(*twists, strict=True))
        x, y, z, w = quaternions.T
        yaws = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)).tolist()  # once for all
        for i, v in enumerate(vehicles):
            v.position, v.velocity, v.angular_velocity = positions[i], velocities[i], rates[i]
            v.set_attitude(quaternions[i], yaws[i])

    # -- inspection ----------------------------------------------------------------------------------

    def rotor_thrusts(self, vehicle: Vehicle) -> np.ndarray:
        """Thrust (N) of each rotor at the last step the vehicle flew; zeros once its motors are off."""
        craft = self._crafts[vehicle.body_id]
        batch = self._batch
        if batch is not None and vehicle.body_id in batch.key:
            return batch.thrusts[batch.key.index(vehicle.body_id), :craft.rotors].copy()
        return craft.thrusts.copy()

    # -- internals -----------------------------------------------------------------------------------

    def _batch_for(self, key: tuple[int, ...]) -> _Batch:
        if self._batch is None or self._batch.key != key:
            self._drop_batch()
            try:
                crafts = [self._crafts[b] for b in key]
            except KeyError as err:
                raise KeyError(f"body {err.args[0]} is flown by the dynamic model but was never attached") from None
            self._batch = _Batch(key, crafts, self.dt)
            for craft in crafts:
                craft.armed = True
        return self._batch

    def _drop_batch(self) -> None:
        if self._batch is not None:
            self._batch.store()
            self._batch = None

    def _disarm(self, body_id: int) -> None:
        craft = self._crafts.get(body_id)
        if craft is None or not craft.armed:
            return
        if self._batch is not None and body_id in self._batch.key:
            self._drop_batch()
        craft.armed = False
        craft.integral = np.zeros(3)
        craft.velocity_reference = np.full(3, np.nan)
        craft.yaw_reference = math.nan
        craft.thrusts = np.zeros(craft.rotors)

    def _control(self, b: _Batch, quaternions: np.ndarray, velocity: np.ndarray, rate_world: np.ndarray,
                 velocity_command: np.ndarray, yaw_rate_command: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World-frame force and torque (N, 3) for every vehicle of the batch; updates its state.

        Written for few numpy calls: at N = 1..50 their fixed cost, not the arithmetic, is the bill.
        """
        dt = self.dt
        rot = rotation_matrices(quaternions)  # body -> map, (N, 3, 3)
        rate = (rate_world[:, None, :] @ rot)[:, 0]  # body rates, R^T w
        yaw = np.arctan2(rot[:, 1, 0], rot[:, 0, 0])
        if b.starting:  # motors just came on: references start from where the body is
            fresh = np.isnan(b.yaw_reference)
            b.yaw_reference[fresh] = yaw[fresh]
            b.velocity_reference[fresh] = velocity[fresh]
            b.starting = False

        # Velocity reference: first order toward the command, its acceleration kept within reach.
        reference = b.velocity_reference
        ref_accel = (velocity_command - reference) * b.inv_time_constant
        _limit_horizontal(ref_accel, b.accel_horizontal)
        ref_accel[:, 2] = np.minimum(np.maximum(ref_accel[:, 2], -b.accel_down), b.accel_up)
        reference += dt * ref_accel

        # Velocity PI around the reference, plus the reference's acceleration, gravity and the drag the
        # airframe meets at the reference velocity: the force wanted, then thrust and tilt limited.
        error = reference - velocity
        drag = (rot @ (b.drag * (reference[:, None, :] @ rot)[:, 0])[:, :, None])[:, :, 0]
        wanted = b.mass * (ref_accel + b.k_velocity * error + b.integral) + b.weight + drag
        force = wanted.copy()
        vertical = np.minimum(np.maximum(wanted[:, 2], b.min_thrust), b.max_thrust)
        force[:, 2] = vertical
        # Climb has priority; the horizontal part gets what the tilt limit and the remaining thrust allow, but
        # never less than a steering margin (the rotors then clip the collective, not the steering).
        _limit_horizontal(force, np.minimum(vertical * b.tan_tilt,
                                            np.sqrt(np.maximum(b.max_thrust_sq - vertical * vertical, b.margin_sq))))
        # Anti-windup by conditional integration: no integrating further into a limit that cut the force.
        b.integral += np.where((wanted - force) * error > 0.0, 0.0, b.k_integral_dt * error)
        np.minimum(np.maximum(b.integral, -b.integral_limit, out=b.integral), b.integral_limit, out=b.integral)

        # Desired attitude: body z along the force, heading from the integrated yaw-rate command.
        lead = b.yaw_reference + yaw_rate_command * dt - yaw
        lead = np.minimum(np.maximum((lead + np.pi) % (2.0 * np.pi) - np.pi, -MAX_YAW_ERROR), MAX_YAW_ERROR)
        b.yaw_reference = yaw + lead
        rot_d_t = np.empty_like(rot)  # rows are the desired body axes, i.e. Rd^T
        z_d = rot_d_t[:, 2]
        np.divide(force, np.sqrt(np.einsum("ni,ni->n", force, force))[:, None], out=z_d)
        heading = np.zeros((len(rot), 3))
        heading[:, 0], heading[:, 1] = np.cos(b.yaw_reference), np.sin(b.yaw_reference)
        y_d = _cross(z_d, heading)
        rot_d_t[:, 1] = y_d / np.sqrt(np.einsum("ni,ni->n", y_d, y_d))[:, None]
        rot_d_t[:, 0] = _cross(rot_d_t[:, 1], z_d)

        # Geometric attitude control on SO(3): e_R = 1/2 vee(Rd^T R - R^T Rd), e_W = W - R^T Rd W_d, where
        # W_d is the commanded yaw rate about map z; torque = -k_R e_R - k_W e_W + W x J W.
        m = rot_d_t @ rot
        skew = (m - m.transpose(0, 2, 1)).reshape(-1, 9).take(_VEE, axis=1)
        e_rate = rate - yaw_rate_command[:, None] * rot[:, 2]
        wrench = np.empty((len(rot), 4))
        wrench[:, 0] = np.einsum("ni,ni->n", force, rot[:, :, 2])  # the part of the force body z can give
        wrench[:, 1:] = b.neg_half_k_attitude * skew + b.neg_k_rate * e_rate + _cross(rate, b.inertia * rate)

        # Mixer: rotor thrusts, shifted together (torques kept, collective given up) into [0, max] if they fit,
        # else kept off zero. Then physics: a rotor gives between nothing and its maximum, whatever was asked.
        rotor = (b.mixer @ wrench[:, :, None])[:, :, 0]
        shift = np.maximum(-rotor.min(axis=1), np.minimum(0.0, b.rotor_max[:, 0] - rotor.max(axis=1)))
        rotor += shift[:, None]
        np.minimum(np.maximum(rotor, 0.0, out=rotor), b.rotor_max, out=rotor)
        b.thrusts = rotor
        real = (b.allocation @ rotor[:, :, None])[:, :, 0]

        # Body-axis linear drag on the air-relative velocity; gusts are an Ornstein-Uhlenbeck wind.
        if self.wind_std > 0.0:
            a = self._gust_decay
            b.wind = a * b.wind + math.sqrt(1.0 - a * a) * self.wind_std * self.rng.standard_normal(b.wind.shape)
            velocity = velocity - b.wind
        body_force = b.drag * (velocity[:, None, :] @ rot)[:, 0]
        np.subtract(real[:, 0], body_force[:, 2], out=body_force[:, 2])
        body_force[:, :2] *= -1.0
        world_force = (rot @ body_force[:, :, None])[:, :, 0]
        world_torque = (rot @ real[:, 1:, None])[:, :, 0]
        return world_force, world_torque


def _limit_horizontal(vectors: np.ndarray, limit: np.ndarray) -> None:
    """Scale the x-y part of each row of (N, 3) `vectors` in place so its length is at most `limit` (N,)."""
    length = np.hypot(vectors[:, 0], vectors[:, 1])
    vectors[:, :2] *= np.minimum(1.0, limit / np.maximum(length, 1e-12))[:, None]


_VEE = np.array([7, 2, 3])  # entries (2, 1), (0, 2), (1, 0) of a flattened 3x3 skew matrix
_CYCLE = np.array([1, 2, 0, 1])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (N, 3) arrays, in a third of np.cross's time at small N."""
    a, b = a.take(_CYCLE, axis=1), b.take(_CYCLE, axis=1)  # (y, z, x, y)
    return a[:, :3] * b[:, 1:] - a[:, 1:] * b[:, :3]


# Coefficients of the products q_i q_j (x, y, z, w order) in each entry of the rotation matrix.
_QUAT_TO_ROT = np.zeros((16, 9))
for _entry, _terms in enumerate([
        [(1, 1, -2), (2, 2, -2)], [(0, 1, 2), (2, 3, -2)], [(0, 2, 2), (1, 3, 2)],
        [(0, 1, 2), (2, 3, 2)], [(0, 0, -2), (2, 2, -2)], [(1, 2, 2), (0, 3, -2)],
        [(0, 2, 2), (1, 3, -2)], [(1, 2, 2), (0, 3, 2)], [(0, 0, -2), (1, 1, -2)]]):
    for _i, _j, _k in _terms:
        _QUAT_TO_ROT[4 * _i + _j, _entry] = _k
_IDENTITY = np.eye(3).reshape(9)


def rotation_matrices(quaternions: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices (body -> world) of unit quaternions (N, 4) in pybullet's x y z w order."""
    products = (quaternions[:, :, None] * quaternions[:, None, :]).reshape(-1, 16)
    return (_IDENTITY + products @ _QUAT_TO_ROT).reshape(-1, 3, 3)
