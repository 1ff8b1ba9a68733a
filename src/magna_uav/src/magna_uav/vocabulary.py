"""The fixed value sets of the goals a UAV manager takes (basic_move's parameters): each a Literal type (for
mypy) and a tuple of its values, in the order messages list them. Missions write the same words, so the mission
model (magna_gs.mission.model) takes them from here. Imports nothing heavy: the mission checker uses it too.
"""
from __future__ import annotations

import math
from typing import Literal, get_args

MoveType = Literal["takeoff", "land", "translation", "rotation"]  # basic_move
MOVE_TYPES: tuple[MoveType, ...] = get_args(MoveType)
Direction = Literal["up", "down", "left", "right", "forward", "backward"]  # basic_move
DIRECTIONS: tuple[Direction, ...] = get_args(Direction)
Dynamic = Literal["position", "velocity"]  # what a move commands
DYNAMICS: tuple[Dynamic, ...] = get_args(Dynamic)


def direction_vector(direction: Direction, yaw: float) -> tuple[float, float, float]:
    """The unit vector, in the map frame, of a basic_move direction for a UAV heading `yaw` (rad): forward is
    along the heading, left 90 degrees counter-clockwise of it, up and down along z."""
    cos, sin = math.cos(yaw), math.sin(yaw)
    return {"up": (0.0, 0.0, 1.0), "down": (0.0, 0.0, -1.0), "forward": (cos, sin, 0.0),
            "backward": (-cos, -sin, 0.0), "left": (-sin, cos, 0.0), "right": (sin, -cos, 0.0)}[direction]
