"""What a navigation algorithm steers towards: a `Goal` in the map frame, with its role.

`position` is always the point to fly to, already worked out by the role:

- "path" (follow_path): the next waypoint (or the carrot on the path);
- "basic_move" (basic_move): the end of the move;
- "agent_ad" (follow_agent_ad): the point `distance` metres from the target UAV on the
  line from it to us; `velocity` is the target's velocity, `distance` the distance kept;
- "agent_ap" (follow_agent_ap): the target UAV's (predicted) position plus `offset`
  (map frame); `velocity` is the target's velocity.

`velocity` (the target's own velocity, feed-forward for the following roles) None means a
still target. `distance` and `offset` describe the following role (the neural networks'
"distance" input); the guidance does not add them again. `yaw` (rad, map frame) is the
heading wanted at the goal, or None.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ROLES = ("path", "agent_ad", "agent_ap", "basic_move")
FOLLOWING_ROLES = ("agent_ad", "agent_ap")


def _vector3(value, name: str) -> np.ndarray:
    try:
        vector = np.array(value, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise ValueError(f"Goal.{name} is {value!r}: give three numbers [x, y, z] in the map frame") from None
    if not np.all(np.isfinite(vector)):
        raise ValueError(f"Goal.{name} is {vector.tolist()}: give finite numbers")
    return vector


@dataclass
class Goal:
    """The point to fly to (map frame) and what the role knows about it (module docstring)."""

    position: np.ndarray  # (3,) m
    role: str = "path"
    velocity: np.ndarray | None = None  # (3,) m/s, the target's velocity (following roles)
    distance: float | None = None  # m, agent_ad: the distance kept from the target (required there)
    offset: np.ndarray | None = None  # (3,) m, agent_ap: the offset from the target already in `position`
    yaw: float | None = None  # rad, heading wanted at the goal

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"Goal.role is {self.role!r}: give one of {', '.join(ROLES)}")
        self.position = _vector3(self.position, "position")
        if self.velocity is not None:
            self.velocity = _vector3(self.velocity, "velocity")
        if self.offset is not None:
            self.offset = _vector3(self.offset, "offset")
        if self.distance is not None:
            self.distance = float(self.distance)
            if not math.isfinite(self.distance) or self.distance < 0.0:
                raise ValueError(f"Goal.distance is {self.distance}: give a finite distance >= 0 in metres")
        if self.role == "agent_ad" and self.distance is None:
            raise ValueError("Goal.distance is missing: role 'agent_ad' follows at a distance; give it in metres")
        if self.yaw is not None:
            self.yaw = float(self.yaw)
            if not math.isfinite(self.yaw):
                raise ValueError(f"Goal.yaw is {self.yaw}: give a finite angle in radians or None")

    @property
    def target_velocity(self) -> np.ndarray:
        """The target's velocity, zeros for a still target."""
        return np.zeros(3) if self.velocity is None else self.velocity
