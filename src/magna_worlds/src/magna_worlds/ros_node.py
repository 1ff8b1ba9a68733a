"""The world node: holds the world parts, publishes their frames and markers, spawns their obstacles.

All world logic lives in `registry` (no ROS); this module only turns requests and
results into messages.
"""
from __future__ import annotations

import argparse
import threading
from pathlib import Path

import numpy as np
import rospy
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion, TransformStamped
from magna_msgs.srv import (
    AddWorldPart,
    AddWorldPartResponse,
    DeleteModel,
    DeleteWorldPart,
    DeleteWorldPartResponse,
    GetFreeSpacePoseSet,
    GetFreeSpacePoseSetResponse,
    ResetWorld,
    ResetWorldResponse,
    SpawnModel,
    SpawnModelRequest,
)
from std_msgs.msg import ColorRGBA
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from magna_common import ros_names as names
from magna_common.records import Hyperparameters, WorldRecord
from magna_worlds.errors import WorldError
from magna_worlds.generate import ResolvedWorld
from magna_worlds.markers import OBSTACLE_COLOR, world_markers
from magna_worlds.query import QueryError
from magna_worlds.registry import WorldRegistry

HELP = """\
magna_worlds world node: loads world parts (ROS-MAGNA world JSON), publishes every
volume, geometry, free-space pose and obstacle as a static tf frame under `map`,
their rviz markers on /magna/world/markers (visualization_msgs/MarkerArray, latched),
and spawns the obstacles in magna_sim (/magna/sim/spawn_model) when it is running.

Services (magna_msgs):
  /magna/world/add          AddWorldPart: a world/subworld, or inline volumes (definition_json);
                            both empty (or definition_json "from_hyperparameters") takes
                            world/subworld from /magna/hyperparameters
  /magna/world/get_fspset   GetFreeSpacePoseSet: [volume, geometry, kind, arg] -> map poses
  /magna/world/delete       DeleteWorldPart: removes a part, its frames, markers and obstacles
  /magna/world/reset        ResetWorld: [seed, record] -> the node as if started afresh with ~seed:=seed
                            and ~record:=record ("" = no world.json): no parts (but the ~world_file
                            or ~world start part, loaded again), /magna/world deleted, tf_static
                            latched empty and the markers a lone DELETEALL. Obstacles it spawned are
                            forgotten, not deleted: the simulator's reset (/magna/sim/reset) removes them,
                            so reset the simulator first (a start part's obstacles are spawned again).
                            The next world.json equals a cold start's for the same seed and parts.

Private parameters (defaults):
  ~world_file ("")          a world file loaded at start as part ~part_id
  ~world (""), ~subworld ("")   or a world looked up as <worlds path>/<world>/<subworld>.json
  ~part_id (main)           id of the part loaded at start
  ~seed (/magna/hyperparameters/seed, else 0)   random poses and obstacles repeat per seed
  ~worlds_path ([])         extra folders searched for worlds before MAGNA's worlds/
  ~spawn_obstacles (true)   spawn obstacles in magna_sim if its spawn service appears
  ~sim_wait (2.0)           seconds to wait for that service
  ~record ("")              file the resolved world (every pose and obstacle) is written to

Parameters set: /magna/world/origin_geo [lat, lon, alt] and /magna/world/boundaries
[[xmin, xmax], [ymin, ymax], [zmin, zmax]] of the last part that has them. The node owns
/magna/world: it deletes what an earlier world node left there when it starts (and on a reset).

Example: rosrun magna_worlds world _world:=Gym _subworld:=Four_Cylinders _seed:=1
"""

class WorldNode:
    def __init__(self):
        hyper = Hyperparameters.from_param(rospy.get_param(names.HYPERPARAMETERS, {}))
        seed = int(rospy.get_param("~seed", hyper.seed or 0))
        extra = [Path(p) for p in rospy.get_param("~worlds_path", [])]
        self.registry = WorldRegistry(seed)
        self.registry.search_path = extra + self.registry.search_path
        self.spawn_obstacles = bool(rospy.get_param("~spawn_obstacles", True))
        self.sim_wait = float(rospy.get_param("~sim_wait", 2.0))
        self.start_file = rospy.get_param("~world_file", "")
        self.start_world, self.start_sub = rospy.get_param("~world", ""), rospy.get_param("~subworld", "")
        self.start_part_id = rospy.get_param("~part_id", "main")
        self.record_path = ""
        self.flown: dict[str, dict] = {}  # every part recorded this run, by id
        self.lock = threading.Lock()
        self.spawned: dict[str, list[str]] = {}  # part id -> obstacle models in the simulator
        self.tf_pub = rospy.Publisher("/tf_static", TFMessage, queue_size=1, latch=True)
        self.marker_pub = rospy.Publisher(names.WORLD_MARKERS, MarkerArray, queue_size=1, latch=True)
        with self.lock:
            self._start(seed, rospy.get_param("~record", ""))
        rospy.Service(names.WORLD_ADD, AddWorldPart, self.handle_add)
        rospy.Service(names.WORLD_GET_FSPSET, GetFreeSpacePoseSet, self.handle_get)
        rospy.Service(names.WORLD_DELETE, DeleteWorldPart, self.handle_delete)
        rospy.Service(names.WORLD_RESET, ResetWorld, self.handle_reset)

    def _start(self, seed: int, record_path: str) -> None:
        """The state of a node just started with this seed and record: at start and on every reset (the lock held)."""
        # An earlier run's world (on the same master) must not stand in for this one's: a default
        # box of ours would never replace its boundaries.
        if rospy.has_param(names.WORLD):  # what the node tells others: origin_geo, boundaries
            rospy.delete_param(names.WORLD)
        self.registry.reset(seed)
        self.record_path = record_path
        self.flown = {}
        # The simulator's reset removes the models; a fresh node would not know an earlier node's either.
        self.spawned = {}
        self._publish()  # no frames, and a lone DELETEALL marker
        if self.start_file:
            self.registry.add_file(self.start_part_id, self.start_file)
            self._after_add(self.start_part_id)
        elif self.start_world:
            self.registry.add_named(self.start_part_id, self.start_world, self.start_sub)
            self._after_add(self.start_part_id)

    # --- services ----------------------------------------------------------------------------------------------

    def handle_add(self, req) -> AddWorldPartResponse:
        with self.lock:
            try:
                definition = req.definition_json.strip()
                if req.world:
                    part = self.registry.add_named(req.id, req.world, req.subworld)
                elif definition and definition != "from_hyperparameters":
                    part = self.registry.add_inline(req.id, definition)
                else:
                    hyper = Hyperparameters.from_param(rospy.get_param(names.HYPERPARAMETERS, {}))
                    if not hyper.world or not hyper.subworld:
                        return AddWorldPartResponse(False, f"world: empty, and {names.HYPERPARAMETERS} has no "
                                                    "world/subworld; give world and subworld or definition_json", [])
                    part = self.registry.add_named(req.id, hyper.world, hyper.subworld)
            except WorldError as err:
                return AddWorldPartResponse(False, str(err), [])
            message = self._after_add(req.id)
            return AddWorldPartResponse(True, message, [child for _, child in part.frame_links()])

    def handle_get(self, req) -> GetFreeSpacePoseSetResponse:
        with self.lock:
            try:
                result = self.registry.resolve(list(req.definition))
            except QueryError as err:
                return GetFreeSpacePoseSetResponse(False, str(err), PoseArray(), [])
            if result.new_frames:  # query frames have no markers: only tf changes
                self._publish_frames()
        poses = PoseArray(poses=[Pose(Point(*p), Quaternion(*q))
                                 for p, q in zip(result.positions.tolist(), result.quaternions.tolist(), strict=True)])
        poses.header.frame_id = "map"
        poses.header.stamp = rospy.Time.now()
        return GetFreeSpacePoseSetResponse(True, f"{len(result.frames)} pose(s)", poses, result.frames)

    def handle_delete(self, req) -> DeleteWorldPartResponse:
        with self.lock:
            try:
                self.registry.delete(req.id)
            except KeyError as err:
                return DeleteWorldPartResponse(False, err.args[0])
            removed = self._delete_obstacles(req.id)
            self._publish()
            self._write_record()
        return DeleteWorldPartResponse(True, f"deleted part {req.id!r} and {removed} obstacle(s) from the simulator")

    def handle_reset(self, req) -> ResetWorldResponse:
        with self.lock:
            try:
                self._start(int(req.seed), req.record)
            except WorldError as err:
                return ResetWorldResponse(False, f"reset with seed {req.seed}: the start part failed: {err}")
        where = f"recorded to {req.record}" if req.record else "not recorded"
        return ResetWorldResponse(True, f"reset: seed {req.seed}, {len(self.registry.parts)} part(s), {where}")

    # --- effects -----------------------------------------------------------------------------------------------

    def _after_add(self, part_id: str) -> str:
        part = self.registry.parts[part_id]
        if part.world.origin_geo:  # for nodes that convert to and from WGS84 (go_to_waypoint_geo, real UAVs)
            rospy.set_param(names.WORLD_ORIGIN_GEO, list(part.world.origin_geo))
        # A box MAGNA made up for a file without world_boundaries never replaces one that a file gave.
        if np.isfinite(part.world.boundaries).all() and not (part.world.boundaries_defaulted
                                                             and rospy.has_param(names.WORLD_BOUNDARIES)):
            rospy.set_param(names.WORLD_BOUNDARIES, part.world.boundaries.tolist())
        for warning in part.warnings:
            rospy.logwarn("world part %r: %s", part_id, warning)
        self._publish()
        spawned = self._spawn_obstacles(part_id, part)
        self._write_record()
        rospy.loginfo("world part %r: %d volumes, %d poses, %d obstacles (%s)", part_id, len(part.world.volumes),
                      part.pose_count(), len(part.obstacles()), spawned)
        return (f"added part {part_id!r} from {part.world.source}: {len(part.world.volumes)} volume(s), "
                f"{part.pose_count()} pose(s), {len(part.obstacles())} obstacle(s); {spawned}")

    def _publish(self) -> None:
        """Frames and markers of every part: after a part is added or deleted."""
        self._publish_frames()
        self._publish_markers()

    def _publish_frames(self) -> None:
        stamp = rospy.Time.now()
        transforms = []
        for parent, child, frame in self.registry.static_transforms():
            t = TransformStamped()
            t.header.stamp, t.header.frame_id, t.child_frame_id = stamp, parent, child
            t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = frame.translation
            q = frame.quaternion()
            t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w = q
            transforms.append(t)
        self.tf_pub.publish(TFMessage(transforms=transforms))

    def _publish_markers(self) -> None:
        stamp = rospy.Time.now()
        markers = world_markers(list(self.registry.parts.values()))
        for marker in markers.markers:
            marker.header.stamp = stamp
        self.marker_pub.publish(markers)

    def _spawn_obstacles(self, part_id: str, part: ResolvedWorld) -> str:
        obstacles = part.obstacles()
        if not obstacles:
            return "no obstacles to spawn"
        if not self.spawn_obstacles:
            return "obstacles not spawned (~spawn_obstacles false)"
        try:
            rospy.wait_for_service(names.SIM_SPAWN_MODEL, timeout=self.sim_wait)
        except rospy.ROSException:
            return f"obstacles not spawned: no simulator ({names.SIM_SPAWN_MODEL} absent)"
        spawn = rospy.ServiceProxy(names.SIM_SPAWN_MODEL, SpawnModel)
        done, failures = [], []
        for o in obstacles:
            req = SpawnModelRequest(name=o.name, kind="obstacle", shape=o.shape,
                                    dimensions=list(o.dimensions),  # a prism's is its height only
                                    vertices=[Point(x, y, 0.0) for x, y in o.polygon],
                                    pose=Pose(Point(*o.position.tolist()), Quaternion(*o.quaternion.tolist())),
                                    color=ColorRGBA(*OBSTACLE_COLOR))
            try:
                answer = spawn(req)
            except rospy.ServiceException as err:
                failures.append(f"{o.name}: {err}")
                continue
            if answer.success:
                done.append(o.name)
            else:
                failures.append(f"{o.name}: {answer.message}")
        self.spawned[part_id] = done
        for failure in failures:
            rospy.logerr("spawning obstacle %s", failure)
        return f"{len(done)} obstacle(s) spawned in the simulator" + (f", {len(failures)} failed" if failures else "")

    def _delete_obstacles(self, part_id: str) -> int:
        models = self.spawned.pop(part_id, [])
        if not models:
            return 0
        delete = rospy.ServiceProxy(names.SIM_DELETE_MODEL, DeleteModel)
        removed = 0
        for name in models:
            try:
                removed += bool(delete(name).success)
            except rospy.ServiceException as err:
                rospy.logwarn("deleting obstacle %s: %s", name, err)
        return removed

    def _write_record(self) -> None:
        """The record keeps every part the run had: a deleted part stays, marked, since the record
        says what the simulation flew in (missions delete their world at the end)."""
        if not self.record_path:
            return
        current = self.registry.record()
        for part_id, part in current["parts"].items():
            self.flown[part_id] = dict(part, deleted=False)
        for part_id in self.flown.keys() - current["parts"].keys():
            self.flown[part_id]["deleted"] = True
        record = {"seed": current["seed"], "parts": self.flown}
        WorldRecord.from_dict(record, self.record_path).write(self.record_path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rosrun magna_worlds world", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_known_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node("magna_world")
    try:
        WorldNode()
    except WorldError as err:
        rospy.logfatal(str(err))
        return 2
    rospy.spin()
    return 0

