"""The world file as plain typed objects, checked once by `loader` (the ROS-MAGNA world format:
worlds/README.md).

World -> Volume -> Geometry -> PoseSetSpec. Positions are metres, angles radians,
colours 0..1 (the files write 0-255). Nothing here is random: `generate` turns
the specs into poses and obstacles for a given seed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from magna_worlds.shapes import ShapeSpec
from magna_worlds.transforms import Frame
from magna_worlds.vocabulary import MatrixType, PoseSetType, PoseUse, Sense, Shape

SHAPES_FOR_ZIGZAG: tuple[Shape, ...] = ("prism",)


@dataclass(frozen=True)
class OrientationSpec:
    """How generated poses are turned: a fixed roll-pitch-yaw, or drawn per pose.

    `ranges` holds [low, high] per roll, pitch, yaw; a fixed orientation has low == high.
    `any_rotation` draws uniformly over all 3-D rotations (`"random"` in the file).
    """

    ranges: tuple[tuple[float, float], ...] = ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    any_rotation: bool = False

    @property
    def fixed(self) -> bool:
        return not self.any_rotation and all(low == high for low, high in self.ranges)


@dataclass(frozen=True)
class ObstacleSpec:
    """What each obstacle of a set looks like: a shape drawn from `shapes`, dimensions fixed or drawn per axis."""

    shapes: tuple[Shape, ...]
    dimension_ranges: tuple[tuple[float, float], ...]  # [low, high] per dimension; prism: height only
    prism_polygon: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class PoseSetSpec:
    type: PoseSetType
    use: PoseUse
    source_path: str  # JSON path of the set, for messages
    orientation: OrientationSpec = OrientationSpec()
    set_yaw: float = 0.0  # matrix over a prism: yaw of the grid (set_orientation[2])
    obstacle: ObstacleSpec | None = None
    # matrix
    matrix_type: MatrixType = "dimension"
    matrix_dimensions: tuple[float, float, float] = (1, 1, 1)  # counts (dimension) or spacings in m (distance)
    density: float = 1.0
    # random
    quantity: int = 0
    # coordinates: (N, 3) positions and (N, 4) quaternions, in the geometry frame
    coordinates: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = ()
    # zigzag
    height: float = 0.0
    spacing: tuple[float, float] = (0.0, 0.0)  # along each line (0: its ends only), between lines
    sweep_angle: float = 0.0
    margins: tuple[float, float] = (0.0, 0.0)  # at each line's ends, from the first and last line to the edge
    initial_sense: Sense = "right"


@dataclass(frozen=True)
class Geometry:
    name: str
    prefix: str
    spec: ShapeSpec
    id: int
    origin: Frame  # in the volume frame
    color: tuple[float, float, float]  # 0..1
    alpha: float
    pose_sets: tuple[PoseSetSpec, ...]
    source_path: str
    frame_prefix: str = ""  # names its pose and obstacle frames instead of `prefix` (a prefix its volume repeats)


@dataclass(frozen=True)
class Volume:
    name: str
    prefix: str
    origin: Frame  # in the map frame
    permits: str
    geometries: tuple[Geometry, ...]
    source: str  # file the volume was read from
    source_path: str

    def geometry(self, name: str) -> Geometry | None:
        return next((g for g in self.geometries if g.name == name), None)


@dataclass(frozen=True)
class World:
    source: str
    boundaries: np.ndarray  # (3, 2): [[xmin, xmax], [ymin, ymax], [zmin, zmax]]
    origin_geo: tuple[float, float, float] | None
    volumes: tuple[Volume, ...]
    included: tuple[str, ...] = ()  # nested files, in load order
    warnings: tuple[str, ...] = field(default=())  # what the original tolerated, and what MAGNA does with it
    changes: tuple[str, ...] = field(default=())  # what the migration of an older format changed
    boundaries_defaulted: bool = False  # the file had no world_boundaries: the box around its geometries

    def volume(self, name: str) -> Volume | None:
        return next((v for v in self.volumes if v.name == name), None)
