"""The parameters of magna_sim's PX4-like MAVLink vehicle: PX4's names, types and defaults.

Only parameters the vehicle honours, or that clients read (MAVSDK's action plugin reads
MIS_TAKEOFF_ALT; ground stations read the offboard and link-loss settings), are here. Each is
either settable (the vehicle uses the new value at once) or read-only (it describes the airframe;
a PARAM_SET is answered with the unchanged value, which clients report as a failed set).

PX4 sends integer parameters "bytewise": the four bytes of the int32 travel in the float field
of PARAM_VALUE / PARAM_SET (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE). MAVSDK decodes them
that way for PX4, so this table does too.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass

MAV_PARAM_TYPE_INT32 = 6
MAV_PARAM_TYPE_REAL32 = 9
PARAM_ID_LENGTH = 16  # characters of PARAM_VALUE.param_id


@dataclass
class Param:
    name: str
    value: float | int
    param_type: int  # MAV_PARAM_TYPE_REAL32 or MAV_PARAM_TYPE_INT32
    settable: bool = True
    minimum: float = -math.inf
    maximum: float = math.inf


class ParamError(ValueError):
    """A PARAM_SET that cannot be applied; the message names the parameter."""


def encode(param: Param) -> float:
    """The float that carries `param.value` on the wire (bytewise for integers, as PX4)."""
    if param.param_type == MAV_PARAM_TYPE_INT32:
        return struct.unpack("<f", struct.pack("<i", int(param.value)))[0]
    return float(param.value)


def decode(wire_value: float, param_type: int) -> float | int:
    """The value a PARAM_SET's float field carries for a parameter of `param_type`."""
    if param_type == MAV_PARAM_TYPE_INT32:
        return struct.unpack("<i", struct.pack("<f", wire_value))[0]
    return float(wire_value)


def default_params(system_id: int, max_horizontal_speed: float, max_vertical_speed: float) -> list[Param]:
    """PX4's defaults for the parameters the vehicle knows; the speed limits come from the airframe."""
    real, integer = MAV_PARAM_TYPE_REAL32, MAV_PARAM_TYPE_INT32
    return [
        Param("COM_DISARM_LAND", 2.0, real, minimum=-1.0, maximum=20.0),  # s on the ground after landing; <=0 never
        Param("COM_DISARM_PRFLT", 10.0, real, minimum=-1.0, maximum=20.0),  # s armed without taking off; <=0 never
        Param("COM_OBL_RC_ACT", 5, integer, settable=False),  # offboard loss: 5 = hold (the only one simulated)
        Param("COM_OF_LOSS_T", 1.0, real, minimum=0.0, maximum=60.0),  # s without set-points before leaving OFFBOARD
        Param("COM_RCL_EXCEPT", 4, integer, minimum=0, maximum=31),  # RC loss ignored in OFFBOARD (no RC here)
        Param("MAV_SYS_ID", system_id, integer, settable=False),
        Param("MAV_TYPE", 2, integer, settable=False),  # MAV_TYPE_QUADROTOR
        Param("MIS_TAKEOFF_ALT", 2.5, real, minimum=0.5, maximum=100.0),  # m above home for a take-off
        Param("MPC_LAND_SPEED", 0.7, real, minimum=0.2, maximum=max_vertical_speed),  # m/s
        Param("MPC_TKO_SPEED", 1.5, real, minimum=0.2, maximum=max_vertical_speed),  # m/s
        Param("MPC_XY_VEL_MAX", max_horizontal_speed, real, settable=False),  # the airframe's limit
        Param("MPC_Z_VEL_MAX_DN", max_vertical_speed, real, settable=False),
        Param("MPC_Z_VEL_MAX_UP", max_vertical_speed, real, settable=False),
        Param("NAV_DLL_ACT", 0, integer, minimum=0, maximum=6),  # data-link loss action (not simulated)
        Param("NAV_RCL_ACT", 0, integer, minimum=0, maximum=6),  # RC loss action: 0 = none (no RC here)
    ]


class ParamTable:
    """Parameters by name and by index (the order of PARAM_REQUEST_LIST)."""

    def __init__(self, params: list[Param]):
        self._params = sorted(params, key=lambda p: p.name)
        self._by_name = {p.name: p for p in self._params}

    def __len__(self) -> int:
        return len(self._params)

    def __iter__(self):
        return iter(self._params)

    def __getitem__(self, name: str) -> float | int:
        return self._by_name[name].value

    def find(self, name: str = "", index: int = -1) -> tuple[int, Param] | None:
        """The parameter called `name`, or the one at `index` when index >= 0 (as PARAM_REQUEST_READ)."""
        if index >= 0:
            return (index, self._params[index]) if index < len(self._params) else None
        param = self._by_name.get(name)
        return None if param is None else (self._params.index(param), param)

    def set(self, name: str, wire_value: float, param_type: int) -> tuple[int, Param]:
        """Apply a PARAM_SET; raises ParamError for an unknown name or a wrong type, leaves read-only ones."""
        found = self.find(name)
        if found is None:
            raise ParamError(f"PARAM_SET {name!r}: no such parameter; known: {', '.join(self._by_name)}")
        index, param = found
        if param_type != param.param_type:
            raise ParamError(f"PARAM_SET {name!r}: type {param_type}, but {name} is of type {param.param_type}")
        if not param.settable:
            return index, param
        value = decode(wire_value, param_type)
        if not (isinstance(value, int) or math.isfinite(value)) or not param.minimum <= value <= param.maximum:
            raise ParamError(f"PARAM_SET {name!r}: {value} is outside [{param.minimum:g}, {param.maximum:g}]")
        param.value = value
        return index, param
