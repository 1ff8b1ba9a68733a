"""The fixed value sets of the world format: each a Literal type (for mypy) and a tuple of its values, in the
order messages list them. The values are the files' own spellings and stay plain strings at run time (they go
into ROS messages, parameters and JSON as they are). Imports nothing heavy: missions use it too.
"""
from __future__ import annotations

from typing import Literal, get_args

Shape = Literal["cube", "sphere", "cylinder", "torus", "prism"]  # a geometry's or an obstacle's solid
SHAPES: tuple[Shape, ...] = get_args(Shape)

PoseSetType = Literal["matrix", "random", "coordinates", "zigzag"]  # how a pose set lays out its poses
POSE_SET_TYPES: tuple[PoseSetType, ...] = get_args(PoseSetType)

PoseUse = Literal["poses", "obstacles"]  # a set's poses are free-space poses, or where its obstacles stand
USES: tuple[PoseUse, ...] = get_args(PoseUse)

MatrixType = Literal["dimension", "distance"]  # a matrix's dimensions: counts per axis, or spacings in m
MATRIX_TYPES: tuple[MatrixType, ...] = get_args(MatrixType)

Sense = Literal["left", "right"]  # the side a zigzag turns to first
SENSES: tuple[Sense, ...] = get_args(Sense)

# The third item of a mission's pose definition [volume, geometry, kind, arg] (magna_worlds.query resolves it).
PoseKind = Literal["matrix", "random", "coordinates", "path", "poses"]
POSE_KINDS: tuple[PoseKind, ...] = get_args(PoseKind)
