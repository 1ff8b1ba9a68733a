"""Simulation bag -> the steps of every UAV (`mlr.steps.UavSteps`), as the recorder CSVs hold them.

The ground station bags (magna_gs `bag_recorder.mission_topics`) what a UAV manager saw and did at each control
step, so the steps can be rebuilt where no CSV exists (a real flight's bag, a lost file):

- `/magna/uav_{id}/navigation` (magna_msgs/NavigationStep): one message per recorded step, with
  that CSV row's time (the stamp), role, algorithm, goal, goal_vel, goal_dist, sel_vel and
  teacher_vel (NaN in bags made before steps carried it), and its row index. One step per row
  index, in row order: a repeat (the manager replays its steps to a late subscriber, see
  magna_uav's README) is dropped. So the steps are the CSV's rows,
  except rows whose message the bag missed (none, normally).
- own and other UAVs' position and velocity: the very `/uav_{id}/ual/pose` and
  `/uav_{id}/ual/velocity` messages the manager used, which each step names by their stamps
  (`uav_ids`, `pose_stamps`, `velocity_stamps`; for the other UAVs the manager hears their odom,
  stamped as the pose and velocity of the same instant): the newest one stamped at or before the
  named stamp, which is that very message when the bag has it. A UAV the step does not name was
  not in the manager's view yet: NaN, as in the CSV; a zero velocity stamp means no velocity heard
  yet: zero, as in the CSV. Bags made before the steps named their messages (no `uav_ids`) take
  the newest stamped at or before the step itself: mostly the message the manager used, else a
  neighbour in the 30 Hz stream, depending on when the manager's subscriber got it. A zero stamp
  counts as the time the bag got the message. Before the bag's first message of a UAV: NaN (the
  ground station lets the bag connect before any UAV moves; bags made before it did may miss the
  first take-off steps, as rosbag finds a new topic only within about a wall second). Others' gap =
  centre distance minus both safety radii (the airframes' `safety_radius`, the models of
  `mission.json`), as the view computes it.
- obstacles: the managers learn them only from the world node's `/magna/world/markers`, as the
  obstacles (real shape and bounding sphere) `magna_uav.ros_data.ObstacleMarkers` makes of the
  "obstacles" markers; the same class replays the bagged marker messages up to each step (by the
  time the bag got them), so a world part added or deleted mid-mission counts from then on. The
  markers are latched and have no stamp: a manager may have them a step or two before the bag
  does, so the bag may know fewer obstacles than the CSV in those steps, never more. They
  are ranked by the gap between own safety sphere and the obstacle's real shape, nearest first,
  ties in the markers' order, as the recorder ranks them; K = `magna_uav.recorder.DEFAULT_OBSTACLES`
  slots, NaN where fewer.
- role_end: the last step of each role, i.e. the last message of each `role_number`; the recorder
  writes the role's outcome on that same row, so `role_end` equals the CSV's (`outcome != ""`).

The bag is read by `magna_common.simulation_bag` (rosbags, pure Python: the message definitions
come from the bag, so magna_msgs need not be built); the markers' geometry comes from
magna_uav.ros_data, which imports the ROS message packages (geometry_msgs, visualization_msgs: no
rospy, no master).
Depth images are not bagged: `depth_frames` stays None.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from magna_common import ros_names
from magna_common.simulation_bag import BagError, BagMessage, read_simulation_bag
from magna_common.storage_tree import BAG_FILE, MISSION_FILE
from magna_uav.config import ConfigError, configs_from_mission_file
from magna_uav.recorder import DEFAULT_OBSTACLES
from magna_uav.world_view import AgentState, WorldView
from mlr.steps import PicklerError, UavSteps

_USE_CSV = "use the CSVs (source csv)"
NOT_IN_VIEW = -1  # a used-message stamp: the step had nothing of that UAV
NO_VELOCITY_YET = -2  # a used-message stamp: the step had the UAV's pose, but no velocity yet


class _Series:
    """Vectors by stamp (integer ns), for 'the newest at or before t'."""

    def __init__(self):
        self._stamps: list[int] = []
        self._values: list[tuple[float, float, float]] = []
        self.stamps = np.zeros(0, dtype=np.int64)
        self.values = np.zeros((0, 3))

    def add(self, stamp: int, value: tuple[float, float, float]) -> None:
        self._stamps.append(stamp)
        self._values.append(value)

    def freeze(self) -> None:
        # A stable sort: of equal stamps (the simulator re-sends the pose while paused) the last heard wins.
        order = np.argsort(np.asarray(self._stamps, dtype=np.int64), kind="stable")
        self.stamps = np.asarray(self._stamps, dtype=np.int64)[order]
        self.values = np.asarray(self._values, dtype=float).reshape(-1, 3)[order]

    def at(self, stamps: np.ndarray) -> np.ndarray:
        """(n, 3) the newest value stamped at or before each of `stamps`; NaN before the first and for
        NOT_IN_VIEW, zero for NO_VELOCITY_YET."""
        k = np.searchsorted(self.stamps, stamps, side="right") - 1
        out = np.full((len(stamps), 3), np.nan)
        known = (k >= 0) & (stamps >= 0)
        out[known] = self.values[k[known]]
        out[stamps == NO_VELOCITY_YET] = 0.0
        return out


def _ns(time) -> int:
    return int(time.sec) * 10**9 + int(time.nanosec)


def _used_stamps(msgs: list, stamps: np.ndarray, uav: int) -> tuple[np.ndarray, np.ndarray]:
    """Per step, the stamps of `uav`'s pose and velocity messages the step used (module docstring)."""
    pose = np.full(len(msgs), NOT_IN_VIEW, dtype=np.int64)
    velocity = pose.copy()
    for i, msg in enumerate(msgs):
        named = getattr(msg, "uav_ids", None)
        if named is None:  # a bag made before the steps named their messages: the step's own stamp
            pose[i] = velocity[i] = stamps[i]
            continue
        for k, j in enumerate(named):
            if int(j) == uav:
                pose[i] = _ns(msg.pose_stamps[k])
                velocity[i] = _ns(msg.velocity_stamps[k]) or NO_VELOCITY_YET
                break
    return pose, velocity


def _xyz(v) -> tuple[float, float, float]:
    return (float(v.x), float(v.y), float(v.z))


def _safety_radii(sim_dir: Path, ids) -> dict[int, float]:
    mission = sim_dir / MISSION_FILE
    try:
        radii = {c.id: float(c.safety_radius) for c in configs_from_mission_file(mission)}
    except ConfigError as err:
        raise PicklerError(f"{err} (the UAVs' safety radii come from their models there)") from None
    missing = sorted(set(ids) - set(radii))
    if missing:
        raise PicklerError(f"{mission}: UAV {missing[0]} is not in Agents_Config: its safety radius is unknown")
    return radii


def steps_from_bag(sim_dir: str | Path, max_speeds: Mapping[int, float],
                   safety_radii: Mapping[int, float] | None = None) -> list[UavSteps]:
    """The steps of every UAV of `max_speeds` (sorted by id) from `sim_dir/simulation.bag` (module docstring).

    `safety_radii` (UAV id -> m) defaults to the airframes of `sim_dir/mission.json`'s models.
    A UAV without navigation messages gets no steps; a bag without any raises PicklerError.
    """
    sim_dir = Path(sim_dir)
    bag = sim_dir / BAG_FILE
    if not bag.is_file():
        raise PicklerError(f"{bag}: no such bag (the simulation ran with --no-bag?): {_USE_CSV}")
    ids = sorted(int(i) for i in max_speeds)
    radii = dict(safety_radii) if safety_radii is not None else _safety_radii(sim_dir, ids)
    if missing := [i for i in ids if i not in radii]:
        raise PicklerError(f"{bag}: no safety radius for UAV {missing[0]}")
    navigation, poses, velocities, markers = _read(bag)
    if not navigation:
        raise PicklerError(f"{bag}: no {ros_names.manager('<id>', 'navigation')} messages: recorded before "
                           f"navigation steps were bagged: {_USE_CSV}")
    strangers = sorted(set(navigation) - set(ids))
    if strangers:
        raise PicklerError(f"{bag}: UAV {strangers[0]} flew but is not in the simulation's mission.json "
                           "Agents_Config")
    return [_uav_steps(bag, uav, float(max_speeds[uav]), navigation.get(uav, []), poses, velocities, markers,
                       radii, ids) for uav in ids]


def _series(messages: list[BagMessage], vector: Callable) -> _Series:
    series = _Series()
    for message in messages:
        series.add(message.stamp, _xyz(vector(message.msg)))
    series.freeze()
    return series


def _read(bag: Path):
    try:
        read = read_simulation_bag(bag, ("navigation", "pose", "velocity", "markers"))
    except BagError as err:
        raise PicklerError(f"{bag}: cannot read the bag: {err.reason}") from None
    # UAV -> row -> (stamp, message), keyed by row: a replayed step is the same row (two steps may share a stamp)
    navigation: dict[int, dict[int, tuple]] = {
        uav: {int(step.msg.row): (step.stamp, step.msg) for step in steps}
        for uav, steps in read.by_owner("navigation").items()}
    poses = {uav: _series(found, lambda msg: msg.pose.position) for uav, found in read.by_owner("pose").items()}
    velocities = {uav: _series(found, lambda msg: msg.twist.linear)
                  for uav, found in read.by_owner("velocity").items()}
    # the markers count from when the bag got them (a MarkerArray has no stamp of its own)
    markers = sorted(((m.log_time, m.msg) for m in read.of("markers")), key=lambda item: item[0])
    ordered = {uav: [steps[row] for row in sorted(steps)] for uav, steps in navigation.items()}
    return ordered, poses, velocities, markers


def _uav_steps(bag: Path, uav: int, max_speed: float, messages: list, poses, velocities, markers, radii,
               ids: list[int]) -> UavSteps:
    n = len(messages)
    stamps = np.array([stamp for stamp, _ in messages], dtype=np.int64)
    msgs = [msg for _, msg in messages]
    numbers = np.array([m.role_number for m in msgs], dtype=np.int64)
    empty = _Series()
    empty.freeze()
    used = {j: _used_stamps(msgs, stamps, j) for j in ids}
    position = poses.get(uav, empty).at(used[uav][0])
    others = {}
    for j in ids:
        if j == uav:
            continue
        other_position = poses.get(j, empty).at(used[j][0])
        distance = np.linalg.norm(other_position - position, axis=1)
        others[j] = (other_position, velocities.get(j, empty).at(used[j][1]), distance - radii[uav] - radii[j])
    obstacle_pos, obstacle_gap = _ranked_obstacles(stamps, position, radii[uav], markers)
    return UavSteps(
        source=bag,
        uav_id=uav,
        max_speed=max_speed,
        time=stamps / 1e9,
        role=np.array([m.role for m in msgs], dtype=object),
        algorithm=np.array([m.algorithm for m in msgs], dtype=object),
        position=position,
        velocity=velocities.get(uav, empty).at(used[uav][1]),
        goal=np.array([_xyz(m.goal) for m in msgs], dtype=float).reshape(n, 3),
        goal_vel=np.array([_xyz(m.goal_velocity) for m in msgs], dtype=float).reshape(n, 3),
        goal_dist=np.array([m.goal_distance for m in msgs], dtype=float),
        sel_vel=np.array([_xyz(m.selected_velocity) for m in msgs], dtype=float).reshape(n, 3),
        teacher_vel=np.array([_xyz(m.teacher_velocity) if hasattr(m, "teacher_velocity") else (math.nan,) * 3
                              for m in msgs], dtype=float).reshape(n, 3),
        # the last message of a role: the row where the recorder writes the role's outcome
        role_end=np.append(numbers[1:] != numbers[:-1], True) if n else np.zeros(0, dtype=bool),
        others=others,
        obstacle_pos=obstacle_pos,
        obstacle_gap=obstacle_gap,
    )


def _ranked_obstacles(stamps: np.ndarray, position: np.ndarray, safety_radius: float, markers: list,
                      k: int = DEFAULT_OBSTACLES) -> tuple[np.ndarray, np.ndarray]:
    """(n, k, 3) centres and (n, k) gaps of the k nearest obstacles at each step, as a manager's view ranks them."""
    out_pos = np.full((len(stamps), k, 3), np.nan)
    out_gap = np.full((len(stamps), k), np.nan)
    if not markers:
        return out_pos, out_gap
    from magna_uav.ros_data import ObstacleMarkers  # the managers' own reading of the markers

    table = ObstacleMarkers()
    view = WorldView(0)
    applied = 0
    for i, stamp in enumerate(stamps):
        while applied < len(markers) and markers[applied][0] <= stamp:
            table.apply(markers[applied][1])  # rosbags' messages have the fields and values of the ROS ones
            view.set_obstacles(table.obstacles())
            applied += 1
        if not np.all(np.isfinite(position[i])) or not view.obstacles:
            continue
        view.update_agent(AgentState(0, position[i], safety_radius=safety_radius))
        for slot, (obstacle, gap) in enumerate(view.nearest_obstacles(k)):
            out_pos[i, slot] = obstacle.position
            out_gap[i, slot] = gap if math.isfinite(gap) else np.nan
    return out_pos, out_gap


__all__ = ["steps_from_bag"]
