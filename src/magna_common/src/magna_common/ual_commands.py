"""What every UAL server refuses the same way: a command that cannot be done now, and numbers that are not
finite. magna_sim's UAL and ual_mavlink both raise these, so a client reads the same reasons from either."""
from __future__ import annotations

import math

import numpy as np


class CommandRefused(ValueError):
    """A UAL command that cannot be done now; the message is for the caller."""


def require_finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise CommandRefused(f"{name}: {value} is not a finite number")


def finite_vector(name: str, values) -> np.ndarray:
    """`values` as three finite floats, or CommandRefused naming `name`."""
    vector = np.asarray(values, dtype=float)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise CommandRefused(f"{name}: {np.ravel(vector).tolist()} is not three finite numbers")
    return vector
