"""The page's messages to the bridge: one WebSocket text frame in, one checked request out, or a ProtocolError.

The bridge speaks a subset of rosbridge's protocol (version 2): JSON objects with an "op". The page may send

    {"op": "subscribe", "topic": T, "id"?, "type"?, "throttle_rate"?, "queue_length"?, "compression"?: "none"}
    {"op": "unsubscribe", "topic": T, "id"?}
    {"op": "call_service", "service": S, "args"?: {...}, "id"?, "type"?, "compression"?: "none"}

and nothing else: publish, advertise and rosbridge's other ops are refused, and T and S must be on the allow list
(magna_studio.allowed). Everything is checked before the bridge acts: the frame's size, strict JSON (no NaN, no
Infinity, no key twice, bounded nesting), the fields of each op and their types (a boolean is not a number), the
ranges, and a call's args against the fields of the service's request message, recursively. A refusal is a
ProtocolError naming the op, the request's id, the field (`args.parameters[0].number`) and the fix; the bridge
sends it back as rosbridge's {"op": "status", "level": "error", ...}.

Choices where rosbridge leaves room: fragment_size is refused (the bridge sends whole messages); uint8[] is a
list of numbers, not base64; queue_length 0 (roslibjs's default) keeps no message back while a throttle waits.

Pure Python: the message classes are looked up (magna_studio.ros_json) only to check a call's args.
"""
from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any, ClassVar

from magna_studio import allowed
from magna_studio.ros_json import PRIMITIVES, FieldType, field_type, fields_of, message_class, request_class

MAX_FRAME_BYTES = 64 * 1024
MAX_DEPTH = 16  # JSON nesting; a GroundStationCommand call needs 4
MAX_ID_LENGTH = 128
MAX_NAME_LENGTH = 256
MAX_STRING_LENGTH = 1024  # characters of a string field in a call's args
MAX_ARRAY_LENGTH = 100  # items of an array field in a call's args
MAX_THROTTLE_MS = 60_000
MAX_QUEUE_LENGTH = 100
DEFAULT_QUEUE_LENGTH = 1  # while a throttle waits, the latest message is kept and sent when it may be

CLIENT_OPS = ("subscribe", "unsubscribe", "call_service")
_OPS_TEXT = "subscribe, unsubscribe or call_service"
# rosbridge's other ops: known, and refused by design.
REFUSED_OPS = ("publish", "advertise", "unadvertise", "advertise_service", "unadvertise_service",
               "service_response", "call_service_response", "set_level", "fragment", "png", "auth", "status",
               "send_action_goal", "cancel_action_goal", "advertise_action", "unadvertise_action")
_FIELDS = {
    "subscribe": ("op", "id", "topic", "type", "throttle_rate", "queue_length", "compression", "fragment_size"),
    "unsubscribe": ("op", "id", "topic"),
    "call_service": ("op", "id", "service", "args", "type", "compression", "fragment_size"),
}


class ProtocolError(ValueError):
    """A message the bridge refuses: what is wrong, where, and how to put it right."""

    def __init__(self, problem: str, fix: str, field: str = "", op: str | None = None,
                 request_id: str | None = None):
        self.problem, self.fix, self.field, self.op, self.request_id = problem, fix, field, op, request_id
        super().__init__(self.text)

    @property
    def text(self) -> str:
        head = self.op or "message"
        if self.request_id is not None:
            head += f" (id {json.dumps(self.request_id)})"
        subject = f"{self.field} " if self.field else ""
        return f"{head}: {subject}{self.problem}; {self.fix}"

    def __str__(self) -> str:
        return self.text

    def in_request(self, op: str | None, request_id: str | None) -> ProtocolError:
        """This error, told the op and id of the request it belongs to when it did not know them."""
        self.op = self.op or op
        self.request_id = self.request_id if self.request_id is not None else request_id
        self.args = (self.text,)
        return self

    def to_status(self) -> dict[str, Any]:
        """rosbridge's answer to a refused message."""
        status: dict[str, Any] = {"op": "status", "level": "error", "msg": self.text}
        if self.request_id is not None:
            status["id"] = self.request_id
        return status


class RateLimited(ProtocolError):
    """More messages than the connection's budget; `report` is true for the first refusal of a run only."""

    def __init__(self, problem: str, fix: str, report: bool):
        super().__init__(problem, fix)
        self.report = report


@dataclass(frozen=True)
class Subscribe:
    op: ClassVar[str] = "subscribe"
    topic: str
    type: str  # the allowed message type
    id: str | None = None
    throttle_rate: int = 0  # ms between two messages of this topic to this page; 0: every message
    queue_length: int = DEFAULT_QUEUE_LENGTH  # messages kept back while the throttle waits


@dataclass(frozen=True)
class Unsubscribe:
    op: ClassVar[str] = "unsubscribe"
    topic: str
    id: str | None = None


@dataclass(frozen=True)
class CallService:
    op: ClassVar[str] = "call_service"
    service: str
    type: str  # the allowed service type
    args: dict[str, Any] = field(default_factory=dict)  # checked; absent fields keep the request's defaults
    id: str | None = None


Request = Subscribe | Unsubscribe | CallService


def parse_request(frame: str | bytes, find_request_class: Callable[[str], Any] | None = None) -> Request:
    """The request in one WebSocket frame, or ProtocolError. `find_request_class(service_type)` gives a
    service's request class (default: the generated one, imported when first needed)."""
    message = _load_frame(frame)
    known_op = message.get("op") if message.get("op") in CLIENT_OPS else None
    request_id = _request_id(message, known_op)  # first, so that every later refusal carries it
    try:
        op = _op(message)
        unknown = [key for key in message if key not in _FIELDS[op]]
        if unknown:
            raise ProtocolError("is not a field of this op", f"give only {', '.join(_FIELDS[op])}",
                                _show_key(unknown[0]))
        if message.get("compression", "none") != "none":
            raise ProtocolError(f"is {_describe(message['compression'])}", 'give "none" or leave it out',
                                "compression")
        if "fragment_size" in message:
            raise ProtocolError("is not supported", "leave it out: this bridge sends whole messages",
                                "fragment_size")
        if op == "subscribe":
            topic, type_name = _topic(message)
            return Subscribe(topic, type_name, request_id,
                             _integer(message, "throttle_rate", 0, MAX_THROTTLE_MS, default=0),
                             _integer(message, "queue_length", 0, MAX_QUEUE_LENGTH, default=DEFAULT_QUEUE_LENGTH))
        if op == "unsubscribe":
            return Unsubscribe(_topic(message)[0], request_id)
        service, type_name = _service(message)
        return CallService(service, type_name, _args(message, type_name, find_request_class or request_class),
                           request_id)
    except ProtocolError as error:
        raise error.in_request(known_op, request_id) from None


# --- the frame ---------------------------------------------------------------------------------------------

def _load_frame(frame: str | bytes) -> dict[str, Any]:
    if not isinstance(frame, str):
        raise ProtocolError("the frame is binary", "send JSON as a text frame")
    if len(frame) > MAX_FRAME_BYTES or len(frame.encode("utf-8", "surrogatepass")) > MAX_FRAME_BYTES:
        raise ProtocolError(f"the frame is larger than {MAX_FRAME_BYTES // 1024} KiB",
                            "send smaller messages (one request per frame)")
    try:
        message = json.loads(frame, parse_constant=_refuse_constant, parse_float=_finite_float,
                             object_pairs_hook=_object_once)
    except ProtocolError:
        raise
    except RecursionError:  # nested far beyond MAX_DEPTH, deeper than Python's parser goes
        raise ProtocolError(f"the frame is nested more than {MAX_DEPTH} levels deep", "flatten the message") from None
    except ValueError as error:  # JSONDecodeError, and integers too long for Python
        raise ProtocolError(f"the frame is not JSON ({error})", "send one JSON object per text frame") from None
    if not isinstance(message, dict):
        raise ProtocolError(f"the frame holds {_describe(message)}",
                            'send a JSON object such as {"op": "subscribe", "topic": "/clock"}')
    _check_depth(message, MAX_DEPTH)
    return message


def _refuse_constant(name: str) -> Any:
    raise ProtocolError(f"the frame holds {name}, which JSON does not have", "give finite numbers only")


def _finite_float(text: str) -> float:
    number = float(text)
    if not math.isfinite(number):
        raise ProtocolError(f"the frame holds the number {text[:24]}, beyond a double's range",
                            "give finite numbers only")
    return number


def _object_once(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # A key given twice means one thing to us and maybe another to a proxy or a log reader: refuse it.
    result: dict[str, Any] = {}
    for key, value in pairs:
        if key in result:
            raise ProtocolError(f"the frame gives the key {_show_key(key)} twice", "give each key once")
        result[key] = value
    return result


def _check_depth(value: Any, limit: int) -> None:
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict | list):
            if depth > limit:
                raise ProtocolError(f"the frame is nested more than {MAX_DEPTH} levels deep",
                                    "flatten the message")
            children = item.values() if isinstance(item, dict) else item
            stack.extend((child, depth + 1) for child in children)


# --- the fields of an op -------------------------------------------------------------------------------------

def _op(message: dict[str, Any]) -> str:
    if "op" not in message:
        raise ProtocolError("is missing", f"give op: {_OPS_TEXT}", "op")
    op = message["op"]
    if not isinstance(op, str):
        raise ProtocolError(f"is {_describe(op)}", f"give op as a string: {_OPS_TEXT}", "op")
    if op in CLIENT_OPS:
        return op
    if op in REFUSED_OPS:
        raise ProtocolError(f"{_show(op)} is not allowed: the page may only subscribe, unsubscribe and call the "
                            "services listed for it", f"send {_OPS_TEXT}", "op")
    raise ProtocolError(f"{_show(op)} is unknown", f"give {_OPS_TEXT}", "op")


def _request_id(message: dict[str, Any], op: str | None) -> str | None:
    if "id" not in message:
        return None
    value = message["id"]
    if not isinstance(value, str):
        raise ProtocolError(f"is {_describe(value)}", "give the id as a string", "id", op)
    if not value or len(value) > MAX_ID_LENGTH:
        raise ProtocolError(f"is {len(value)} characters long", f"give 1 to {MAX_ID_LENGTH} characters", "id", op)
    if not value.isprintable():
        raise ProtocolError("holds control or invisible characters", "give printable characters only", "id", op)
    return value


def _name(message: dict[str, Any], key: str) -> str:
    if key not in message:
        raise ProtocolError("is missing", f"give the {key}'s name", key)
    value = message[key]
    if not isinstance(value, str):
        raise ProtocolError(f"is {_describe(value)}", f"give the {key}'s name as a string", key)
    if len(value) > MAX_NAME_LENGTH:
        raise ProtocolError(f"is {len(value)} characters long", f"give a {key} from the allow list", key)
    return value


def _topic(message: dict[str, Any]) -> tuple[str, str]:
    topic = _name(message, "topic")
    type_name = allowed.topic_type(topic)
    if type_name is None:
        raise ProtocolError(f"{_show(topic)} is not open to the page",
                            f"subscribe to one of {', '.join(allowed.topic_patterns())} (<id>: a UAV id, 1-999)",
                            "topic")
    _declared_type(message, type_name)
    return topic, type_name


def _service(message: dict[str, Any]) -> tuple[str, str]:
    service = _name(message, "service")
    type_name = allowed.service_type(service)
    if type_name is None:
        raise ProtocolError(f"{_show(service)} is not open to the page",
                            f"call one of {', '.join(allowed.service_names())}", "service")
    _declared_type(message, type_name)
    return service, type_name


def _declared_type(message: dict[str, Any], type_name: str) -> None:
    if "type" in message and message["type"] != type_name:
        raise ProtocolError(f"is {_describe(message['type'])}", f'give "{type_name}" or leave it out', "type")


def _integer(message: dict[str, Any], key: str, low: int, high: int, default: int) -> int:
    if key not in message:
        return default
    value = message[key]
    if isinstance(value, bool) or not isinstance(value, int):
        raise ProtocolError(f"is {_describe(value)}", f"give a whole number from {low} to {high}", key)
    if not low <= value <= high:
        raise ProtocolError(f"is {value}, out of range", f"give a whole number from {low} to {high}", key)
    return value


def _args(message: dict[str, Any], service_type: str, find_request_class: Callable[[str], Any]) -> dict[str, Any]:
    args = message.get("args", {})
    try:
        request = find_request_class(service_type)
    except LookupError as error:
        raise ProtocolError(f"cannot be checked: {error}", "ask whoever runs the bridge", "args") from None
    return check_message(args, request, "args")


# --- a call's args against the request message -----------------------------------------------------------

def check_message(value: Any, cls: Any, path: str) -> dict[str, Any]:
    """`value` checked as the JSON form of a message of class `cls`: its fields, recursively. The result holds
    the checked values (floats as floats); a field left out keeps the message's default."""
    fields = fields_of(cls)
    if not isinstance(value, dict):
        raise ProtocolError(f"is {_describe(value)}", f"give an object with the fields of {cls._type}: "
                            f"{', '.join(fields) or 'none'}", path)
    checked = {}
    for name, item in value.items():
        if name not in fields:
            raise ProtocolError(f"is not a field of {cls._type}",
                                f"give only {', '.join(fields)}" if fields else "give no fields ({})",
                                f"{path}.{_show_key(name)}")
        checked[name] = _check_field(item, field_type(fields[name]), f"{path}.{name}")
    return checked


def _check_field(value: Any, kind: FieldType, path: str) -> Any:
    if not kind.array:
        return _check_scalar(value, kind.base, path)
    if not isinstance(value, list):
        raise ProtocolError(f"is {_describe(value)}", f"give an array of {kind.base}", path)
    if kind.length is not None and len(value) != kind.length:
        raise ProtocolError(f"has {len(value)} items", f"give exactly {kind.length}", path)
    if len(value) > MAX_ARRAY_LENGTH:
        raise ProtocolError(f"has {len(value)} items", f"give at most {MAX_ARRAY_LENGTH}", path)
    return [_check_scalar(item, kind.base, f"{path}[{index}]") for index, item in enumerate(value)]


def _check_scalar(value: Any, base: str, path: str) -> Any:
    primitive = PRIMITIVES.get(base)
    if primitive is None:
        try:
            nested = message_class(base)
        except LookupError as error:
            raise ProtocolError(f"cannot be checked: {error}", "ask whoever runs the bridge", path) from None
        return check_message(value, nested, path)
    kind = primitive.kind
    if kind == "bool":
        if not isinstance(value, bool):
            raise ProtocolError(f"is {_describe(value)}", "give true or false", path)
        return value
    if kind == "string":
        if not isinstance(value, str):
            raise ProtocolError(f"is {_describe(value)}", "give a string", path)
        if len(value) > MAX_STRING_LENGTH:
            raise ProtocolError(f"is {len(value)} characters long", f"give at most {MAX_STRING_LENGTH}", path)
        if not value.isprintable():
            raise ProtocolError("holds control or invisible characters", "give printable characters only", path)
        return value
    if kind in ("time", "duration"):
        return _check_time(value, kind, path)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProtocolError(f"is {_describe(value)}", f"give a number ({base})", path)
    if kind == "int":
        if not isinstance(value, int):
            raise ProtocolError(f"is {_describe(value)}", f"give a whole number ({base})", path)
    elif isinstance(value, float) and not math.isfinite(value):
        raise ProtocolError(f"is {value}", "give a finite number", path)
    if not primitive.low <= value <= primitive.high:
        raise ProtocolError(f"is {value}, out of the range of {base}",
                            f"give a number from {primitive.low:g} to {primitive.high:g}", path)
    return value if kind == "int" else float(value)


def _check_time(value: Any, kind: str, path: str) -> dict[str, int]:
    if not isinstance(value, dict):
        raise ProtocolError(f"is {_describe(value)}", f'give the {kind} as {{"secs": S, "nsecs": N}}', path)
    secs_type = "uint32" if kind == "time" else "int32"
    checked = {}
    for key, item in value.items():
        if key not in ("secs", "nsecs"):
            raise ProtocolError(f"is not a field of a {kind}", "give only secs and nsecs", f"{path}.{_show_key(key)}")
        checked[key] = _check_scalar(item, secs_type if key == "secs" else "int32", f"{path}.{key}")
    if not 0 <= checked.get("nsecs", 0) <= 999_999_999:
        raise ProtocolError(f"is {checked['nsecs']}", "give 0 to 999999999 nanoseconds", f"{path}.nsecs")
    return checked


# --- how values are named in messages --------------------------------------------------------------------

def _show(text: str, limit: int = 60) -> str:
    """A string the page sent, quoted and escaped (non-ASCII and control characters as \\u escapes), cut short."""
    shown = ascii(text)
    return shown if len(shown) <= limit else shown[:limit] + "...'"


def _show_key(key: str) -> str:
    return key if key.isidentifier() and key.isascii() and len(key) <= 60 else _show(key)


def _describe(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"{str(value).lower()}, a boolean"
    if isinstance(value, int | float):
        return f"the number {value:.6g}" if isinstance(value, float) else f"the number {str(value)[:24]}"
    if isinstance(value, str):
        return f"the string {_show(value)}"
    return "an array" if isinstance(value, list) else "an object"


# --- a connection's budget -----------------------------------------------------------------------------------

class ConnectionLimiter:
    """One connection's budget: how fast it may send, how many topics it may watch, how many calls it may
    have waiting. A token bucket: `burst` messages at once, then `messages_per_second`."""

    def __init__(self, max_subscriptions: int = 200, messages_per_second: float = 100.0, burst: int = 200,
                 max_calls_in_flight: int = 4, clock: Callable[[], float] = time.monotonic):
        self.max_subscriptions = max_subscriptions
        self.messages_per_second = messages_per_second
        self.burst = burst
        self.max_calls_in_flight = max_calls_in_flight
        self._clock = clock
        self._tokens = float(burst)
        self._last = clock()
        self._refused_in_row = 0
        self.calls_in_flight = 0

    def admit_message(self) -> None:
        """Count one incoming message; RateLimited when the connection sends faster than its budget."""
        now = self._clock()
        self._tokens = min(float(self.burst), self._tokens + (now - self._last) * self.messages_per_second)
        self._last = now
        if self._tokens < 1.0:
            self._refused_in_row += 1
            raise RateLimited(f"more than {self.messages_per_second:g} messages a second (after a burst of "
                              f"{self.burst}); this and the next ones are dropped, and reported once",
                              "send less often", report=self._refused_in_row == 1)
        self._tokens -= 1.0
        self._refused_in_row = 0

    def admit_subscription(self, topic: str, subscribed: Collection[str]) -> None:
        if topic not in subscribed and len(subscribed) >= self.max_subscriptions:
            raise ProtocolError(f"would be subscription {len(subscribed) + 1}, and a connection may watch at most "
                                f"{self.max_subscriptions} topics", "unsubscribe from another topic first", "topic")

    def start_call(self) -> None:
        if self.calls_in_flight >= self.max_calls_in_flight:
            raise ProtocolError(f"would be call {self.calls_in_flight + 1} waiting for an answer, and a connection "
                                f"may have at most {self.max_calls_in_flight}",
                                "wait for a service_response first", "service")
        self.calls_in_flight += 1

    def end_call(self) -> None:
        self.calls_in_flight = max(0, self.calls_in_flight - 1)
