"""Airframe files: `src/magna_common/airframes/<model>.json`, parsed once into typed objects.

The first keys are those of the original ROS-MAGNA files (autopilot, ual_use,
safety_radius, max_speed, accepted_target_radius, ...). MAGNA adds the physical
description the simulator needs: a multirotor has four blocks (body, propulsion,
limits, battery); a fixed wing (body.rotors = 0) has body, fixed_wing and battery.
A file with only the original keys still loads; the simulator then refuses it
with an error that names the missing block.
"""
from __future__ import annotations

import json
import math
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

AIRFRAME_DIR = Path(__file__).resolve().parents[2] / "airframes"


class AirframeError(ValueError):
    """A bad or missing airframe file; the message names the file and the field."""


@dataclass(frozen=True)
class Body:
    mass: float  # kg
    rotors: int  # 0 for a fixed wing (no dynamic multirotor model)
    arm_length: float  # m, centre to rotor axis
    radius: float  # m, collision cylinder
    height: float  # m, collision cylinder
    inertia: tuple[float, float, float]  # kg m^2, principal moments Ixx Iyy Izz


@dataclass(frozen=True)
class Propulsion:
    max_rotor_thrust: float  # N per rotor
    torque_to_thrust: float  # m, rotor drag torque per newton of thrust
    drag_coefficients: tuple[float, float, float]  # N/(m/s), body-axis linear drag


@dataclass(frozen=True)
class Limits:
    max_horizontal_speed: float  # m/s
    max_vertical_speed: float  # m/s
    max_yaw_rate: float  # rad/s
    max_tilt: float  # rad
    velocity_time_constant: float  # s, first-order lag of the light model


@dataclass(frozen=True)
class Battery:
    capacity_mah: float
    voltage: float  # V, nominal
    idle_power_w: float  # W drawn while landed and armed
    hover_power_w: float | None = None  # W drawn while hovering (multirotors; required for them)
    cruise_power_w: float | None = None  # W drawn in level flight at cruise_speed (fixed wings; required for them)


GRAVITY = 9.81  # m/s^2


@dataclass(frozen=True)
class FixedWing:
    """How a fixed wing flies (PX4's fixed-wing airspeed, turn, climb and landing settings in spirit)."""

    stall_speed: float  # m/s: below this the wing does not lift
    min_speed: float  # m/s: slowest airspeed flown in the air (landing approach); above stall_speed
    cruise_speed: float  # m/s: airspeed of transits and loiters
    max_speed: float  # m/s: fastest airspeed a velocity command may ask for
    max_bank_angle: float  # rad: sets the tightest turn, radius = speed^2 / (g tan(bank))
    max_climb_rate: float  # m/s
    max_sink_rate: float  # m/s
    loiter_radius: float  # m: a held pose or reached waypoint is circled at this radius
    landing_slope: float  # rad: glide-path angle of the landing approach
    min_flight_height: float  # m: waypoints and holds below this height are flown at it
    rollout_deceleration: float  # m/s^2: braking on the ground after touchdown

    def min_turn_radius(self, speed: float | None = None) -> float:
        """Tightest turn radius (m) at `speed` (default cruise_speed) and max_bank_angle."""
        speed = self.cruise_speed if speed is None else speed
        return speed * speed / (GRAVITY * math.tan(self.max_bank_angle))


@dataclass(frozen=True)
class Airframe:
    model: str
    source: Path
    autopilot: str
    ual_use: int
    safety_radius: float
    max_speed: float
    accepted_target_radius: float
    body: Body | None = None
    propulsion: Propulsion | None = None
    limits: Limits | None = None
    battery: Battery | None = None
    fixed_wing: FixedWing | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # original keys MAGNA does not use

    @property
    def is_fixed_wing(self) -> bool:
        """A fixed wing cannot hover: it has a fixed_wing block (and body.rotors = 0)."""
        return self.fixed_wing is not None or (self.body is not None and self.body.rotors == 0)

    def require_physics(self) -> None:
        """Raise AirframeError unless the physical blocks of its kind are present."""
        blocks: tuple[str, ...]
        if self.is_fixed_wing:
            blocks, kind, example = ("body", "fixed_wing", "battery"), "a fixed wing", "plane"
        else:
            blocks, kind, example = ("body", "propulsion", "limits", "battery"), "a multirotor", "iris"
        for block in blocks:
            if getattr(self, block) is None:
                raise AirframeError(
                    f"{self.source}: '{block}': missing; the simulator needs the {', '.join(blocks)} blocks "
                    f"for {kind} (see src/magna_common/airframes/{example}.json)")


_BLOCKS = {"body": Body, "propulsion": Propulsion, "limits": Limits, "battery": Battery, "fixed_wing": FixedWing}
_POSITIVE = ("mass", "radius", "height")
_TOP_LEVEL = ("autopilot", "ual_use", "safety_radius", "max_speed", "accepted_target_radius")


def available_models(directory: Path = AIRFRAME_DIR) -> list[str]:
    return sorted(p.stem for p in directory.glob("*.json"))


def load_airframe(model: str, directory: Path = AIRFRAME_DIR) -> Airframe:
    path = Path(directory) / f"{model}.json"
    if not path.is_file():
        raise AirframeError(f"{path}: no such airframe; known models: {', '.join(available_models(directory))}")
    try:
        raw = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise AirframeError(f"{path}: not valid JSON: {err}") from None
    return parse_airframe(model, raw, path)


def parse_airframe(model: str, raw: Any, source: Path) -> Airframe:
    if not isinstance(raw, dict):
        raise AirframeError(f"{source}: the top level must be a JSON object")
    for key in _TOP_LEVEL:
        if key not in raw:
            raise AirframeError(f"{source}: '{key}': missing (every airframe has {', '.join(_TOP_LEVEL)})")
    values: dict[str, Any] = {}
    for key in _TOP_LEVEL:
        values[key] = raw[key] if key == "autopilot" else _number(raw[key], source, key)
    values["ual_use"] = int(values["ual_use"])
    for block, cls in _BLOCKS.items():
        if block in raw:
            values[block] = _parse_block(cls, raw[block], source, block)
    extra = {k: v for k, v in raw.items() if k not in _TOP_LEVEL and k not in _BLOCKS}
    airframe = Airframe(model=model, source=source, extra=extra, **values)
    _check_kind(airframe)
    return airframe


def _check_kind(af: Airframe) -> None:
    """The blocks must agree on what flies: a multirotor hovers, a fixed wing circles and cannot stop."""
    src = af.source
    if af.body is not None and af.body.rotors == 0 and af.fixed_wing is None:
        raise AirframeError(f"{src}: 'fixed_wing': missing; body.rotors = 0 makes a fixed wing, which needs its "
                            "speeds, bank angle, climb and sink rates, loiter radius and landing slope "
                            "(see src/magna_common/airframes/plane.json)")
    if af.fixed_wing is None:
        if af.battery is not None and af.battery.hover_power_w is None:
            raise AirframeError(f"{src}: 'battery.hover_power_w': missing (W drawn while hovering)")
        return
    if af.body is not None and af.body.rotors != 0:
        raise AirframeError(f"{src}: 'body.rotors': {af.body.rotors}, but the file has a fixed_wing block; "
                            "a fixed wing has 0 rotors (remove fixed_wing for a multirotor)")
    fw = af.fixed_wing
    speeds = ("stall_speed", "min_speed", "cruise_speed", "max_speed")
    for slower, faster in zip(speeds, speeds[1:], strict=False):
        low, high = getattr(fw, slower), getattr(fw, faster)
        if not (low < high or (slower != "stall_speed" and low == high)):
            raise AirframeError(f"{src}: 'fixed_wing.{faster}': {high:g} m/s must be above fixed_wing.{slower} "
                                f"({low:g} m/s); the speeds go stall_speed < min_speed <= cruise_speed <= max_speed")
    if fw.stall_speed <= 0:
        raise AirframeError(f"{src}: 'fixed_wing.stall_speed': must be positive, got {fw.stall_speed:g}")
    if not 0.05 <= fw.max_bank_angle <= 1.2:
        raise AirframeError(f"{src}: 'fixed_wing.max_bank_angle': {fw.max_bank_angle:g} rad; give 0.05 to 1.2 rad "
                            "(3 to 69 degrees)")
    for name in ("max_climb_rate", "max_sink_rate"):
        rate = getattr(fw, name)
        if not 0 < rate < fw.min_speed:
            raise AirframeError(f"{src}: 'fixed_wing.{name}': {rate:g} m/s; give a positive rate below "
                                f"fixed_wing.min_speed ({fw.min_speed:g} m/s)")
    if not 0.01 <= fw.landing_slope <= 0.35:
        raise AirframeError(f"{src}: 'fixed_wing.landing_slope': {fw.landing_slope:g} rad; give a glide path of "
                            "0.01 to 0.35 rad (0.6 to 20 degrees)")
    if fw.rollout_deceleration <= 0:
        raise AirframeError(f"{src}: 'fixed_wing.rollout_deceleration': must be positive, got "
                            f"{fw.rollout_deceleration:g} m/s^2")
    tightest = fw.min_turn_radius()
    if fw.loiter_radius < tightest:
        raise AirframeError(f"{src}: 'fixed_wing.loiter_radius': {fw.loiter_radius:g} m is tighter than the "
                            f"{tightest:.1f} m turn at cruise_speed {fw.cruise_speed:g} m/s and max_bank_angle "
                            f"{fw.max_bank_angle:g} rad; use at least {math.ceil(tightest)} m")
    if af.accepted_target_radius <= fw.loiter_radius:
        raise AirframeError(f"{src}: 'accepted_target_radius': {af.accepted_target_radius:g} m is not beyond the "
                            f"{fw.loiter_radius:g} m loiter circle (fixed_wing.loiter_radius): a plane cannot "
                            f"stop on a waypoint, it circles it, so it would never reach one; give more than "
                            f"{fw.loiter_radius:g} m")
    if af.battery is not None:
        if af.battery.cruise_power_w is None:
            raise AirframeError(f"{src}: 'battery.cruise_power_w': missing; a fixed wing draws its power in level "
                                "flight at fixed_wing.cruise_speed (W)")
        if af.battery.hover_power_w is not None:
            raise AirframeError(f"{src}: 'battery.hover_power_w': a fixed wing cannot hover; remove it and give "
                                "battery.cruise_power_w")


def _parse_block(cls, raw: Any, source: Path, block: str):
    if not isinstance(raw, dict):
        raise AirframeError(f"{source}: '{block}': must be an object with keys {[f.name for f in fields(cls)]}")
    unknown = set(raw) - {f.name for f in fields(cls)}
    if unknown:
        raise AirframeError(f"{source}: '{block}.{sorted(unknown)[0]}': unknown key; "
                            f"allowed: {', '.join(f.name for f in fields(cls))}")
    values: dict[str, Any] = {}
    for f in fields(cls):
        where = f"{block}.{f.name}"
        if f.name not in raw:
            if f.default is not MISSING:
                continue  # optional: which of them a kind of airframe needs is checked in _check_kind
            raise AirframeError(f"{source}: '{where}': missing")
        value = raw[f.name]
        if isinstance(value, list):
            if len(value) != 3:
                raise AirframeError(f"{source}: '{where}': expected 3 numbers, got {len(value)}")
            values[f.name] = tuple(_number(v, source, where, positive=True) for v in value)
        elif f.name == "rotors":
            if not isinstance(value, int) or value < 0 or value in (1, 2):
                raise AirframeError(f"{source}: '{where}': expected 0 (fixed wing) or 3 or more rotors, got {value!r}")
            values[f.name] = value
        else:
            values[f.name] = _number(value, source, where, positive=f.name in _POSITIVE or (
                block == "fixed_wing" and f.name != "min_flight_height"))
    return cls(**values)


def _number(value: Any, source: Path, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise AirframeError(f"{source}: '{where}': expected a finite number, got {value!r}")
    if value < 0 or (positive and value == 0):
        raise AirframeError(f"{source}: '{where}': must be {'positive' if positive else 'zero or more'}, got {value}")
    return float(value)
