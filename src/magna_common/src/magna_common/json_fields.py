"""Typed reads of the fields of a JSON file (worlds, missions, agent entries), one message rule for all.

Every failure names the file, the JSON path as the file writes it and what to write instead:
`worlds/Gym/Ring.json: scenario.volumes[2].geometries[0].shape: unknown value 'cone'; use one of ...`.
A reader works in one of two modes:

    fields = JsonFields.first_error("w.json", WorldError)  # the first failure raises WorldError(source, path, msg)
    fields = JsonFields.collect_all("m.json")              # every failure is added to fields.problems

A first-error reader's getters return the value read; a collecting reader's return None for a value
that failed, so its caller goes on and reports every problem at once (raising once, at the end).
`ObjectFields` reads the keys of one object: defaults, required keys, and the keys nobody read.
A migrated file's paths are mapped back to the file's own spelling by `original_path`.
"""
from __future__ import annotations

import difflib
import enum
import json
import math
from collections.abc import Callable, Iterable, Sequence
from numbers import Integral, Real
from pathlib import Path
from typing import Any, Final, Generic, Never, TypeVar, cast

from magna_common.errors import UserError

# What a getter returns for a value that failed: Never for a first-error reader (the failure raised), None for a
# collecting one. `str | Failed` is then `str`, or `str | None`.
Failed = TypeVar("Failed")
Option = TypeVar("Option", bound=str)


class Missing(enum.Enum):
    """The absence of a key (a JSON null is None, a value)."""

    MISSING = "missing"


MISSING: Final = Missing.MISSING


class FieldError(UserError, ValueError):
    """A bad field of a JSON file; str() reads `file: JSON.path: what is wrong; how to fix it`."""

    def __init__(self, source: str, path: str, message: str):
        self.source, self.path, self.message = source, path, message
        super().__init__(f"{located(source, path)}: {message}")


def located(source: str, path: str) -> str:
    """`file: JSON.path`, or the file alone for the whole document."""
    return f"{source}: {path}" if path else source


def join_path(base: str, key: str | int) -> str:
    """The JSON path one level down: `a.b` for a key, `a[3]` for an index."""
    if isinstance(key, int):
        return f"{base}[{key}]"
    return f"{base}.{key}" if base else str(key)


def describe(value: Any) -> str:
    """A value as a message names what was found instead: `an object`, `a list`, `a string`, else its JSON-ish repr."""
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "a list"
    return "a string" if isinstance(value, str) else repr(value)


def closest(value: Any, options: Iterable[Any], cutoff: float = 0.6) -> str | None:
    """The option `value` was most likely meant to be (a typo), if any is close enough."""
    close = difflib.get_close_matches(str(value), [str(o) for o in options], n=1, cutoff=cutoff)
    return close[0] if close else None


def did_you_mean(value: Any, options: Iterable[Any]) -> str:
    """` (did you mean 'x'?)` for a near miss of one of `options`, else nothing."""
    close = closest(value, options)
    return f" (did you mean '{close}'?)" if close else ""


def is_integer(value: Any) -> bool:
    return isinstance(value, Integral) and not isinstance(value, bool)


def is_number(value: Any) -> bool:
    """A finite JSON number (true and false are not numbers; nor is an integer beyond any float, 1e400)."""
    if not isinstance(value, Real) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int too large to become a float
        return False


def copy_json(value: Any) -> Any:
    """A copy of parsed JSON (its dicts and lists new, the rest immutable): copy.deepcopy's work without its
    bookkeeping, several times faster on a file of megabytes."""
    if isinstance(value, dict):
        return {key: copy_json(item) for key, item in value.items()}
    if isinstance(value, list):
        return [copy_json(item) for item in value]
    return value


class UnreadableJson(ValueError):
    """A file that holds no JSON document MAGNA can read; str() says why and what to do (the caller names the file)."""


def read_json_document(path: Path) -> Any:
    """The JSON document in `path`, or UnreadableJson saying why not: missing, unreadable, not UTF-8, not JSON,
    a number too long for Python to read, or nested too deeply."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UnreadableJson("no such file; check the path") from None
    except UnicodeDecodeError as err:
        raise UnreadableJson(f"not UTF-8 text: byte 0x{err.object[err.start]:02x} at offset {err.start} cannot be "
                             "decoded; save the file as UTF-8") from None
    except OSError as err:
        raise UnreadableJson(f"cannot read it: {err.strerror or err}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise UnreadableJson(f"not valid JSON: {err.msg} at line {err.lineno} column {err.colno}") from None
    except RecursionError:
        raise UnreadableJson("nested too deeply to read (hundreds of levels of lists or objects); "
                             "no world or mission needs that many: check how the file was made") from None
    except ValueError as err:  # e.g. an integer of thousands of digits (Python's int_max_str_digits)
        raise UnreadableJson(f"not a JSON document MAGNA can read: {err}") from None


def _same_path(path: str) -> str:
    return path


class JsonFields(Generic[Failed]):
    """Typed reads of one file's JSON values, each failure named by the value's JSON path."""

    def __init__(self, source: str, error: Callable[[str, str, str], Exception] | None,
                 original_path: Callable[[str], str] | None = None):
        self.source = source
        self.error = error  # None: collect every problem
        self.original_path = original_path or _same_path
        self.problems: list[str] = []  # collecting: `file: path: message`, in the order found
        self.warnings: list[str] = []

    @staticmethod
    def first_error(source: str, error: Callable[[str, str, str], Exception] = FieldError,
                    original_path: Callable[[str], str] | None = None) -> JsonFields[Never]:
        """A reader whose first failure raises `error(source, path, message)`."""
        return JsonFields(source, error, original_path)

    @staticmethod
    def collect_all(source: str, original_path: Callable[[str], str] | None = None) -> JsonFields[None]:
        """A reader that adds every failure to `problems` and lets its caller go on."""
        return JsonFields(source, None, original_path)

    def where(self, path: str) -> str:
        return located(self.source, self.original_path(path))

    def fail(self, path: str, message: str) -> Failed:
        """Report a bad value: raise (first-error reader) or add it to `problems` (collecting reader)."""
        if self.error is not None:
            raise self.error(self.source, self.original_path(path), message)
        self.problems.append(f"{self.where(path)}: {message}")
        return cast(Failed, None)

    def warn(self, path: str, message: str) -> None:
        self.warnings.append(f"{self.where(path)}: {message}")

    # --- getters: each checks one value and returns it typed, or reports it and returns Failed -----------------

    def key(self, obj: Any, path: str, key: str, fix: str) -> Any | Failed:
        """obj[key] of the object at `path`; a missing key reads `missing; <fix>`."""
        if not isinstance(obj, dict):
            return self.fail(path, f"expected an object, got {describe(obj)}")
        if key not in obj:
            return self.fail(join_path(path, key), f"missing; {fix}")
        return obj[key]

    def object(self, value: Any, path: str, usage: str = "an object {...}") -> dict[str, Any] | Failed:
        if not isinstance(value, dict):
            return self.fail(path, f"expected {usage}, got {describe(value)}")
        return value

    def list(self, value: Any, path: str, usage: str = "a list [...]", *,
             non_empty: bool = False) -> list[Any] | Failed:
        if not isinstance(value, list) or (non_empty and not value):
            return self.fail(path, f"expected {usage}, got {describe(value)}")
        return value

    def text(self, value: Any, path: str, usage: str = "a non-empty string", *,
             allow_empty: bool = False) -> str | Failed:
        if not isinstance(value, str) or (not value and not allow_empty):
            return self.fail(path, f"expected {usage}, got {value!r}")
        return value

    def number(self, value: Any, path: str, usage: str = "a finite number", *, minimum: float | None = None,
               positive: bool = False) -> float | Failed:
        if not is_number(value) or (positive and value <= 0) or (minimum is not None and value < minimum):
            return self.fail(path, f"expected {usage}, got {value!r}")
        return float(value)

    def integer(self, value: Any, path: str, usage: str = "a whole number", *,
                minimum: int | None = None) -> int | Failed:
        if not is_integer(value) or (minimum is not None and value < minimum):
            return self.fail(path, f"expected {usage}, got {value!r}")
        return int(value)

    def numbers(self, value: Any, path: str, count: int, usage: str) -> tuple[float, ...] | Failed:
        """A list of exactly `count` finite numbers; `usage` says what they are (`[x, y, z] in m`)."""
        items = self.list(value, path)
        if not isinstance(items, list):  # a collecting reader's failed value
            return cast(Failed, None)
        if len(items) != count:
            return self.fail(path, f"expected {usage}, got {len(items)} value(s)")
        read = [self.number(v, join_path(path, i)) for i, v in enumerate(items)]
        if any(v is None for v in read):
            return cast(Failed, None)
        return tuple(cast(list[float], read))

    def choice(self, value: Any, path: str, options: Sequence[Option], noun: str | None = None) -> Option | Failed:
        """One of `options`. The message reads `'x' is not one of a, b`, or with a noun `unknown kind 'x'; use one
        of a, b`, with a guess when `x` is a near miss."""
        if value not in options:
            listed = ", ".join(options)
            hint = did_you_mean(value, options)
            if noun is None:
                return self.fail(path, f"{value!r} is not one of {listed}{hint}")
            return self.fail(path, f"unknown {noun} {value!r}{hint}; use one of {listed}")
        return options[list(options).index(value)]

    def flag(self, value: Any, path: str, *, zero_one: bool = False) -> bool | Failed:
        """true or false (with `zero_one`, 0 and 1 too, as some older files write them)."""
        if isinstance(value, bool):
            return value
        if zero_one and is_integer(value) and value in (0, 1):
            return bool(value)
        return self.fail(path, f"expected true or false, got {value!r}")


class ObjectFields:
    """Reads the keys of one JSON object of a collecting reader: a key absent without a default is a problem
    (`missing; <what missing_fix says>`), and `unused()` lists the keys nobody read. `ok` turns False at the first
    problem in this object."""

    def __init__(self, fields: JsonFields[Any], obj: dict[str, Any], path: str,
                 missing_fix: Callable[[str, str], str]):
        self.fields, self.obj, self.path = fields, obj, path
        self.missing_fix = missing_fix  # (key, usage) -> how to add it
        self.used: set[str] = set()
        self.ok = True

    def path_of(self, key: str) -> str:
        return join_path(self.path, key)

    def fail(self, key: str, message: str) -> None:
        self.ok = False
        self.fields.fail(self.path_of(key), message)

    def get(self, key: str, required: bool, usage: str) -> Any:
        """The raw value of `key`, or MISSING (a problem when `required`)."""
        self.used.add(key)
        if key not in self.obj:
            if required:
                self.fail(key, f"missing; {self.missing_fix(key, usage)}")
            return MISSING
        return self.obj[key]

    def _checked(self, value: Any) -> Any:
        if value is None:  # a getter's failed value (a value read is never None)
            self.ok = False
        return value

    def number(self, key: str, default: float | None | Missing = MISSING, *, minimum: float | None = None,
               positive: bool = False, usage: str = "a number") -> float | None:
        value = self.get(key, default is MISSING, usage)
        if value is MISSING:
            return None if isinstance(default, Missing) else default
        return self._checked(self.fields.number(value, self.path_of(key), usage, minimum=minimum, positive=positive))

    def integer(self, key: str, default: int | Missing = MISSING, *, minimum: int = 0,
                usage: str = "a whole number") -> int | None:
        value = self.get(key, default is MISSING, usage)
        if value is MISSING:
            return None if isinstance(default, Missing) else default
        return self._checked(self.fields.integer(value, self.path_of(key), usage, minimum=minimum))

    def text(self, key: str, default: str | Missing = MISSING, *, usage: str = "a string") -> str | None:
        value = self.get(key, default is MISSING, usage)
        if value is MISSING:
            return None if isinstance(default, Missing) else default
        return self._checked(self.fields.text(value, self.path_of(key), usage))

    def choice(self, key: str, options: Sequence[Option], default: Option | Missing = MISSING) -> Option | None:
        value = self.get(key, default is MISSING, "one of " + ", ".join(options))
        if value is MISSING:
            return None if isinstance(default, Missing) else default
        return self._checked(self.fields.choice(value, self.path_of(key), options))

    def flag(self, key: str, default: bool) -> bool:
        value = self.get(key, False, "true or false")
        if value is MISSING:
            return default
        read = self._checked(self.fields.flag(value, self.path_of(key)))
        return default if read is None else read

    def unused(self) -> list[str]:
        """The object's keys no getter read, in file order."""
        return [key for key in self.obj if key not in self.used]
