"""What each UAL action is in MAVLink: arming, flight modes, take-off, home, and the set-points streamed.

Everything here is already in the autopilot's frame (local NED, FRD); the backend converts from ROS.
PX4 takes its modes through MAV_CMD_DO_SET_MODE as (custom-mode flag, main mode, sub mode);
ArduPilot Copter as (custom-mode flag, mode number).
"""
from __future__ import annotations

import math

import numpy as np

from . import autopilot as ap
from .link import MavlinkLink, mavlink

# SET_POSITION_TARGET_LOCAL_NED.type_mask: the fields the autopilot must ignore.
_IGNORE_POSITION = 1 | 2 | 4
_IGNORE_VELOCITY = 8 | 16 | 32
_IGNORE_ACCELERATION = 64 | 128 | 256
_IGNORE_YAW = 1024
_IGNORE_YAW_RATE = 2048
POSITION_AND_YAW = _IGNORE_VELOCITY | _IGNORE_ACCELERATION | _IGNORE_YAW_RATE
VELOCITY_AND_YAW_RATE = _IGNORE_POSITION | _IGNORE_ACCELERATION | _IGNORE_YAW


def mode_command_params(autopilot: str, name: str) -> tuple[float, float, float]:
    """(param1, param2, param3) of MAV_CMD_DO_SET_MODE selecting `name` on `autopilot`."""
    base_mode, custom_mode = ap.encode_mode(autopilot, name)
    if autopilot == ap.PX4:
        return float(base_mode), float((custom_mode >> 16) & 0xFF), float((custom_mode >> 24) & 0xFF)
    return float(base_mode), float(custom_mode), 0.0


class Commander:
    """The UAL's requests to one autopilot over a MavlinkLink; each raises link.CommandFailed when refused."""

    def __init__(self, link: MavlinkLink, autopilot: str):
        self.link = link
        self.autopilot = autopilot

    def arm(self) -> None:
        self.link.command_accepted(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, name="arm")

    def set_mode(self, name: str) -> None:
        self.link.command_accepted(mavlink.MAV_CMD_DO_SET_MODE, *mode_command_params(self.autopilot, name),
                                   name=f"set mode {name}")

    def take_off(self, height: float) -> None:
        """ArduPilot Copter's climb in GUIDED (it does not take off on a position set-point): `height` m up."""
        self.link.command_accepted(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, height, name="take-off")

    def set_home(self, geo: tuple[float, float, float] | None) -> None:
        """MAV_CMD_DO_SET_HOME at (lat, lon, alt), or where the vehicle is now when `geo` is None."""
        if geo is None:
            self.link.command_accepted(mavlink.MAV_CMD_DO_SET_HOME, 1, name="set home")
        else:
            self.link.command_accepted(mavlink.MAV_CMD_DO_SET_HOME, 0, 0, 0, math.nan, *geo, name="set home")

    def send_position(self, position_ned, yaw_ned: float) -> None:
        x, y, z = (float(c) for c in np.asarray(position_ned, dtype=float))
        self._send_target(POSITION_AND_YAW, (x, y, z), (0.0, 0.0, 0.0), yaw_ned, 0.0)

    def send_velocity(self, velocity_ned, yaw_rate_ned: float) -> None:
        vx, vy, vz = (float(c) for c in np.asarray(velocity_ned, dtype=float))
        self._send_target(VELOCITY_AND_YAW_RATE, (0.0, 0.0, 0.0), (vx, vy, vz), 0.0, yaw_rate_ned)

    def _send_target(self, type_mask: int, position, velocity, yaw: float, yaw_rate: float) -> None:
        link = self.link
        link.send(lambda mav: mav.set_position_target_local_ned_send(
            link.time_boot_ms(), link.target_system, 1, mavlink.MAV_FRAME_LOCAL_NED, type_mask,
            *position, *velocity, 0.0, 0.0, 0.0, yaw, yaw_rate))
