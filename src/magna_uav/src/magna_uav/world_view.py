"""What one UAV manager knows of the world at a control step (UAV-D): the latest state
of itself and every other UAV, and the obstacles, with nearest-first queries.

Pure data: the ROS side (magna_uav.ros_data) fills it from the UAL topics, the battery
topic, the depth camera and the world node's obstacle markers.

Gaps to obstacles use their real shape (`magna_uav.shapes`): the signed distance from our
centre to the obstacle's surface minus our safety radius. A 400 m wire 0.3 m thick is
0.15 m thick in every direction, not a 200 m sphere.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from magna_common import ros_names
from magna_uav.shapes import Part, ShapeTable, Sphere, bounding_sphere

UNKNOWN_BATTERY = math.nan


@dataclass
class AgentState:
    """The latest known state of one UAV, in the map frame."""

    id: int
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))  # m
    orientation: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))  # quaternion x y z w
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # m/s
    yaw_rate: float = 0.0  # rad/s
    ual_state: int = 0  # uav_abstraction_layer/State constant
    battery: float = UNKNOWN_BATTERY  # remaining charge, 0..1
    stamp: float = 0.0  # s (sim time) of the pose
    # The messages this state came from, as integer ns (exact, unlike `stamp`), for the recorder to name them:
    # their header stamps, or when they came if unstamped; velocity 0: none heard yet.
    pose_stamp_ns: int = 0
    velocity_stamp_ns: int = 0
    safety_radius: float = 0.3  # m, from the UAV's airframe
    depth: np.ndarray | None = None  # latest depth image (metres), when the camera is on

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float).reshape(3)
        self.orientation = np.asarray(self.orientation, dtype=float).reshape(4)
        self.velocity = np.asarray(self.velocity, dtype=float).reshape(3)

    @property
    def yaw(self) -> float:
        x, y, z, w = self.orientation
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass(frozen=True)
class Obstacle:
    """A world obstacle: its bounding sphere (what ORCA-3D and the networks are given) and its real shape.

    `parts` are the solids of its real shape, in map (`magna_uav.shapes`); none means the
    bounding sphere is the shape (a spherical obstacle, or one known only by its sphere).
    Gaps, the nearest-first order and collisions use the parts.
    """

    name: str
    position: np.ndarray  # m, bounding sphere centre in map
    radius: float  # m, bounding sphere
    parts: tuple[Part, ...] = field(default=(), repr=False)

    @classmethod
    def solid(cls, name: str, *parts: Part) -> Obstacle:
        """An obstacle of these parts, with a bounding sphere about the centre of their bounding box."""
        centre, radius = bounding_sphere(parts)
        return cls(name, centre, radius, tuple(parts))

    @property
    def shape(self) -> tuple[Part, ...]:
        """The solids the gaps are measured to."""
        return self.parts or (Sphere(self.position, self.radius),)


class WorldView:
    """Own state, the other UAVs' states and the obstacles, as last heard."""

    def __init__(self, own_id: int, boundaries: np.ndarray | None = None):
        self.own_id = int(own_id)
        # [[xmin, xmax], [ymin, ymax], [zmin, zmax]] or None when the world has none
        self.boundaries = None if boundaries is None else np.asarray(boundaries, dtype=float).reshape(3, 2)
        self._agents: dict[int, AgentState] = {}
        self.obstacles = ()
        self.own_pose_topic = ros_names.ual(self.own_id, "pose")  # where the own pose is heard, for the messages

    def update_agent(self, state: AgentState) -> None:
        self._agents[state.id] = state

    def agent(self, agent_id: int) -> AgentState | None:
        return self._agents.get(agent_id)

    @property
    def has_own(self) -> bool:
        return self.own_id in self._agents

    @property
    def own(self) -> AgentState:
        try:
            return self._agents[self.own_id]
        except KeyError:
            raise LookupError(f"UAV {self.own_id} has no pose yet (nothing heard on {self.own_pose_topic})") \
                from None

    def others(self) -> list[AgentState]:
        return [self._agents[i] for i in sorted(self._agents) if i != self.own_id]

    @property
    def obstacles(self) -> tuple[Obstacle, ...]:
        return self._obstacles

    @obstacles.setter
    def obstacles(self, obstacles: Iterable[Obstacle]) -> None:
        self._obstacles = tuple(obstacles)
        self._table = ShapeTable([o.shape for o in self._obstacles])  # stacked once per obstacle set
        self._distances_at: tuple[bytes, np.ndarray] | None = None

    def set_obstacles(self, obstacles: Iterable[Obstacle]) -> None:
        self.obstacles = obstacles

    def obstacle_distances(self, position: Sequence[float] | None = None) -> np.ndarray:
        """Signed distance (m) from our centre (or `position`) to each obstacle's surface, in `obstacles` order.

        Negative inside. The evaluator, the neighbour selection and the recorder ask for the
        same pose within a control step: the last answer is kept.
        """
        p = self.own.position if position is None else np.asarray(position, dtype=float).reshape(3)
        key = p.tobytes()
        if self._distances_at is None or self._distances_at[0] != key:
            self._distances_at = (key, self._table.signed_distances(p))
        return self._distances_at[1]

    def nearest_agents(self, k: int | None = None, within: float = math.inf) -> list[tuple[AgentState, float]]:
        """Other UAVs by the gap between their safety spheres and ours, nearest first (ties by id)."""
        own = self.own
        others = list(self.others())
        if not others:
            return []
        # One array operation for the swarm instead of a norm per UAV (the managers of 50 UAVs ask every step).
        # Elementwise and in a fixed order, (x*x + y*y) + z*z, so each distance is the same float on every
        # machine; np.linalg.norm's dot product depends on the CPU's BLAS kernel in its last bit.
        d = np.array([o.position for o in others], dtype=float) - own.position
        distances = np.sqrt((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2])
        gaps = [(float(distance) - o.safety_radius - own.safety_radius, o.id, o)
                for distance, o in zip(distances, others, strict=True)]
        return _nearest(gaps, k, within)

    def nearest_obstacles(self, k: int | None = None, within: float = math.inf) -> list[tuple[Obstacle, float]]:
        """Obstacles by the gap between their real shape and our safety sphere, nearest first (ties: list order).

        gap = signed distance from our centre to the obstacle's surface - our safety radius.
        """
        if not self._obstacles:
            return []
        gaps = self.obstacle_distances() - self.own.safety_radius
        order = np.argsort(gaps, kind="stable")  # stable: ties keep the obstacles' order
        order = order[gaps[order] < within]
        if k is not None:
            order = order[:k]
        return [(self._obstacles[i], float(gaps[i])) for i in order]

    def inside_boundaries(self, position: Sequence[float] | None = None) -> bool:
        if self.boundaries is None:
            return True
        p = self.own.position if position is None else np.asarray(position, dtype=float)
        return bool(np.all(p >= self.boundaries[:, 0]) and np.all(p <= self.boundaries[:, 1]))


def _nearest(gaps: list, k: int | None, within: float) -> list:
    gaps = sorted((g for g in gaps if g[0] < within), key=lambda g: (g[0], g[1]))
    if k is not None:
        gaps = gaps[:k]
    return [(item, gap) for gap, _, item in gaps]
