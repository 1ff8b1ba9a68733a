"""ROS and MAVLink frame conventions, and the conversions between them.

ROS (REP 103) uses ENU for the world (x east, y north, z up) and FLU for the body (x forward,
y left, z up); MAVLink uses NED for the local world (x north, y east, z down) and FRD for the
body (x forward, y right, z down). Yaw is measured from east, anticlockwise, in ENU and from
north, clockwise, in NED: ENU yaw 90 deg (facing north) is NED yaw 0.

Every conversion is its own inverse in shape (swap x and y, negate z), so each pair of functions
shares one matrix. Angles come back wrapped to (-pi, pi].
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

# World: a vector in ENU as NED (and back: the matrix is its own inverse).
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
# Body: a vector in FLU as FRD (and back).
FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])


def wrap_angle(angle: float) -> float:
    """The same angle in (-pi, pi]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def enu_to_ned(vector: ArrayLike) -> np.ndarray:
    """A position or velocity in ENU as NED."""
    return ENU_TO_NED @ np.asarray(vector, dtype=float)


def ned_to_enu(vector: ArrayLike) -> np.ndarray:
    """A position or velocity in NED as ENU."""
    return ENU_TO_NED @ np.asarray(vector, dtype=float)


def flu_to_frd(vector: ArrayLike) -> np.ndarray:
    """A body-frame vector (velocity, angular rate) in FLU as FRD."""
    return FLU_TO_FRD @ np.asarray(vector, dtype=float)


def frd_to_flu(vector: ArrayLike) -> np.ndarray:
    """A body-frame vector in FRD as FLU."""
    return FLU_TO_FRD @ np.asarray(vector, dtype=float)


def yaw_enu_to_ned(yaw: float) -> float:
    """Heading from east anticlockwise (ENU) as heading from north clockwise (NED)."""
    return wrap_angle(math.pi / 2.0 - yaw)


def yaw_ned_to_enu(yaw: float) -> float:
    """Heading from north clockwise (NED) as heading from east anticlockwise (ENU)."""
    return wrap_angle(math.pi / 2.0 - yaw)


def attitude_enu_flu_to_ned_frd(quaternion_xyzw: ArrayLike) -> np.ndarray:
    """The body attitude as ROS gives it (FLU body in the ENU world, x, y, z, w) as MAVLink wants it
    (FRD body in the NED world, x, y, z, w). MAVLink messages order it w, x, y, z: reorder at the edge."""
    matrix = ENU_TO_NED @ Rotation.from_quat(quaternion_xyzw).as_matrix() @ FLU_TO_FRD
    return Rotation.from_matrix(matrix).as_quat()


def attitude_ned_frd_to_enu_flu(quaternion_xyzw: ArrayLike) -> np.ndarray:
    """The inverse of attitude_enu_flu_to_ned_frd."""
    matrix = ENU_TO_NED @ Rotation.from_quat(quaternion_xyzw).as_matrix() @ FLU_TO_FRD
    return Rotation.from_matrix(matrix).as_quat()
