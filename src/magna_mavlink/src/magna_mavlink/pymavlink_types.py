"""What magna_mavlink uses of pymavlink's objects, as Protocols for the type checker.

pymavlink generates its message classes and its encoder (one `*_send` method per message) when it is
imported and ships no type information, so their fields and methods are typed by name only here: a
message's fields are whatever its MAVLink type defines. Importing this module does not import pymavlink.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol


class MavMessage(Protocol):
    """A received message (pymavlink's MAVLink_message): its header, and its fields as attributes."""

    def get_type(self) -> str: ...  # e.g. "HEARTBEAT", or "BAD_DATA" for bytes that did not decode

    def get_srcSystem(self) -> int: ...

    def get_srcComponent(self) -> int: ...

    def __getattr__(self, field: str) -> Any: ...  # the fields of its message type: msg.autopilot, msg.lat ...


class MavEncoder(Protocol):
    """A connection's `mav`: builds, numbers and writes messages (e.g. heartbeat_send, command_long_send)."""

    def __getattr__(self, name: str) -> Callable[..., None]: ...


class MavConnection(Protocol):
    """A pymavlink connection (mavutil.mavlink_connection's mavfile), or a test's stand-in."""

    @property
    def mav(self) -> MavEncoder: ...

    def recv_match(self, *, blocking: bool, timeout: float) -> MavMessage | None: ...

    def close(self) -> None: ...
