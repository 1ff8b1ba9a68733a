"""Accuracy, defined once (mlr/README.md, "Accuracy").

A prediction is right when the predicted velocity is within 0.1 x the UAV's max speed
(Euclidean norm of the difference, in m/s) of the velocity the teacher chose. Accuracy is the
share of samples predicted right. With an iris (max speed 2 m/s) the tolerance is 0.2 m/s.
"""
from __future__ import annotations

import numpy as np

TOLERANCE = 0.1  # of the max speed


def within_tolerance(predicted: np.ndarray, teacher: np.ndarray, max_speed: np.ndarray) -> np.ndarray:
    """Per sample: whether the prediction is right (all in m/s; max_speed per sample)."""
    error = np.linalg.norm(np.asarray(predicted, dtype=float) - np.asarray(teacher, dtype=float), axis=1)
    return error <= TOLERANCE * np.asarray(max_speed, dtype=float)


def accuracy(predicted: np.ndarray, teacher: np.ndarray, max_speed: np.ndarray) -> float:
    right = within_tolerance(predicted, teacher, max_speed)
    return float(right.mean()) if len(right) else float("nan")
