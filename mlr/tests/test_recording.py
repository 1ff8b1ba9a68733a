"""Recorded missions as mlr reads them: the recorder CSV's goal target columns, the navigation
steps in the bag, and `mlr.bags.steps_from_bag` against `mlr.pickler.steps_from_csv`.

The first tests write small bags by hand (rosbags, no ROS) and check the reading rules exactly;
the others read one real simulation (the `recorded_run` fixture, tests/recorded_run.py).

Each navigation step names, by their stamps, the pose and velocity messages it was computed from,
so the bag rebuilds every step from the very messages the manager used: positions, velocities,
gaps and input vectors equal the CSV's exactly (the others' velocities to 1e-9: the manager turns
their odom's body twist into the map frame, the bag has the map-frame velocity). This holds
however late the manager heard its messages, so it holds under any load. The one thing the bag
cannot time exactly is the latched obstacle markers: they count from when the bag got them, so it
may know fewer obstacles than the manager for a step or two, never more; at steps where both know
the same ones, the obstacle slots are equal too.
Steps before the bag's first pose of a UAV (rosbag subscribes to a new topic within about a wall
second, during the take-off) have NaN positions in the bag: they are allowed before the first
path step only.
"""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from magna_common import ros_names
from magna_common.simulation_bag import read_simulation_bag
from magna_common.storage_tree import BAG_FILE
from magna_uav.recorder import GOAL_TARGET, columns, read_csv
from mlr.bags import steps_from_bag
from mlr.pickler import PicklerError, Teacher, runs, samples, steps_from_csv
from tests.support import ROOT

MSG_DIR = ROOT / "src" / "magna_msgs" / "msg"
TEACHER = Teacher(role="path", algorithm="orca3d", n_neighbors=1, n_obstacles=2)
ROTATION_ROUNDING = 1e-9  # m/s: the others' velocities went from the map frame to the body and back
LEGACY_CUT = "# Which messages"  # where NavigationStep.msg's fields naming the used messages begin
SPEEDS = {1: 2.0, 2: 2.0}


# --- hand-made bags ---------------------------------------------------------------------------------------------


def _store(definition: str):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(definition, "magna_msgs/msg/NavigationStep"))
    return store


@pytest.fixture(scope="module")
def typestore():
    return _store((MSG_DIR / "NavigationStep.msg").read_text())


@pytest.fixture(scope="module")
def legacy_typestore():
    """NavigationStep as bagged before the steps named the messages they used."""
    definition = (MSG_DIR / "NavigationStep.msg").read_text()
    assert LEGACY_CUT in definition
    return _store(definition.split(LEGACY_CUT)[0])


class BagMaker:
    """Messages of a hand-made bag, written with their log times (ns)."""

    def __init__(self, store):
        self.store, self.items = store, []
        t = store.types
        self.Time, self.Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
        self.Point, self.Vector3 = t["geometry_msgs/msg/Point"], t["geometry_msgs/msg/Vector3"]

    def header(self, ns: int):
        return self.Header(seq=0, stamp=self.Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="map")

    def navigation(self, uav, row, role_number, role, algorithm, ns, goal=(5.0, 0.0, 2.0), sel=(1.0, 0.0, 0.0),
                   goal_vel=(math.nan,) * 3, goal_dist=math.nan, log_ns=None, used=(), teacher=(math.nan,) * 3):
        """`used`: (UAV id, pose stamp ns, velocity stamp ns) of the messages the step used (new bags only)."""
        step_type = self.store.types["magna_msgs/msg/NavigationStep"]
        named = {}
        if "uav_ids" in step_type.__dataclass_fields__:
            time = self.store.types["builtin_interfaces/msg/Time"]
            named = dict(uav_ids=np.array([u[0] for u in used], dtype=np.uint32),
                         pose_stamps=[time(sec=u[1] // S, nanosec=u[1] % S) for u in used],
                         velocity_stamps=[time(sec=u[2] // S, nanosec=u[2] % S) for u in used])
        if "teacher_velocity" in step_type.__dataclass_fields__:
            named |= dict(teacher_velocity=self.Vector3(*teacher), fallback=-1 if math.isnan(teacher[0]) else 0)
        msg = step_type(
            header=self.header(ns), row=row, role_number=role_number, role=role, algorithm=algorithm,
            goal=self.Point(*goal), goal_velocity=self.Vector3(*goal_vel), goal_distance=goal_dist,
            selected_velocity=self.Vector3(*sel), feasible=-1, **named)
        self.items.append((ros_names.manager(uav, "navigation"), "magna_msgs/msg/NavigationStep", log_ns or ns, msg))

    def pose(self, uav, ns, xyz, stamped=True):
        t = self.store.types
        pose = t["geometry_msgs/msg/Pose"](position=self.Point(*xyz),
                                           orientation=t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0))
        msg = t["geometry_msgs/msg/PoseStamped"](header=self.header(ns if stamped else 0), pose=pose)
        self.items.append((ros_names.ual(uav, "pose"), "geometry_msgs/msg/PoseStamped", ns, msg))

    def velocity(self, uav, ns, xyz):
        t = self.store.types
        twist = t["geometry_msgs/msg/Twist"](linear=self.Vector3(*xyz), angular=self.Vector3(0.0, 0.0, 0.0))
        msg = t["geometry_msgs/msg/TwistStamped"](header=self.header(ns), twist=twist)
        self.items.append((ros_names.ual(uav, "velocity"), "geometry_msgs/msg/TwistStamped", ns, msg))

    def markers(self, ns, markers):
        msg = self.store.types["visualization_msgs/msg/MarkerArray"](markers=markers)
        self.items.append((ros_names.WORLD_MARKERS, "visualization_msgs/msg/MarkerArray", ns, msg))

    def marker(self, marker_id, kind, action, xyz=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0), text="", ns="obstacles"):
        t = self.store.types
        return t["visualization_msgs/msg/Marker"](
            header=self.header(0), ns=ns, id=marker_id, type=kind, action=action,
            pose=t["geometry_msgs/msg/Pose"](position=self.Point(*xyz),
                                             orientation=t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)),
            scale=self.Vector3(*scale), color=t["std_msgs/msg/ColorRGBA"](0.5, 0.5, 0.5, 1.0),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=False, points=[],
            colors=[], text=text, mesh_resource="", mesh_use_embedded_materials=False)

    def write(self, path: Path) -> Path:
        from rosbags.rosbag1 import Writer

        with Writer(path) as writer:
            connections = {}
            for topic, msgtype, ns, msg in sorted(self.items, key=lambda item: item[2]):
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, msgtype, typestore=self.store)
                writer.write(connections[topic], ns, self.store.serialize_ros1(msg, msgtype))
        return path


def sim_folder(tmp_path: Path) -> Path:
    agents = [{"ID": i, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 1.0]} for i in (1, 2)]
    (tmp_path / "mission.json").write_text(json.dumps({"Agents_Config": agents, "State_Machine": []}))
    return tmp_path


S = 10**9  # ns per s


def test_a_hand_made_bag_gives_one_step_per_row_with_the_newest_poses_and_the_ranked_obstacles(tmp_path,
                                                                                             legacy_typestore):
    bag = BagMaker(legacy_typestore)  # steps that do not name their messages: the newest before the step
    M = legacy_typestore.types["visualization_msgs/msg/Marker"]
    # two obstacles (bounding radii: sphere 1.0, cube sqrt(3)/2 * 2), then the sphere is deleted at 1.5 s
    bag.markers(S // 10, [bag.marker(0, M.CUBE, M.DELETEALL, ns=""),
                          bag.marker(0, M.SPHERE, M.ADD, (0.0, 10.0, 2.0), (2.0, 2.0, 2.0), "ball"),
                          bag.marker(1, M.CUBE, M.ADD, (4.0, 0.0, 2.0), (2.0, 2.0, 2.0), "box"),
                          bag.marker(0, M.CUBE, M.ADD, (9.0, 9.0, 9.0), ns="geometries")])
    bag.markers(3 * S // 2, [bag.marker(0, M.SPHERE, M.DELETE)])
    for k in range(25):  # UAV 1 flies +x at 1 m/s, poses at 20 Hz, stamped
        ns = k * S // 20
        bag.pose(1, ns, (k / 20, 0.0, 2.0))
        bag.velocity(1, ns, (1.0, 0.0, 0.0))
    bag.pose(2, S, (0.0, 3.0, 2.0), stamped=False)  # unstamped: counts from when the bag got it
    bag.velocity(2, S, (0.0, -1.0, 0.0))
    steps = [(0, 1, "take_off", "ual", 0.5), (1, 1, "take_off", "ual", 0.6), (2, 2, "path", "orca3d", 1.0),
             (3, 2, "path", "orca3d", 1.1), (4, 3, "path", "orca3d", 1.1), (5, 3, "path", "orca3d", 1.6)]
    for row, number, role, algorithm, t in steps:
        bag.navigation(1, row, number, role, algorithm, round(t * S), sel=(row, 0.0, 0.0))
    bag.navigation(1, 3, 2, "path", "orca3d", round(1.1 * S), sel=(3.0, 0.0, 0.0), log_ns=2 * S)  # a replay
    bag.navigation(2, 0, 1, "agent_ad", "neural_network", S, goal_vel=(0.5, 0.0, 0.0), goal_dist=2.0,
                   teacher=(0.25, -0.5, 0.0))
    folder = sim_folder(tmp_path)
    bag.write(folder / "simulation.bag")

    one, two = steps_from_bag(folder, {2: 1.5, 1: 2.0})
    assert (one.uav_id, one.max_speed, one.source) == (1, 2.0, folder / "simulation.bag")
    assert len(one) == 6  # the replayed row 3 once; rows 3 and 4 share a stamp and stay two steps
    assert one.time.tolist() == [0.5, 0.6, 1.0, 1.1, 1.1, 1.6]
    assert one.role.tolist()[:2] == ["take_off"] * 2 and set(one.algorithm[2:]) == {"orca3d"}
    assert one.sel_vel[:, 0].tolist() == [0, 1, 2, 3, 4, 5]
    # the last step of each role_number: back-to-back path roles stay apart
    assert one.role_end.tolist() == [False, True, False, True, False, True]
    assert [r for r in runs(one, "path", "orca3d")] == [(2, 4), (4, 6)]
    # the newest pose stamped at or before the step (20 Hz: 0.5 s -> pose 10, 1.1 s -> pose 22)
    assert one.position[:, 0].tolist() == pytest.approx([0.5, 0.6, 1.0, 1.1, 1.1, 1.2])
    assert np.all(one.velocity == [1.0, 0.0, 0.0])
    assert np.all(np.isnan(one.goal_vel)) and np.all(np.isnan(one.goal_dist))
    position_2, velocity_2, gap_2 = one.others[2]
    assert np.all(np.isnan(position_2[:2])) and np.all(np.isnan(gap_2[:2]))  # UAV 2 not heard of before 1 s
    assert position_2[2].tolist() == [0.0, 3.0, 2.0] and velocity_2[2].tolist() == [0.0, -1.0, 0.0]
    assert gap_2[2] == pytest.approx(math.hypot(1.0, 3.0) - 0.6)  # centre distance - both iris safety radii
    # obstacles, nearest first by the gap to their real shape; the geometries' markers do not count
    box_half = 1.0  # the 2 m cube's face is 1 m from its centre
    assert one.obstacle_pos.shape == (6, 5, 3) and one.obstacle_gap.shape == (6, 5)
    assert one.obstacle_pos[0, 0].tolist() == [4.0, 0.0, 2.0] and one.obstacle_pos[0, 1].tolist() == [0.0, 10.0, 2.0]
    assert one.obstacle_gap[0, :2] == pytest.approx([3.5 - box_half - 0.3, math.hypot(0.5, 10) - 1.0 - 0.3])
    assert np.all(np.isnan(one.obstacle_gap[0, 2:])) and np.all(np.isnan(one.obstacle_pos[0, 2:]))
    assert np.all(np.isnan(one.obstacle_gap[5, 1:]))  # the ball was deleted at 1.5 s
    # UAV 2: its follower step keeps the goal's target; its own position came unstamped at 1 s
    assert len(two) == 1 and two.max_speed == 1.5 and two.role_end.tolist() == [True]
    assert two.goal_vel[0].tolist() == [0.5, 0.0, 0.0] and two.goal_dist.tolist() == [2.0]
    # a network's step carries the teacher's answer (DAgger's label); ORCA-3D's own steps have none
    assert two.teacher_vel.tolist() == [[0.25, -0.5, 0.0]] and np.all(np.isnan(one.teacher_vel))
    assert two.position[0].tolist() == [0.0, 3.0, 2.0]


def test_steps_that_name_their_messages_get_those_very_messages(tmp_path, typestore):
    bag = BagMaker(typestore)
    for k in range(25):  # UAVs 1 and 2 fly +x at 1 m/s, poses and velocities at 20 Hz
        ns = k * S // 20
        for uav, y in ((1, 0.0), (2, 3.0)):
            bag.pose(uav, ns, (k / 20, y, 2.0))
            bag.velocity(uav, ns, (float(k), 0.0, 0.0))  # the velocity tells which message it is
    P = S // 20  # one period
    # step 0: UAV 1 alone in the view, with no velocity yet; step 1: a pose two periods old (a stalled
    # subscriber), UAV 2's odom of 3 periods before; step 2: a stamp between two messages (an odom the bag
    # does not have takes the pose and velocity stamped before it)
    bag.navigation(1, 0, 1, "path", "orca3d", 10 * P, used=[(1, 10 * P, 0)])
    bag.navigation(1, 1, 1, "path", "orca3d", 12 * P, used=[(1, 10 * P, 11 * P), (2, 9 * P, 9 * P)])
    bag.navigation(1, 2, 1, "path", "orca3d", 14 * P, used=[(1, 14 * P, 14 * P), (2, 13 * P + 1, 13 * P + 1)])
    bag.navigation(2, 0, 1, "path", "orca3d", 14 * P, used=[])  # not even its own pose yet
    folder = sim_folder(tmp_path)
    bag.write(folder / "simulation.bag")

    one, two = steps_from_bag(folder, SPEEDS)
    assert one.position[:, 0].tolist() == [0.5, 0.5, 0.7]
    assert one.velocity.tolist() == [[0.0, 0.0, 0.0], [11.0, 0.0, 0.0], [14.0, 0.0, 0.0]]
    position_2, velocity_2, gap_2 = one.others[2]
    assert np.isnan(position_2[0]).all() and np.isnan(velocity_2[0]).all() and np.isnan(gap_2[0])
    assert position_2[1:].tolist() == [[0.45, 3.0, 2.0], [0.65, 3.0, 2.0]]
    assert velocity_2[1:, 0].tolist() == [9.0, 13.0]
    assert gap_2[1] == pytest.approx(math.hypot(0.05, 3.0) - 0.6)
    assert np.isnan(two.position).all() and np.isnan(two.velocity).all() and np.isnan(two.others[1][0]).all()


def test_a_missing_bag_or_one_without_navigation_steps_is_refused_naming_the_fix(tmp_path, typestore):
    folder = sim_folder(tmp_path)
    with pytest.raises(PicklerError, match=r"simulation.bag: no such bag .*source csv"):
        steps_from_bag(folder, SPEEDS)
    bag = BagMaker(typestore)
    bag.pose(1, S, (0.0, 0.0, 1.0))
    bag.write(folder / "simulation.bag")
    with pytest.raises(PicklerError, match=r"simulation.bag: no /magna/uav_<id>/navigation messages: recorded "
                                           r"before navigation steps were bagged: use the CSVs \(source csv\)"):
        steps_from_bag(folder, SPEEDS)
    (folder / "simulation.bag").write_bytes(b"not a bag")
    with pytest.raises(PicklerError, match="simulation.bag: cannot read the bag"):
        steps_from_bag(folder, SPEEDS)


def test_a_uav_missing_from_the_mission_is_refused(tmp_path, typestore):
    bag = BagMaker(typestore)
    bag.navigation(3, 0, 1, "path", "orca3d", S)
    folder = sim_folder(tmp_path)
    bag.write(folder / "simulation.bag")
    with pytest.raises(PicklerError, match="UAV 3 flew but is not in the simulation's mission.json"):
        steps_from_bag(folder, SPEEDS)
    with pytest.raises(PicklerError, match="mission.json: UAV 4 is not in Agents_Config"):
        steps_from_bag(folder, {1: 2.0, 4: 2.0})


# --- one real simulation --------------------------------------------------------------------------------------


def csv_rows(run, uav: int) -> tuple[list[str], list[dict]]:
    return read_csv(run.sim_dir / f"uav_{uav}.csv")


def bag_navigation(run) -> dict[int, list]:
    steps = read_simulation_bag(run.sim_dir / BAG_FILE, ("navigation",)).by_owner("navigation")
    return {uav: [step.msg for step in steps[uav]] for uav in run.uav_ids if uav in steps}


def test_the_csvs_carry_the_goal_target_columns(recorded_run):
    for uav in recorded_run.uav_ids:
        header, rows = csv_rows(recorded_run, uav)
        assert header == columns([j for j in recorded_run.uav_ids if j != uav])
        assert header[header.index("goal.z") + 1:header.index("sel_vel.x")] == list(GOAL_TARGET)
        # this mission has no follower role: no step has a target to follow
        assert {row["role"] for row in rows} == {"take_off", "path", "land"}
        assert all(math.isnan(row[c]) for row in rows for c in GOAL_TARGET)
        path = [row for row in rows if row["algorithm"] == "orca3d"]
        assert len(path) > 50 and all(math.isfinite(row["goal.x"]) and math.isfinite(row["sel_vel.x"]) for row in path)


def test_the_bag_holds_one_navigation_step_per_recorded_row_with_its_values(recorded_run):
    navigation = bag_navigation(recorded_run)
    for uav in recorded_run.uav_ids:
        _, rows = csv_rows(recorded_run, uav)
        by_row = {msg.row: msg for msg in navigation[uav]}  # a step replayed to the late rosbag comes twice
        assert sorted(by_row) == list(range(len(rows)))
        flown = [msg for msg in by_row.values() if msg.algorithm != "ual"]
        assert len(flown) == sum(row["algorithm"] != "ual" for row in rows) > 50
        for index, row in enumerate(rows):
            msg = by_row[index]
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            assert stamp == pytest.approx(row["time"], abs=1e-9) and msg.header.frame_id == "map"
            assert (msg.role, msg.algorithm) == (row["role"], row["algorithm"])
            got = [msg.goal.x, msg.goal.y, msg.goal.z, msg.goal_velocity.x, msg.goal_velocity.y, msg.goal_velocity.z,
                   msg.goal_distance, msg.selected_velocity.x, msg.selected_velocity.y, msg.selected_velocity.z]
            want = [row[c] for c in ("goal.x", "goal.y", "goal.z", *GOAL_TARGET, "sel_vel.x", "sel_vel.y",
                                     "sel_vel.z")]
            assert np.array_equal(got, want, equal_nan=True), index
            assert msg.feasible == (-1 if row["feasible"] is None else row["feasible"])
        # a role's steps share a role_number; its last one is where the CSV wrote the outcome
        numbers = [by_row[i].role_number for i in range(len(rows))]
        ends = [i for i in range(len(rows)) if i == len(rows) - 1 or numbers[i + 1] != numbers[i]]
        assert ends == [i for i, row in enumerate(rows) if row["outcome"]]


def same_obstacles_known(bag, csv) -> np.ndarray:
    """Steps where the bag knows the obstacles the manager knew (the latched markers may reach the bag later)."""
    return np.all(np.isnan(bag.obstacle_gap) == np.isnan(csv.obstacle_gap), axis=1)


def test_steps_from_the_bag_match_steps_from_the_csvs(recorded_run):
    from_bag = steps_from_bag(recorded_run.sim_dir, SPEEDS)
    assert [s.uav_id for s in from_bag] == list(recorded_run.uav_ids)
    for bag in from_bag:
        csv = steps_from_csv(recorded_run.sim_dir / f"uav_{bag.uav_id}.csv", SPEEDS[bag.uav_id])
        assert len(bag) == len(csv)
        assert bag.role.tolist() == csv.role.tolist() and bag.algorithm.tolist() == csv.algorithm.tolist()
        assert bag.role_end.tolist() == csv.role_end.tolist()
        assert runs(bag, "path", "orca3d") == runs(csv, "path", "orca3d")
        assert np.abs(bag.time - csv.time).max() < 1e-6
        for name in ("goal", "goal_vel", "goal_dist", "sel_vel"):  # the same numbers, sent and written
            assert np.array_equal(getattr(bag, name), getattr(csv, name), equal_nan=True), name
        first_path = int(np.flatnonzero(csv.role == "path")[0])
        posed = ~np.isnan(bag.position).any(axis=1)
        assert posed[first_path:].all() and not np.isnan(csv.position).any()

        # The very messages the manager used: its own pose and velocity, and the others', exactly.
        assert np.array_equal(bag.position[posed], csv.position[posed])
        assert np.array_equal(bag.velocity[posed], csv.velocity[posed])
        for j, (position, velocity, gap) in bag.others.items():
            heard = ~np.isnan(position).any(axis=1)
            assert heard[first_path:].all()
            assert np.array_equal(position[heard], csv.others[j][0][heard]), f"UAV {j}'s position"
            assert np.allclose(velocity[heard], csv.others[j][1][heard], rtol=0, atol=ROTATION_ROUNDING)
            assert np.allclose(gap[heard & posed], csv.others[j][2][heard & posed], rtol=0, atol=1e-9)

        # Known obstacles: the bag may only lag (it counts the latched markers from when it got them, the
        # manager may have had them a step before), never know one the manager lacked; by the end both know
        # them all. Where both know the same ones, the same obstacles fill the same slots with the same gaps.
        unknown_bag, unknown_csv = (np.isnan(g[posed]).sum(axis=1) for g in (bag.obstacle_gap, csv.obstacle_gap))
        assert (unknown_bag >= unknown_csv).all()
        assert unknown_bag[-1] == unknown_csv[-1]
        same = same_obstacles_known(bag, csv) & posed
        assert same[first_path:].any()
        assert np.array_equal(bag.obstacle_pos[same], csv.obstacle_pos[same], equal_nan=True)
        assert np.allclose(bag.obstacle_gap[same], csv.obstacle_gap[same], rtol=0, atol=1e-9, equal_nan=True)
        print(f"UAV {bag.uav_id}: {(unknown_bag > unknown_csv).sum()} of {posed.sum()} steps where the bag knew "
              f"fewer obstacles than the manager")


def test_the_input_vectors_from_bag_and_csv_agree(recorded_run):
    for bag in steps_from_bag(recorded_run.sim_dir, SPEEDS):
        csv = steps_from_csv(recorded_run.sim_dir / f"uav_{bag.uav_id}.csv", SPEEDS[bag.uav_id])
        from_bag, from_csv = samples(bag, TEACHER), samples(csv, TEACHER)
        assert len(from_bag) == len(from_csv) > 50
        assert np.array_equal(from_bag.step, from_csv.step)
        assert np.array_equal(from_bag.y, from_csv.y)  # the labels are the chosen velocities themselves
        # from the same messages, the same input vectors (a step out of order, or a velocity in another
        # frame, would differ here), wherever the bag knew the obstacles the manager knew
        same = same_obstacles_known(bag, csv)[from_bag.step]
        assert same.mean() > 0.5
        assert np.allclose(from_bag.x[same], from_csv.x[same], rtol=0, atol=ROTATION_ROUNDING)


def test_a_copy_without_its_bag_is_refused_and_the_csvs_still_read(recorded_run, tmp_path):
    copy = tmp_path / "simulation_1"
    shutil.copytree(recorded_run.sim_dir, copy, ignore=shutil.ignore_patterns("simulation.bag", "logs"))
    with pytest.raises(PicklerError, match="no such bag"):
        steps_from_bag(copy, SPEEDS)
    assert len(steps_from_csv(copy / "uav_1.csv", 2.0)) > 0
