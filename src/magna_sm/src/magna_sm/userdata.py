"""Userdata: the data states pass to each other, with declared keys enforced.

A container owns a `UserData` store. Each child sees it through a `Remapper`
that lets it read only its input keys, write only its output keys, and that
renames keys as the container's remapping says (child key -> container key).
"""
from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping
from typing import Any

from magna_sm.exceptions import UserDataError


class UserData:
    """A thread-safe key/value store; keys read as attributes or items."""

    def __init__(self, initial: Mapping[str, Any] | None = None):
        object.__setattr__(self, "_data", dict(initial or {}))
        object.__setattr__(self, "_lock", threading.Lock())

    def __getitem__(self, key: str) -> Any:
        with self._lock:
            try:
                return self._data[key]
            except KeyError:
                raise UserDataError(f"userdata has no key '{key}'") from None

    def __setitem__(self, key: str, value: Any) -> None:
        with self._lock:
            self._data[key] = value

    def __getattr__(self, key: str) -> Any:
        if key.startswith("_"):
            raise AttributeError(key)
        return self[key]

    def __setattr__(self, key: str, value: Any) -> None:
        self[key] = value

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._data

    def keys(self) -> list[str]:
        with self._lock:
            return list(self._data)

    def update(self, other: Mapping[str, Any]) -> None:
        with self._lock:
            self._data.update(other)

    def to_dict(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._data)

    def __repr__(self) -> str:
        return f"UserData({self.to_dict()!r})"


class Remapper:
    """What one state sees of its container's userdata."""

    __slots__ = ("_store", "_inputs", "_outputs", "_remapping", "_owner")

    def __init__(self, store: UserData | Remapper, input_keys: Iterable[str], output_keys: Iterable[str],
                 remapping: Mapping[str, str] | None, owner: str):
        self._store = store
        self._inputs = frozenset(input_keys)
        self._outputs = frozenset(output_keys)
        self._remapping = dict(remapping or {})
        self._owner = owner

    def _outer(self, key: str) -> str:
        return self._remapping.get(key, key)

    def __getitem__(self, key: str) -> Any:
        if key not in self._inputs:
            if key in self._outputs:
                raise UserDataError(f"{self._owner}: key '{key}' is output-only; declare it as an input key to read it")
            raise UserDataError(f"{self._owner}: reads undeclared userdata key '{key}'; add it to input_keys")
        return self._store[self._outer(key)]

    def __setitem__(self, key: str, value: Any) -> None:
        if key not in self._outputs:
            if key in self._inputs:
                raise UserDataError(f"{self._owner}: key '{key}' is input-only (read-only); "
                                    "declare it as an output key to write it")
            raise UserDataError(f"{self._owner}: writes undeclared userdata key '{key}'; add it to output_keys")
        self._store[self._outer(key)] = value

    def __getattr__(self, key: str) -> Any:
        if key.startswith("_"):
            raise AttributeError(key)
        return self[key]

    def __setattr__(self, key: str, value: Any) -> None:
        if key in Remapper.__slots__:
            object.__setattr__(self, key, value)
        else:
            self[key] = value

    def __contains__(self, key: object) -> bool:
        return key in self._inputs and self._outer(key) in self._store

    def keys(self) -> list[str]:
        return sorted(k for k in self._inputs if self._outer(k) in self._store)
