"""Airframe files: `src/magna_uav/airframes/<model>.json`, parsed once into typed objects.

The first keys are those of the original ROS-MAGNA files (autopilot, ual_use,
safety_radius, max_speed, accepted_target_radius, ...). MAGNA adds the physical
description the simulator needs in four blocks: body, propulsion, limits, battery.
A file with only the original keys still loads; the simulator then refuses it
with an error that names the missing block.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields
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
    hover_power_w: float  # W drawn while flying at hover
    idle_power_w: float  # W drawn while landed and armed


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
    extra: dict[str, Any] = field(default_factory=dict)  # original keys MAGNA does not use

    def require_physics(self) -> None:
        """Raise AirframeError unless the four physical blocks are present."""
        for block in ("body", "propulsion", "limits", "battery"):
            if getattr(self, block) is None:
                raise AirframeError(
                    f"{self.source}: '{block}': missing; the simulator needs the body, propulsion, "
                    f"limits and battery blocks (see src/magna_uav/airframes/iris.json)")


_BLOCKS = {"body": Body, "propulsion": Propulsion, "limits": Limits, "battery": Battery}
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
    return Airframe(model=model, source=source, extra=extra, **values)


def _parse_block(cls, raw: Any, source: Path, block: str):
    if not isinstance(raw, dict):
        raise AirframeError(f"{source}: '{block}': must be an object with keys {[f.name for f in fields(cls)]}")
    unknown = set(raw) - {f.name for f in fields(cls)}
    if unknown:
        raise AirframeError(f"{source}: '{block}.{sorted(unknown)[0]}': unknown key; "
                            f"allowed: {', '.join(f.name for f in fields(cls))}")
    values = {}
    for f in fields(cls):
        where = f"{block}.{f.name}"
        if f.name not in raw:
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
            values[f.name] = _number(value, source, where, positive=f.name in ("mass", "radius", "height"))
    return cls(**values)


def _number(value: Any, source: Path, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise AirframeError(f"{source}: '{where}': expected a finite number, got {value!r}")
    if value < 0 or (positive and value == 0):
        raise AirframeError(f"{source}: '{where}': must be {'positive' if positive else 'zero or more'}, got {value}")
    return float(value)
