"""ROS messages to JSON-ready data and back, read from the generated classes (genpy's `__slots__`/`_slot_types`).

    message_to_dict(msg)        a message as dicts, lists, numbers, strings and booleans
    dict_to_message(cls, data)  a message of class `cls` with the fields in `data`; the others keep their defaults

The JSON form follows rosbridge's: a field per key, time and duration as {"secs", "nsecs"}. Two choices of
our own: uint8[] (and char[]) is a list of numbers, not base64; a NaN or infinite float is null, since JSON has
neither (dict_to_message reads null back as NaN). Importing this module needs no ROS: the message classes are
looked up when first asked for.
"""
from __future__ import annotations

import functools
import importlib
import math
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Primitive:
    kind: str  # bool, int, float, string, time or duration
    low: float = 0
    high: float = 0


def _int(bits: int, signed: bool) -> Primitive:
    return Primitive("int", -(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else Primitive("int", 0, 2 ** bits - 1)


FLOAT32_MAX = 3.4028234663852886e38
PRIMITIVES: dict[str, Primitive] = {
    "bool": Primitive("bool"),
    "int8": _int(8, True), "uint8": _int(8, False), "int16": _int(16, True), "uint16": _int(16, False),
    "int32": _int(32, True), "uint32": _int(32, False), "int64": _int(64, True), "uint64": _int(64, False),
    "byte": _int(8, True), "char": _int(8, False),  # ROS 1's deprecated aliases of int8 and uint8
    "float32": Primitive("float", -FLOAT32_MAX, FLOAT32_MAX),
    "float64": Primitive("float", -sys.float_info.max, sys.float_info.max),
    "string": Primitive("string"),
    "time": Primitive("time"),
    "duration": Primitive("duration"),
}
_BYTE_TYPES = ("uint8", "char")  # genpy holds arrays of these as bytes

_SLOT_TYPE = re.compile(r"([A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*)?)(?:\[([0-9]*)\])?")


@dataclass(frozen=True)
class FieldType:
    """One field's type as genpy writes it in `_slot_types`: `float64`, `uint32[]`, `float64[9]`, `pkg/Name[]`."""

    base: str
    array: bool = False
    length: int | None = None  # of a fixed-size array

    @property
    def primitive(self) -> Primitive | None:
        return PRIMITIVES.get(self.base)

    @property
    def is_bytes(self) -> bool:
        return self.array and self.base in _BYTE_TYPES


@functools.cache
def field_type(slot_type: str) -> FieldType:
    match = _SLOT_TYPE.fullmatch(slot_type)
    if match is None:
        raise ValueError(f"{slot_type!r} is not a ROS field type")
    base, length = match.groups()
    if base == "Header":  # how old message files name std_msgs/Header
        base = "std_msgs/Header"
    return FieldType(base, length is not None, int(length) if length else None)


def fields_of(cls: Any) -> dict[str, str]:
    """A message class's fields, name -> slot type, in their order."""
    return dict(zip(cls.__slots__, cls._slot_types, strict=True))


def _split_type(type_name: str) -> tuple[str, str]:
    package, _, name = type_name.partition("/")
    if not (package.isidentifier() and name.isidentifier()):
        raise LookupError(f"{type_name!r} is not a ROS type name: give package/Name")
    return package, name


@functools.cache
def message_class(type_name: str) -> Any:
    """The generated class of a message type, e.g. "geometry_msgs/PoseStamped"."""
    package, name = _split_type(type_name)
    return _generated(package, "msg", name, type_name)


@functools.cache
def service_class(type_name: str) -> Any:
    """The generated class of a service type, e.g. "std_srvs/Trigger" (its `_request_class`, `_response_class`)."""
    package, name = _split_type(type_name)
    return _generated(package, "srv", name, type_name)


def request_class(service_type: str) -> Any:
    return service_class(service_type)._request_class


def _generated(package: str, kind: str, name: str, type_name: str) -> Any:
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError) as error:
        raise LookupError(f"no generated class for {type_name} ({error}): build the workspace and source "
                          "devel/setup.bash") from None


# --- message -> JSON-ready data --------------------------------------------------------------------------------

def message_to_dict(msg: Any) -> dict[str, Any]:
    return {name: _to_json(getattr(msg, name), field_type(slot_type)) for name, slot_type in fields_of(msg).items()}


def _to_json(value: Any, kind: FieldType) -> Any:
    if not kind.array:
        return _scalar_to_json(value, kind.base)
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    return [_scalar_to_json(item, kind.base) for item in value]


def _scalar_to_json(value: Any, base: str) -> Any:
    primitive = PRIMITIVES.get(base)
    if primitive is None:
        return message_to_dict(value)
    if primitive.kind == "float":
        number = float(value)
        return number if math.isfinite(number) else None
    if primitive.kind == "int":
        return int(value)
    if primitive.kind == "bool":
        return bool(value)
    if primitive.kind == "string":
        return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)
    return {"secs": int(value.secs), "nsecs": int(value.nsecs)}  # time, duration


# --- JSON data -> message ------------------------------------------------------------------------------------

def dict_to_message(cls: Any, data: Mapping[str, Any]) -> Any:
    """A message of class `cls` holding `data` (checked beforehand: see magna_studio.protocol); a field absent
    from `data` keeps the class's default, as rosbridge does. An unknown field raises ValueError."""
    msg = cls()
    fields = fields_of(cls)
    for name, value in data.items():
        if name not in fields:
            raise ValueError(f"{cls._type} has no field {name!r}: its fields are {', '.join(fields)}")
        setattr(msg, name, _from_json(value, field_type(fields[name])))
    return msg


def _from_json(value: Any, kind: FieldType) -> Any:
    if not kind.array:
        return _scalar_from_json(value, kind.base)
    if kind.is_bytes:
        return bytes(value)
    return [_scalar_from_json(item, kind.base) for item in value]


def _scalar_from_json(value: Any, base: str) -> Any:
    primitive = PRIMITIVES.get(base)
    if primitive is None:
        return dict_to_message(message_class(base), value)
    if primitive.kind == "float":
        return math.nan if value is None else float(value)
    if primitive.kind == "int":
        return int(value)
    if primitive.kind == "bool":
        return bool(value)
    if primitive.kind == "string":
        return str(value)
    import genpy  # a ROS library: only here, so that importing this module needs no ROS

    time_class = genpy.Time if primitive.kind == "time" else genpy.Duration
    return time_class(int(value.get("secs", 0)), int(value.get("nsecs", 0)))
