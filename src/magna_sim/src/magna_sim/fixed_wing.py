"""The fixed-wing flight model: a kinematic plane that cannot hover (airframes with a fixed_wing block).

The plane flies along its heading at an airspeed kept between the airframe's
min_speed and max_speed (both above stall_speed) while airborne. It turns by
banking: the turn rate never exceeds g tan(max_bank_angle) / speed, so no turn is
tighter than speed^2 / (g tan(max_bank_angle)). It climbs and sinks at most at
max_climb_rate and max_sink_rate. The pose is integrated here and placed in
pybullet, which only detects contacts (as in the light model); the orientation
shows the bank and the flight-path angle.

What each setpoint means, as PX4's fixed-wing position control does it:

- POSITION (go_to_waypoint, set_pose, a hold): fly to the point and circle it at
  loiter_radius, clockwise seen from above (PX4's default), at cruise_speed and the
  point's height (raised to min_flight_height). A plane cannot stop on a waypoint.
- TAKE_OFF (runway-less, as a hand or catapult launch): leave at min_speed, climb
  along the heading to the height, then circle the point above the launch spot.
- LAND (PX4's land mode): spiral down at max_sink_rate on a loiter circle joined where
  the plane is, down to the final-approach height (two loiter radii of glide path);
  then hold the heading, glide at landing_slope at min_speed, flare near the ground,
  touch down and brake to a stop at rollout_deceleration.
- VELOCITY: the course, speed and climb of the command, each within the limits:
  a slow or zero command flies at min_speed on the commanded course (or the current
  one when the command has no horizontal part); the yaw rate command is ignored,
  a plane's heading is its course.

`flying_power` is the battery draw of a plane: the cruise power at cruise_speed,
split evenly into parasite (~ speed^3) and induced (~ 1/speed) power, so cruise_speed
is the speed of longest range; climbing costs m g climb_rate / PROPULSIVE_EFFICIENCY
more and sinking that much less, down to the idle power.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pybullet as p

from magna_common.airframes import GRAVITY, Airframe, AirframeError, FixedWing

from .vehicle import Manoeuvre, Setpoint, SetpointMode, Vehicle

HEADING_GAIN = 1.5  # 1/s: turn rate asked per radian of course error
LOITER_SHARPNESS = 2.0  # how steeply the loiter field turns toward its circle: atan(k (d - R) / R)
LOITER_DIRECTION = -1.0  # clockwise seen from above, PX4's default loiter direction
ALTITUDE_GAIN = 0.8  # 1/s: climb rate asked per metre of height error
ROLL_TIME_CONSTANT = 0.3  # s: the bank, hence the turn rate, follows its demand with this lag
CLIMB_TIME_CONSTANT = 0.5  # s
SPEED_TIME_CONSTANT = 1.5  # s: airspeed changes slowly (thrust against drag)
FLARE_TIME = 1.5  # s: near the ground the sink rate is height / FLARE_TIME ...
TOUCHDOWN_SINK = 0.3  # m/s: ... but at least this, so it touches down (gently) rather than floating
CLIMB_OUT_DONE = 0.5  # m below the take-off height where the climb-out ends and the circling begins
PROPULSIVE_EFFICIENCY = 0.5  # electrical to climbing power (motor, propeller, controller)
MIN_AIRBORNE_HEIGHT = 1e-3  # m: lower than this the plane is on the ground


def held_point(fw: FixedWing, position: np.ndarray) -> np.ndarray:
    """The point a plane circles for a setpoint: its height raised to min_flight_height."""
    point = np.array(position, dtype=float)
    point[2] = max(point[2], fw.min_flight_height)
    return point


def on_station(fw: FixedWing, target: np.ndarray, position: np.ndarray, tolerance: float) -> bool:
    """Is the plane at the setpoint, that is on (or inside) its loiter circle at its height?"""
    distance = float(np.linalg.norm(held_point(fw, target) - position))
    return distance <= fw.loiter_radius * 1.05 + tolerance


def final_approach_height(fw: FixedWing) -> float:
    """Height (m) of the straight final approach: two loiter radii of glide at landing_slope."""
    return 2.0 * fw.loiter_radius * math.tan(fw.landing_slope)


def max_turn_rate(fw: FixedWing, horizontal_speed: float) -> float:
    """Fastest turn (rad/s) at this speed: a coordinated turn at max_bank_angle."""
    return GRAVITY * math.tan(fw.max_bank_angle) / max(horizontal_speed, 1e-3)


def flying_power(airframe: Airframe) -> Callable[[float, float], float]:
    """Electrical power (W) drawn in flight at (airspeed m/s, climb rate m/s)."""
    fw, battery, body = airframe.fixed_wing, airframe.battery, airframe.body
    if fw is None or body is None or battery is None or battery.cruise_power_w is None:
        raise AirframeError(f"{airframe.source}: a fixed wing's flying power needs its body, fixed_wing and "
                            "battery blocks, with battery.cruise_power_w")
    min_speed, cruise_speed, mass = fw.min_speed, fw.cruise_speed, body.mass
    cruise_power, idle_power = battery.cruise_power_w, battery.idle_power_w

    def power(speed: float, climb_rate: float) -> float:
        ratio = max(speed, min_speed) / cruise_speed  # on the ground the motor still pulls as in flight
        level = cruise_power * 0.5 * (ratio ** 3 + 1.0 / ratio)
        return max(idle_power, level + mass * GRAVITY * climb_rate / PROPULSIVE_EFFICIENCY)

    return power


@dataclass
class _PlaneState:
    wing: FixedWing  # the airframe's fixed_wing block
    speed: float = 0.0  # m/s along the flight path (airspeed; no wind)
    turn_rate: float = 0.0  # rad/s
    climb: float = 0.0  # m/s
    setpoint: Setpoint | None = None  # the setpoint `course` and `climbed_out` were worked out for
    course: float = 0.0  # rad: heading held during a climb-out or a landing approach
    climbed_out: bool = False
    centre: np.ndarray | None = None  # of the descending spiral before a landing approach
    on_final: bool = False  # on the straight final approach of a landing


class FixedWingModel:
    name = "fixed_wing"
    follows_guidance: Literal[False] = False  # a plane flies its setpoints itself (see the module docstring)

    def __init__(self, client: int, physics_dt: float):
        self.client = client
        self.dt = physics_dt
        self._states: dict[Vehicle, _PlaneState] = {}

    def attach(self, vehicle: Vehicle) -> None:
        frame = vehicle.airframe
        if frame.fixed_wing is None:
            raise AirframeError(f"{frame.source}: 'fixed_wing': missing; the fixed_wing flight model flies fixed "
                                f"wings only, use the light or dynamic model for '{frame.model}'")
        self._states[vehicle] = _PlaneState(frame.fixed_wing)

    def detach(self, vehicle: Vehicle) -> None:
        self._states.pop(vehicle, None)

    def state(self, vehicle: Vehicle) -> _PlaneState:
        """The plane's own state (airspeed, turn rate, climb), for tests and batteries."""
        return self._states[vehicle]

    def apply_controls(self, vehicles: Sequence[Vehicle]) -> None:
        for vehicle in vehicles:
            self._fly(vehicle, self._states[vehicle])

    def read_state(self, vehicles: Sequence[Vehicle]) -> None:
        pass  # the state is ours; contacts do not push a plane

    # --- one plane, one step ----------------------------------------------------------------------------------
    def _fly(self, vehicle: Vehicle, st: _PlaneState) -> None:
        fw, setpoint, dt = st.wing, vehicle.setpoint, self.dt
        if setpoint is not st.setpoint:
            self._new_setpoint(vehicle, st, setpoint)
        position = vehicle.position.copy()
        heading = vehicle.yaw
        on_ground = position[2] <= MIN_AIRBORNE_HEIGHT
        if setpoint.mode == SetpointMode.OFF or (setpoint.manoeuvre == Manoeuvre.LAND and on_ground):
            # On the ground (or parked with nothing to do): roll straight on, braking to a stop.
            st.speed = max(0.0, st.speed - fw.rollout_deceleration * dt)
            st.turn_rate = st.climb = 0.0
            if on_ground:
                position[2] = 0.0
        else:
            course, speed, climb, feedforward = self._aim(vehicle, st, fw, setpoint)
            st.speed += (speed - st.speed) * (1.0 - math.exp(-dt / SPEED_TIME_CONSTANT))
            st.speed = min(max(st.speed, fw.min_speed), fw.max_speed)  # never slower than min_speed in the air
            st.climb += (climb - st.climb) * (1.0 - math.exp(-dt / CLIMB_TIME_CONSTANT))
            st.climb = min(max(st.climb, -fw.max_sink_rate), fw.max_climb_rate)
            horizontal = math.sqrt(st.speed ** 2 - st.climb ** 2)
            limit = max_turn_rate(fw, horizontal)
            wanted = min(max(feedforward + HEADING_GAIN * _wrap(course - heading), -limit), limit)
            st.turn_rate += (wanted - st.turn_rate) * (1.0 - math.exp(-dt / ROLL_TIME_CONSTANT))
            st.turn_rate = min(max(st.turn_rate, -limit), limit)
        horizontal = math.sqrt(max(st.speed ** 2 - st.climb ** 2, 0.0))
        heading = _wrap(heading + st.turn_rate * dt)
        velocity = np.array([horizontal * math.cos(heading), horizontal * math.sin(heading), st.climb])
        position += velocity * dt
        if position[2] < 0.0:  # touchdown: the ground stops the descent
            position[2] = 0.0
            velocity[2] = st.climb = 0.0
        bank = -math.atan(horizontal * st.turn_rate / GRAVITY)  # a left (positive) turn lowers the left wing
        pitch = -math.asin(st.climb / st.speed) if st.speed > 0.0 else 0.0  # nose up is negative about y
        vehicle.position = position
        vehicle.velocity = velocity
        vehicle.set_attitude(_quaternion(bank, pitch, heading), heading)
        vehicle.angular_velocity = np.array([0.0, 0.0, st.turn_rate])
        p.resetBasePositionAndOrientation(vehicle.body_id, position, vehicle.orientation, physicsClientId=self.client)
        p.resetBaseVelocity(vehicle.body_id, velocity, vehicle.angular_velocity, physicsClientId=self.client)

    def _new_setpoint(self, vehicle: Vehicle, st: _PlaneState, setpoint: Setpoint) -> None:
        previous, st.setpoint = st.setpoint, setpoint
        if (previous is not None and previous.mode == setpoint.mode and previous.manoeuvre == setpoint.manoeuvre
                and np.array_equal(previous.position, setpoint.position)):
            return  # the same order sent again (commanders repeat waypoints and holds): keep the manoeuvre going
        fw, heading = st.wing, vehicle.yaw
        st.course, st.climbed_out, st.on_final = heading, False, False
        if setpoint.manoeuvre == Manoeuvre.TAKE_OFF:
            st.speed = max(st.speed, fw.min_speed)  # launched (hand or catapult)
        if setpoint.manoeuvre == Manoeuvre.LAND:  # the spiral's circle passes through the plane, on its course
            side = -LOITER_DIRECTION * np.array([math.sin(heading), -math.cos(heading), 0.0])
            st.centre = vehicle.position + fw.loiter_radius * side

    def _aim(self, vehicle: Vehicle, st: _PlaneState, fw: FixedWing, setpoint: Setpoint):
        """(course rad, airspeed m/s, climb rate m/s, feed-forward turn rate rad/s) wanted now."""
        position = vehicle.position
        if setpoint.mode == SetpointMode.VELOCITY:
            command = setpoint.velocity
            across = math.hypot(command[0], command[1])
            course = math.atan2(command[1], command[0]) if across > 1e-3 else vehicle.yaw
            climb = float(command[2])
            if position[2] < fw.min_flight_height:  # do not let a command fly it into the ground
                climb = max(climb, ALTITUDE_GAIN * (fw.min_flight_height - position[2]))
            return course, float(np.linalg.norm(command)), climb, 0.0
        if setpoint.manoeuvre == Manoeuvre.LAND:
            final = final_approach_height(fw)
            if not st.on_final and position[2] > final + CLIMB_OUT_DONE:
                assert st.centre is not None  # _new_setpoint placed the spiral when this LAND setpoint came
                course, feedforward = self._loiter(vehicle, fw, st.centre)
                return course, fw.cruise_speed, -ALTITUDE_GAIN * (position[2] - final), feedforward
            if not st.on_final:
                st.on_final, st.course = True, vehicle.yaw  # straight on from where the spiral left off
            glide = fw.min_speed * math.sin(fw.landing_slope)
            return st.course, fw.min_speed, -min(glide, max(TOUCHDOWN_SINK, position[2] / FLARE_TIME)), 0.0
        if setpoint.manoeuvre == Manoeuvre.TAKE_OFF:
            height_left = setpoint.position[2] - position[2]
            st.climbed_out = st.climbed_out or height_left < CLIMB_OUT_DONE
            if not st.climbed_out:
                return st.course, fw.cruise_speed, ALTITUDE_GAIN * height_left, 0.0
            centre = np.array(setpoint.position, dtype=float)  # the take-off height, even below min_flight_height
        else:
            centre = held_point(fw, setpoint.position)
        course, feedforward = self._loiter(vehicle, fw, centre)
        return course, fw.cruise_speed, ALTITUDE_GAIN * (centre[2] - position[2]), feedforward

    @staticmethod
    def _loiter(vehicle: Vehicle, fw: FixedWing, centre: np.ndarray) -> tuple[float, float]:
        """Course of a vector field that leads to the loiter circle and round it (Nelson et al., 2007):
        far away it points at the centre, on the circle along it, inside it outwards."""
        dx, dy = vehicle.position[0] - centre[0], vehicle.position[1] - centre[1]
        distance = math.hypot(dx, dy)
        radius = fw.loiter_radius
        approach = math.atan(LOITER_SHARPNESS * (distance - radius) / radius)
        course = math.atan2(dy, dx) + LOITER_DIRECTION * (0.5 * math.pi + approach)
        # Going round the circle the course turns at speed / radius; fade that in as the plane joins it.
        speed = float(np.linalg.norm(vehicle.velocity[:2]))
        feedforward = LOITER_DIRECTION * speed * math.cos(approach) / max(distance, radius)
        return course, feedforward


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _quaternion(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """x, y, z, w of the rotation yaw about z, then pitch about y, then roll about x."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return np.array([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])
