"""A UAV battery: charge drawn by a power model, voltage from a LiPo resting curve.

Power drawn (W):
  * landed (armed or not, the autopilot and motors at idle): `idle_power_w`;
  * flying: `hover_power_w * (1 + SPEED_POWER_FACTOR * speed**2)`, speed in m/s. With
    SPEED_POWER_FACTOR = 0.005 s^2/m^2 a multirotor needs 12.5% more than hover at
    5 m/s and 50% more at 10 m/s: a rough stand-in for parasite drag, which grows
    with speed squared (the dip of translational lift at low speed is left out).
    A fixed wing cannot hover: its flying power comes from `flying_power(speed, climb_rate)`
    (fixed_wing.flying_power: cruise power from the airframe, with speed and climb).

Voltage (V) is the open-circuit voltage of one LiPo cell at the state of charge,
piecewise linear through typical resting values (4.20 V full, 3.84 V at half,
3.30 V empty), times nominal voltage / 3.7 V (3.7 V being a cell's nominal
voltage): 3 cells for an 11.1 V pack. There is no internal resistance, so the
current is power / voltage and rises as the voltage sags. Charge is in Ah.

`capacity_fraction` starts the battery partly charged and `drain_factor` scales
every power draw, so a test mission can reach a low battery in seconds.

`floor_fraction` keeps the charge from falling below that fraction, as PX4's SITL battery
does (SIM_BAT_MIN_PCT, 50 % by default): the original ROS-MAGNA flew its simulated UAVs
on that battery, so its long missions never met a low battery. 0 (the default) is a
real battery that runs empty.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from magna_common.airframes import Battery

SPEED_POWER_FACTOR = 0.005  # s^2/m^2
CELL_NOMINAL_V = 3.7
# State of charge (0..1) -> resting voltage of one LiPo cell.
_CELL_SOC = np.array([0.0, 0.05, 0.10, 0.20, 0.50, 0.80, 0.90, 1.00])
_CELL_V = np.array([3.30, 3.61, 3.69, 3.73, 3.84, 4.02, 4.11, 4.20])


class BatteryModel:
    def __init__(self, spec: Battery, capacity_fraction: float = 1.0, drain_factor: float = 1.0,
                 flying_power: Callable[[float, float], float] | None = None, floor_fraction: float = 0.0):
        if not 0.0 <= capacity_fraction <= 1.0:
            raise ValueError(f"capacity_fraction: must be 0..1 (the starting charge), got {capacity_fraction}")
        if not 0.0 <= floor_fraction < 1.0:
            raise ValueError(f"floor_fraction: must be 0..1 (the charge it never falls below), got {floor_fraction}")
        if not (math.isfinite(drain_factor) and drain_factor > 0.0):
            raise ValueError(f"drain_factor: must be a positive number, got {drain_factor}")
        if spec.capacity_mah <= 0.0 or spec.voltage <= 0.0:
            raise ValueError(f"battery: capacity_mah and voltage must be positive, got {spec}")
        if flying_power is None and spec.hover_power_w is None:
            raise ValueError(f"battery: hover_power_w is needed to fly (or a flying_power model), got {spec}")
        self.spec = spec
        self.drain_factor = drain_factor
        self.flying_power = flying_power
        self.capacity_ah = spec.capacity_mah / 1000.0
        self.charge_ah = self.capacity_ah * capacity_fraction
        self.floor_ah = self.capacity_ah * floor_fraction
        self.power = 0.0  # W, drawn in the last update
        self.current = 0.0  # A, drawn in the last update (positive while discharging)

    @property
    def percentage(self) -> float:
        """State of charge, 0..1 (sensor_msgs/BatteryState.percentage)."""
        return self.charge_ah / self.capacity_ah

    @property
    def voltage(self) -> float:
        cell = float(np.interp(self.percentage, _CELL_SOC, _CELL_V))
        return cell * self.spec.voltage / CELL_NOMINAL_V

    @property
    def depleted(self) -> bool:
        return self.charge_ah <= 0.0

    def update(self, dt: float, flying: bool, speed: float = 0.0, climb_rate: float = 0.0) -> None:
        """Draw `dt` seconds of power; `speed` and `climb_rate` (m/s) only count while flying."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"dt: must be a finite number of seconds >= 0, got {dt}")
        if not math.isfinite(speed):
            raise ValueError(f"speed: must be finite, got {speed}")
        if flying and self.flying_power is not None:
            power = self.flying_power(speed, climb_rate)
        elif flying:
            hover_power = self.spec.hover_power_w
            assert hover_power is not None  # __init__ refuses a battery with neither it nor a flying_power model
            power = hover_power * (1.0 + SPEED_POWER_FACTOR * speed * speed)
        else:
            power = self.spec.idle_power_w
        if self.depleted:
            self.power = self.current = 0.0  # nothing left to give
            return
        self.power = power * self.drain_factor
        self.current = self.power / self.voltage
        floor = min(self.floor_ah, self.charge_ah)  # a battery started below its floor stays where it is
        self.charge_ah = max(floor, self.charge_ah - self.current * dt / 3600.0)
