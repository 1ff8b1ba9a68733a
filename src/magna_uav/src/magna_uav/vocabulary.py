"""The fixed value sets of the goals a UAV manager takes (basic_move's parameters): each a Literal type (for
mypy) and a tuple of its values, in the order messages list them. Missions write the same words, so the mission
model (magna_gs.mission.model) takes them from here. Imports nothing heavy: the mission checker uses it too.
"""
from __future__ import annotations

from typing import Literal, get_args

MoveType = Literal["takeoff", "land", "translation", "rotation"]  # basic_move
MOVE_TYPES: tuple[MoveType, ...] = get_args(MoveType)
Direction = Literal["up", "down", "left", "right", "forward", "backward"]  # basic_move
DIRECTIONS: tuple[Direction, ...] = get_args(Direction)
Dynamic = Literal["position", "velocity"]  # what a move commands
DYNAMICS: tuple[Dynamic, ...] = get_args(Dynamic)
