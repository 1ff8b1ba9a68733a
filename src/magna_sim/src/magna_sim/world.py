"""The simulated world: one pybullet DIRECT client with the ground, UAVs and obstacles.

`SimWorld.step()` advances one fixed physics step: guidance turns each UAV's
setpoint into velocity commands, its flight model acts on pybullet, pybullet
steps, the models read back, each UAV's UAL state machine advances, and new
contacts come back as `Contact` records. No ROS here: the node wraps this.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as p

from magna_common.airframes import Airframe, AirframeError, available_models, load_airframe

from . import bodies, fixed_wing, guidance, shapes
from .battery import BatteryModel
from .fixed_wing import FixedWingModel
from .light import LightModel
from .quadrotor import QuadrotorModel
from .ual_logic import UalLogic, UalSettings, UalState
from .vehicle import FlightModel, Vehicle

FLIGHT_MODELS = ("light", "dynamic", "fixed_wing")


class SpawnError(ValueError):
    """A spawn or delete request that was refused; the message names the field."""


@dataclass(frozen=True)
class Contact:
    """Two things started touching during the last step."""

    uav_id: int
    other_kind: str  # "uav", "obstacle" or "ground"
    other_name: str  # other UAV id as text, obstacle name, or "" for the ground
    position: np.ndarray  # the UAV's position
    distance: float  # to the other UAV's origin, or to the contact point (m)
    speed: float  # the UAV's speed relative to the other (m/s)


@dataclass
class Obstacle:
    name: str
    body_id: int
    shape: str


class SimWorld:
    def __init__(self, physics_rate: float = 240.0, seed: int | None = None, wind_std: float = 0.0,
                 ual_settings: UalSettings = UalSettings(), ground_impact_speed: float = 1.0,
                 battery_floor: float = 0.0):
        if not (math.isfinite(physics_rate) and physics_rate > 0):
            raise ValueError(f"physics_rate: {physics_rate} must be a positive number of steps per second")
        self.dt = 1.0 / physics_rate
        self.steps = 0
        self.physics_rate, self.wind_std = physics_rate, wind_std
        self.client = p.connect(p.DIRECT)
        p.setGravity(0.0, 0.0, -9.81, physicsClientId=self.client)
        p.setTimeStep(self.dt, physicsClientId=self.client)
        # Same inputs, same outputs: pair order must not depend on memory addresses.
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=self.client)
        self.rng = np.random.default_rng(seed)
        self.ground_id = bodies.create_ground(self.client)
        self.ground_impact_speed = ground_impact_speed
        self.battery_floor = battery_floor  # fraction of charge batteries keep (PX4 SITL's SIM_BAT_MIN_PCT)
        self.ual_settings = ual_settings
        self.models: dict[str, FlightModel] = {
            "light": LightModel(self.client, self.dt),
            "dynamic": QuadrotorModel(self.client, self.dt, rng=self.rng, wind_std=wind_std),
            "fixed_wing": FixedWingModel(self.client, self.dt)}
        self.vehicles: dict[int, Vehicle] = {}  # by UAL id
        self.ual: dict[int, UalLogic] = {}
        self.batteries: dict[int, BatteryModel] = {}
        self.obstacles: dict[str, Obstacle] = {}
        self._by_body: dict[int, tuple[str, str]] = {self.ground_id: ("ground", "")}
        self._touching: set[tuple[int, int]] = set()

    @property
    def time(self) -> float:
        return self.steps * self.dt

    def renewed(self, seed: int | None) -> SimWorld:
        """A new, empty world with this one's settings and `seed`: the same as a cold start's.

        A new one rather than this one cleared: a fresh pybullet client numbers bodies from the start, and the
        flight models (which keep the rng) start over. This one stays open; the caller closes it."""
        return SimWorld(self.physics_rate, seed, self.wind_std, self.ual_settings, self.ground_impact_speed,
                        self.battery_floor)

    def close(self) -> None:
        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None

    def sensor_readings(self, uav_ids, position_std: float, velocity_std: float
                        ) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """Each UAV's (position, velocity) as its sensors report them: the true ones plus Gaussian noise.

        The noise comes from the world's rng, position then velocity, UAV by UAV in the order of `uav_ids`: a seeded
        run draws the same numbers only in the same order."""
        readings = {}
        for uav_id in uav_ids:
            vehicle = self.vehicles[uav_id]
            position, velocity = vehicle.position, vehicle.velocity
            if position_std > 0:
                position = position + self.rng.normal(0.0, position_std, 3)
            if velocity_std > 0:
                velocity = velocity + self.rng.normal(0.0, velocity_std, 3)
            readings[uav_id] = (position, velocity)
        return readings

    # --- models ----------------------------------------------------------------------------------------------
    def names(self) -> list[str]:
        return sorted([v.name for v in self.vehicles.values()] + list(self.obstacles))

    def spawn_uav(self, name: str, uav_id: int, airframe: str, flight_model: str,
                  position: Sequence[float], yaw: float = 0.0, rgba=(0.2, 0.2, 0.25, 1.0)) -> Vehicle:
        self._check_new_name(name)
        if uav_id in self.vehicles:
            raise SpawnError(f"uav_id: {uav_id} is already flying as '{self.vehicles[uav_id].name}'; "
                             "pick a free id or delete that model first")
        if flight_model not in FLIGHT_MODELS:
            raise SpawnError(f"flight_model: '{flight_model}' is not one of {', '.join(FLIGHT_MODELS)}")
        try:
            frame = load_airframe(airframe)
            frame.require_physics()
        except AirframeError as err:
            raise SpawnError(f"airframe: {err}; known: {', '.join(available_models())}") from None
        flight_model = _flight_model_for(airframe, frame, flight_model)
        start = _finite("pose.position", position)
        _finite("pose.orientation (yaw)", [yaw], size=1)
        orientation = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
        body_id = bodies.create_uav_body(self.client, frame, start, orientation, rgba)
        vehicle = Vehicle(name=name, uav_id=uav_id, airframe=frame, flight_model=flight_model, body_id=body_id,
                          position=start.copy(), orientation=orientation)
        self.models[flight_model].attach(vehicle)
        self.vehicles[uav_id] = vehicle
        self.ual[uav_id] = UalLogic(vehicle, self.ual_settings)
        assert frame.battery is not None  # require_physics above: every kind of airframe has one
        self.batteries[uav_id] = BatteryModel(
            frame.battery, flying_power=fixed_wing.flying_power(frame) if frame.is_fixed_wing else None,
            floor_fraction=self.battery_floor)
        self._by_body[body_id] = ("uav", str(uav_id))
        return vehicle

    def spawn_obstacle(self, name: str, shape: str, dimensions, vertices, position, orientation_xyzw,
                       rgba=(0.6, 0.6, 0.6, 1.0)) -> Obstacle:
        self._check_new_name(name)
        position = _finite("pose.position", position)
        orientation = _finite("pose.orientation", orientation_xyzw, size=4)
        if np.linalg.norm(orientation) < 1e-9:
            raise SpawnError("pose.orientation: the quaternion is zero; use [0, 0, 0, 1] for no rotation")
        try:
            body_id = shapes.create_obstacle(self.client, shape, dimensions, vertices, position,
                                             orientation / np.linalg.norm(orientation), rgba)
        except shapes.ShapeError as err:
            raise SpawnError(str(err)) from None
        obstacle = Obstacle(name, body_id, shape)
        self.obstacles[name] = obstacle
        self._by_body[body_id] = ("obstacle", name)
        return obstacle

    def delete(self, name: str) -> str:
        """Remove a UAV or an obstacle; returns its kind."""
        if name in self.obstacles:
            obstacle = self.obstacles.pop(name)
            self._forget_body(obstacle.body_id)
            return "obstacle"
        for uav_id, vehicle in self.vehicles.items():
            if vehicle.name == name:
                self.models[vehicle.flight_model].detach(vehicle)
                del self.vehicles[uav_id], self.ual[uav_id], self.batteries[uav_id]
                self._forget_body(vehicle.body_id)
                return "uav"
        raise SpawnError(f"name: no model called '{name}'; models: {', '.join(self.names()) or 'none'}")

    def place_airborne(self, uav_id: int, position: Sequence[float], yaw: float = 0.0) -> None:
        """Put a UAV of the light model at `position` at rest, FLYING_AUTO and holding there, as if it had flown
        there: how a learning environment starts an episode without flying the take-off. Contacts it had end
        without a report; new ones from there are reported as usual. The light model only: its state is the
        pose and velocity, where the dynamic model's controller keeps state of its own."""
        if uav_id not in self.vehicles:
            raise SpawnError(f"uav_id: {uav_id} is not flying here; UAVs: {sorted(self.vehicles) or 'none'}")
        vehicle = self.vehicles[uav_id]
        if vehicle.flight_model != "light":
            raise SpawnError(f"uav_id: UAV {uav_id} flies the {vehicle.flight_model} model; only a light UAV can be "
                             "placed in the air (fly the take-off of the others)")
        start = _finite("position", position)
        _finite("yaw", [yaw], size=1)
        vehicle.position, vehicle.velocity, vehicle.angular_velocity = start.copy(), np.zeros(3), np.zeros(3)
        vehicle.orientation = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
        p.resetBasePositionAndOrientation(vehicle.body_id, start, vehicle.orientation, physicsClientId=self.client)
        p.resetBaseVelocity(vehicle.body_id, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=self.client)
        self._touching = {pair for pair in self._touching if vehicle.body_id not in pair}
        self.ual[uav_id].start_airborne()

    # --- time ------------------------------------------------------------------------------------------------
    def step(self) -> list[Contact]:
        groups = [(model, [v for v in self.vehicles.values() if v.flight_model == kind])
                  for kind, model in self.models.items()]
        groups = [(model, group) for model, group in groups if group]
        for model, group in groups:
            if model.follows_guidance:
                model.apply_controls(group, *guidance.velocity_commands(group))
            else:
                model.apply_controls(group)
        p.stepSimulation(physicsClientId=self.client)
        self.steps += 1
        for model, group in groups:
            model.read_state(group)
        now = self.time
        for logic in self.ual.values():
            logic.update(now)
        return self._new_contacts()

    def drain_batteries(self, dt: float) -> None:
        """Advance every battery by dt; an empty one makes its UAV land, as an autopilot failsafe does."""
        for uav_id, battery in self.batteries.items():
            vehicle = self.vehicles[uav_id]
            battery.update(dt, vehicle.motors_on, float(np.linalg.norm(vehicle.velocity)), float(vehicle.velocity[2]))
            if battery.depleted and self.ual[uav_id].state in (UalState.TAKING_OFF, UalState.FLYING_AUTO):
                self.ual[uav_id].failsafe_land()

    def _new_contacts(self) -> list[Contact]:
        touching: set[tuple[int, int]] = set()
        contacts: list[Contact] = []
        for point in p.getContactPoints(physicsClientId=self.client):
            a, b = point[1], point[2]
            pair = (min(a, b), max(a, b))
            if pair in touching:
                continue
            touching.add(pair)
            if pair in self._touching:
                continue  # reported when it began
            contacts.extend(self._describe(a, b, np.array(point[5]), np.array(point[6])))
        self._touching = touching
        return contacts

    def _describe(self, a: int, b: int, on_a: np.ndarray, on_b: np.ndarray) -> list[Contact]:
        found = []
        for mine, other, touch_point in ((a, b, on_a), (b, a, on_b)):
            kind, name = self._by_body.get(mine, ("", ""))
            if kind != "uav":
                continue
            vehicle = self.vehicles[int(name)]
            other_kind, other_name = self._by_body.get(other, ("obstacle", str(other)))
            other_velocity = self.vehicles[int(other_name)].velocity if other_kind == "uav" else np.zeros(3)
            speed = float(np.linalg.norm(vehicle.velocity - other_velocity))
            impact = speed
            if other_kind == "ground" and vehicle.flight_model == "fixed_wing" and self.ual[vehicle.uav_id].state in (
                    UalState.TAKING_OFF, UalState.LANDING, UalState.LANDED_ARMED):
                impact = abs(float(vehicle.velocity[2]))  # a plane launches and lands running: only the sink hits
            if other_kind == "ground" and impact < self.ground_impact_speed:
                continue  # landing and sitting on the ground are not collisions
            if other_kind == "uav":
                distance = np.linalg.norm(self.vehicles[int(other_name)].position - vehicle.position)
            else:
                distance = np.linalg.norm(touch_point - vehicle.position)
            found.append(Contact(vehicle.uav_id, other_kind, other_name, vehicle.position.copy(),
                                 float(distance), speed))
        return found

    # --- helpers ---------------------------------------------------------------------------------------------
    def _check_new_name(self, name: str) -> None:
        if not name or not name.replace("_", "").replace("-", "").replace("/", "").isalnum():
            raise SpawnError(f"name: '{name}' must be non-empty letters, digits, '_', '-' or '/'")
        if name in self.names():
            raise SpawnError(f"name: '{name}' is taken; delete it first or choose another name")

    def _forget_body(self, body_id: int) -> None:
        p.removeBody(body_id, physicsClientId=self.client)
        del self._by_body[body_id]
        self._touching = {pair for pair in self._touching if body_id not in pair}


def _flight_model_for(airframe: str, frame: Airframe, asked: str) -> str:
    """The model that flies `frame`: a fixed wing always flies fixed_wing ("light", the default every
    spawner sends, means "the kinematic model of this airframe"); a multirotor never does."""
    if frame.is_fixed_wing:
        if asked == "dynamic":
            raise SpawnError(f"flight_model: '{airframe}' has no rotors ({frame.source}: body.rotors = 0); "
                             "fly it with the fixed_wing model (or light, which picks it for a fixed wing)")
        return "fixed_wing"
    if asked == "fixed_wing":
        assert frame.body is not None  # the caller's require_physics: every kind of airframe has one
        raise SpawnError(f"flight_model: '{airframe}' is a multirotor ({frame.source}: body.rotors = "
                         f"{frame.body.rotors}); fixed_wing flies airframes with a fixed_wing block, "
                         "use light or dynamic")
    return asked


def _finite(field: str, values, size: int = 3) -> np.ndarray:
    array = np.asarray(values, dtype=float).ravel()
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise SpawnError(f"{field}: {array.tolist()} must be {size} finite number(s)")
    return array
