"""Rigid frames: the origin `[[x, y, z], [roll, pitch, yaw]]` of the world files as a rotation and a translation.

Angles are radians, fixed axes x-y-z (roll about x, then pitch about y, then yaw
about z, all about the parent's axes), the convention of tf's
`quaternion_from_euler(r, p, y)`, so R = Rz(yaw) Ry(pitch) Rx(roll).
Quaternions are [x, y, z, w] as ROS writes them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation


@dataclass(frozen=True)
class Frame:
    """A child frame expressed in its parent: p_parent = rotation @ p_child + translation."""

    translation: np.ndarray  # (3,)
    rotation: np.ndarray  # (3, 3)

    @staticmethod
    def identity() -> Frame:
        return Frame(np.zeros(3), np.eye(3))

    @staticmethod
    def from_xyz_rpy(xyz: npt.ArrayLike, rpy: npt.ArrayLike = (0.0, 0.0, 0.0)) -> Frame:
        return Frame(np.asarray(xyz, dtype=float), rotation_from_rpy(rpy))

    @staticmethod
    def from_xyz_quaternion(xyz: npt.ArrayLike, quaternion_xyzw: npt.ArrayLike) -> Frame:
        return Frame(np.asarray(xyz, dtype=float), Rotation.from_quat(quaternion_xyzw).as_matrix())

    def compose(self, child: Frame) -> Frame:
        """The frame `child` (given in self) expressed in self's parent."""
        return Frame(self.rotation @ child.translation + self.translation, self.rotation @ child.rotation)

    def inverse(self) -> Frame:
        rt = self.rotation.T
        return Frame(-rt @ self.translation, rt)

    def apply(self, points: npt.ArrayLike) -> np.ndarray:
        """Points (N, 3) given in this frame, expressed in the parent."""
        return np.asarray(points, dtype=float) @ self.rotation.T + self.translation

    def quaternion(self) -> np.ndarray:
        return Rotation.from_matrix(self.rotation).as_quat()

    def rpy(self) -> np.ndarray:
        return Rotation.from_matrix(self.rotation).as_euler("xyz")


def rotation_from_rpy(rpy: npt.ArrayLike) -> np.ndarray:
    return Rotation.from_euler("xyz", np.asarray(rpy, dtype=float)).as_matrix()


def quaternions_from_rpy(rpy: npt.ArrayLike) -> np.ndarray:
    """(N, 3) roll-pitch-yaw rows to (N, 4) quaternions [x, y, z, w]."""
    return Rotation.from_euler("xyz", np.asarray(rpy, dtype=float).reshape(-1, 3)).as_quat()


def rotate_quaternions(rotation: np.ndarray, quaternions: npt.ArrayLike) -> np.ndarray:
    """Orientations (N, 4) given in a frame, expressed in its parent whose rotation is `rotation`."""
    return (Rotation.from_matrix(rotation) * Rotation.from_quat(np.asarray(quaternions).reshape(-1, 4))).as_quat()
