"""The control steps of one UAV in one simulation, as columns: what both readers produce, and the error both raise.

`mlr.pickler` fills a `UavSteps` from a recorder CSV, `mlr.bags` from a simulation bag; the
input vectors are then built from it by one function (`mlr.pickler.samples`), so the two
sources cannot drift apart. Every quantity is in the map frame, metres and m/s; NaN marks a
value the source did not have (a UAV not heard of yet, a role without a target velocity).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


class PicklerError(ValueError):
    """Data that cannot become samples; the message names the file and the fix."""


@dataclass
class UavSteps:
    """n control steps of UAV `uav_id`, oldest first."""

    source: Path  # the CSV or bag they came from (named in errors)
    uav_id: int
    max_speed: float  # m/s, from the UAV's airframe: accuracy's tolerance is 0.1 of it
    time: np.ndarray  # (n,) simulated s
    role: np.ndarray  # (n,) str: path, agent_ad, agent_ap, take_off, land, basic_move...
    algorithm: np.ndarray  # (n,) str: simple, orca3d, neural_network, ual
    position: np.ndarray  # (n, 3)
    velocity: np.ndarray  # (n, 3)
    goal: np.ndarray  # (n, 3) the point the role flies to
    goal_vel: np.ndarray  # (n, 3) the target's velocity (follower roles), NaN otherwise
    goal_dist: np.ndarray  # (n,) the distance kept from the target (agent_ad), NaN otherwise
    sel_vel: np.ndarray  # (n, 3) the velocity the navigation algorithm chose: the teacher's label
    role_end: np.ndarray  # (n,) bool: the role's last step (its outcome was written there)
    # (n, 3) ORCA-3D's answer from the same inputs while a network flew (DAgger's label), NaN otherwise
    teacher_vel: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # other UAV id -> (position (n, 3), velocity (n, 3), gap between safety spheres (n,))
    others: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    obstacle_pos: np.ndarray | None = None  # (n, K, 3) the K nearest obstacles' centres, nearest first
    obstacle_gap: np.ndarray | None = None  # (n, K) their gaps (NaN where fewer than K obstacles)
    depth_frames: np.ndarray | None = None  # (f, H, W) depth images in metres, if the camera was on
    depth_rows: np.ndarray | None = None  # (f,) the step each frame arrived at

    def __post_init__(self) -> None:
        if len(self.teacher_vel) != len(self.time):  # a source without the teacher's answer: unknown
            self.teacher_vel = np.full((len(self.time), 3), np.nan)

    def __len__(self) -> int:
        return len(self.time)

    def depth_at(self, step: int) -> np.ndarray | None:
        """The newest depth frame that arrived at or before `step`, or None."""
        if self.depth_frames is None or self.depth_rows is None or not len(self.depth_rows):
            return None
        k = int(np.searchsorted(self.depth_rows, step, side="right")) - 1
        return None if k < 0 else self.depth_frames[k]
