"""The C++ ORCA-3D library through its C interface (ctypes), with the reference's signatures.

Used by the tests (C++ against the numpy reference) and the benchmark. The library is
libmagna_orca3d.so from the catkin build: found through $MAGNA_ORCA_LIBRARY, the loader's
search path (devel/setup.bash puts devel/lib on it), or this workspace's devel/lib.
"""
from __future__ import annotations

import ctypes
import os
from collections.abc import Sequence
from functools import cache
from pathlib import Path

import numpy as np

from magna_orca_cpp.model import PARAM_FIELDS, PLANE_FIELDS, Agent, Params, Solution, agent_rows
from magna_orca_cpp.reference import Plane
from magna_orca_cpp.validation import OrcaInputError

LIBRARY_NAME = "libmagna_orca3d.so"
_WORKSPACE = Path(__file__).resolve().parents[4]
_ERROR_SIZE = 512
_BAD_INPUT = 2

_doubles = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
_ints = np.ctypeslib.ndpointer(dtype=np.intc, flags="C_CONTIGUOUS")
_sizes = np.ctypeslib.ndpointer(dtype=np.uintp, flags="C_CONTIGUOUS")
_size = ctypes.c_size_t
_text = ctypes.c_char_p
_seconds = ctypes.POINTER(ctypes.c_double)

_SIGNATURES = {
    "magna_orca_new_velocity": [_doubles, _doubles, _size, _doubles, _doubles, _ints, _text, _size],
    "magna_orca_new_velocity_many": [_doubles, _size, _doubles, _sizes, _doubles, _doubles, _ints, _seconds, _text,
                                     _size],
    "magna_orca_new_velocities": [_doubles, _size, _doubles, _doubles, _ints, _seconds, _text, _size],
    "magna_orca_half_spaces": [_doubles, _doubles, _size, _doubles, _doubles, ctypes.POINTER(_size), _text, _size],
    "magna_orca_solve_velocity": [_doubles, _size, ctypes.c_double, _doubles, _doubles, _ints, _text, _size],
}


class LibraryNotFound(RuntimeError):
    pass


@cache
def library() -> ctypes.CDLL:
    tried = []
    candidates = [os.environ.get("MAGNA_ORCA_LIBRARY"), LIBRARY_NAME, str(_WORKSPACE / "devel" / "lib" / LIBRARY_NAME)]
    for candidate in filter(None, candidates):
        try:
            lib = ctypes.CDLL(candidate)
        except OSError as error:
            tried.append(f"{candidate} ({error})")
            continue
        for name, argtypes in _SIGNATURES.items():
            function = getattr(lib, name)
            function.argtypes = argtypes
            function.restype = ctypes.c_int
        return lib
    raise LibraryNotFound(f"cannot load the ORCA-3D C++ library; tried: {'; '.join(tried)}. "
                          "Build the workspace with `make setup` (or catkin build magna_orca_cpp).")


def available() -> bool:
    try:
        library()
    except LibraryNotFound:
        return False
    return True


def _check(status: int, error: ctypes.Array) -> None:
    if status == 0:
        return
    message = error.value.decode(errors="replace")
    raise (OrcaInputError if status == _BAD_INPUT else RuntimeError)(message)


def _rows(agents: Sequence[Agent] | np.ndarray) -> np.ndarray:
    rows = agents if isinstance(agents, np.ndarray) else agent_rows(agents)
    return np.ascontiguousarray(rows, dtype=np.float64).reshape(-1, 12)


def _params_row(params: Params) -> np.ndarray:
    return np.ascontiguousarray(params.row(), dtype=np.float64).reshape(PARAM_FIELDS)


def new_velocity(agent: Agent, others: Sequence[Agent], params: Params) -> Solution:
    velocity, feasible, error = np.zeros(3), np.zeros(1, dtype=np.intc), ctypes.create_string_buffer(_ERROR_SIZE)
    others_rows = _rows(others)
    _check(library().magna_orca_new_velocity(_rows([agent])[0], others_rows, len(others_rows), _params_row(params),
                                             velocity, feasible, error, _ERROR_SIZE), error)
    return Solution(velocity, bool(feasible[0]))


def new_velocity_many(agents: np.ndarray, others: np.ndarray, offsets: np.ndarray,
                      params: Params) -> tuple[np.ndarray, np.ndarray, float]:
    """Independent one-shot problems in one call: agent rows (n, 12), all their neighbours'
    rows stacked (m, 12), and offsets (n + 1) delimiting each agent's neighbours.
    Returns velocities (n, 3), feasibility flags (n,) and the seconds spent solving."""
    agents, others = _rows(agents), _rows(others)
    offsets = np.ascontiguousarray(offsets, dtype=np.uintp)
    if offsets.shape != (len(agents) + 1,) or offsets[-1] != len(others):
        raise ValueError(f"offsets needs {len(agents) + 1} entries ending at {len(others)}")
    velocities = np.zeros((len(agents), 3))
    feasible = np.zeros(len(agents), dtype=np.intc)
    seconds = ctypes.c_double(0.0)
    error = ctypes.create_string_buffer(_ERROR_SIZE)
    _check(library().magna_orca_new_velocity_many(agents, len(agents), others, offsets, _params_row(params),
                                                  velocities, feasible, ctypes.byref(seconds), error, _ERROR_SIZE),
           error)
    return velocities, feasible.astype(bool), seconds.value


def new_velocities_array(agents: np.ndarray, params: Params) -> tuple[np.ndarray, np.ndarray, float]:
    """All agents against each other (one ORCA step) on rows (n, 12): velocities (n, 3), flags (n,)
    and the seconds spent solving (neighbour search included, input reading not)."""
    agents = _rows(agents)
    velocities = np.zeros((len(agents), 3))
    feasible = np.zeros(len(agents), dtype=np.intc)
    seconds = ctypes.c_double(0.0)
    error = ctypes.create_string_buffer(_ERROR_SIZE)
    _check(library().magna_orca_new_velocities(agents, len(agents), _params_row(params), velocities, feasible,
                                               ctypes.byref(seconds), error, _ERROR_SIZE), error)
    return velocities, feasible.astype(bool), seconds.value


def new_velocities(agents: Sequence[Agent], params: Params) -> list[Solution]:
    velocities, feasible, _ = new_velocities_array(_rows(agents), params)
    return [Solution(v, bool(f)) for v, f in zip(velocities, feasible, strict=True)]


def half_spaces(agent: Agent, others: Sequence[Agent], params: Params) -> list[Plane]:
    others_rows = _rows(others)
    planes = np.zeros((max(len(others_rows), 1), PLANE_FIELDS))
    count = _size(0)
    error = ctypes.create_string_buffer(_ERROR_SIZE)
    _check(library().magna_orca_half_spaces(_rows([agent])[0], others_rows, len(others_rows), _params_row(params),
                                            planes, ctypes.byref(count), error, _ERROR_SIZE), error)
    return [(row[:3].copy(), row[3:].copy()) for row in planes[:count.value]]


def solve_velocity(planes: Sequence[Plane], max_speed: float, preferred: np.ndarray) -> Solution:
    rows = np.ascontiguousarray([np.concatenate(plane) for plane in planes] or np.zeros((0, PLANE_FIELDS)),
                                dtype=np.float64).reshape(-1, PLANE_FIELDS)
    velocity, feasible = np.zeros(3), np.zeros(1, dtype=np.intc)
    error = ctypes.create_string_buffer(_ERROR_SIZE)
    _check(library().magna_orca_solve_velocity(rows, len(rows), float(max_speed),
                                               np.ascontiguousarray(preferred, dtype=np.float64), velocity, feasible,
                                               error, _ERROR_SIZE), error)
    return Solution(velocity, bool(feasible[0]))
