"""magna_viz.recording, timeline, recorded_world and latency: a simulation folder -> typed data.

Unit tests write tiny simulation folders (a bag written with rosbags' writer, hand-made CSVs, the
project's own world record); the last tests read the session's real recorded simulation
(root conftest.py `recorded_run`: missions/Gym/2UAVs_Crossing_ORCA flown through `magna run`).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from magna_sm.container import ContainerStructure
from magna_viz.latency import command_latencies, latency_samples
from magna_viz.recorded_world import RECORD_COLOR, world_from_record
from magna_viz.recording import Recording, RecordingError, Samples, UavRecord, load_recording
from magna_viz.timeline import StatusEvent, Timeline, build_timeline
from magna_worlds.registry import WorldRegistry

ROOT = Path(__file__).resolve().parents[3]
MSG_DIR = ROOT / "src" / "magna_msgs" / "msg"
WORLD_FILE = ROOT / "worlds" / "Gym" / "Central_Obstacle_Torus.json"
RED, BLUE = [255, 0, 0, 0.5], [0, 0, 255, 1.0]
DT = 0.1  # s between the synthetic pose and velocity samples


# --- a tiny simulation folder --------------------------------------------------------------------------------------

class BagWriter:
    """Writes ROS 1 messages into a bag with rosbags, magna_msgs' types taken from the package's .msg files."""

    def __init__(self, path: Path):
        from rosbags.rosbag1 import Writer
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self.store = get_typestore(Stores.ROS1_NOETIC)
        types = {}
        for name in ("SMStatus", "SMStructure"):
            types.update(get_types_from_msg((MSG_DIR / f"{name}.msg").read_text(), f"magna_msgs/msg/{name}"))
        self.store.register(types)
        self.t = self.store.types
        self.writer = Writer(path)
        self.writer.open()
        self.connections = {}

    def close(self):
        self.writer.close()

    def write(self, topic: str, msg, t: float):
        msgtype = msg.__msgtype__
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        self.writer.write(self.connections[topic], int(round(t * 1e9)), self.store.serialize_ros1(msg, msgtype))

    def header(self, t: float):
        sec = int(math.floor(t))
        return self.t["std_msgs/msg/Header"](seq=0, stamp=self.t["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=int(round((t - sec) * 1e9))), frame_id="map")

    def point(self, xyz):
        return self.t["geometry_msgs/msg/Point"](x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))

    def pose(self, xyz):
        return self.t["geometry_msgs/msg/Pose"](position=self.point(xyz), orientation=self.t[
            "geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))

    def pose_stamped(self, t, xyz):
        return self.t["geometry_msgs/msg/PoseStamped"](header=self.header(t), pose=self.pose(xyz))

    def twist(self, t, v):
        vector = self.t["geometry_msgs/msg/Vector3"]
        return self.t["geometry_msgs/msg/TwistStamped"](header=self.header(t), twist=self.t["geometry_msgs/msg/Twist"](
            linear=vector(x=float(v[0]), y=float(v[1]), z=float(v[2])), angular=vector(x=0.0, y=0.0, z=0.0)))

    def path(self, t, points):
        return self.t["nav_msgs/msg/Path"](header=self.header(t), poses=[self.pose_stamped(t, p) for p in points])

    def status(self, t, path, active, last="", info="running"):
        return self.t["magna_msgs/msg/SMStatus"](header=self.header(t), path=path, active_states=list(active),
                                                  initial_states=[], last_outcome=last, preempt_requested=False,
                                                  info=info)

    def structure(self, t, path, kind, children, child_types, transitions=()):
        return self.t["magna_msgs/msg/SMStructure"](
            header=self.header(t), path=path, container_type=kind, children=list(children),
            child_types=list(child_types), container_outcomes=["completed", "failed"],
            transitions_from=[a for a, _, _ in transitions], transitions_outcome=[o for _, o, _ in transitions],
            transitions_to=[b for _, _, b in transitions])

    def markers(self, t, items):
        """items: (action, ns, id, type, position, scale)."""
        marker = self.t["visualization_msgs/msg/Marker"]
        out = []
        for action, ns, ident, kind, xyz, scale in items:
            out.append(marker(
                header=self.header(t), ns=ns, id=ident, type=kind, action=action, pose=self.pose(xyz),
                scale=self.t["geometry_msgs/msg/Vector3"](x=scale, y=scale, z=scale),
                color=self.t["std_msgs/msg/ColorRGBA"](r=0.2, g=0.2, b=0.2, a=1.0),
                lifetime=self.t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=False,
                points=[], colors=[], text=f"obs_{ident}", mesh_resource="", mesh_use_embedded_materials=False))
        return self.t["visualization_msgs/msg/MarkerArray"](markers=out)


def speed_profile(uav: int, t: float) -> tuple[float, float, float]:
    """UAV 1 rests, climbs from 1.1 s, hovers from 3.0 s, flies along x from 3.5 s; UAV 2 climbs 1.3-3.0 s."""
    if uav == 1:
        if 1.1 - 1e-9 <= t < 3.0 - 1e-9:
            return (0.0, 0.0, 0.5)
        if t >= 3.5 - 1e-9:
            return (1.0, 0.0, 0.0)
        return (0.0, 0.0, 0.0)
    return (0.0, 0.0, 0.4) if 1.3 - 1e-9 <= t < 3.0 - 1e-9 else (0.0, 0.0, 0.0)


def position(uav: int, t: float) -> np.ndarray:
    """Where each UAV is: UAV 1 at x = 0 until 3.5 s; UAV 2 stays 2 m away in x, then 0.4 m from 5.5 s."""
    if uav == 1:
        return np.array([max(0.0, t - 3.5), 0.0, 1.0])
    x = 0.4 if t >= 5.5 - 1e-9 else 2.0
    return np.array([max(0.0, t - 3.5) + x, 0.0, 1.0])


MISSION_STRUCTURE = [
    ("/MISSION", "StateMachine", ["spawn", "1_take_off", "1_go", "1_safety"],
     ["CallbackState", "Concurrence", "Concurrence", "Concurrence"],
     [("spawn", "completed", "1_take_off"), ("1_take_off", "completed", "1_go"), ("1_take_off", "failed", "1_safety"),
      ("1_go", "completed", "completed")]),
    ("/MISSION/1_take_off", "Concurrence", ["1_take_off", "2_take_off"], ["MissionActionState"] * 2,
     [("1_take_off", "succeeded", "completed")]),
    ("/MISSION/1_go", "Concurrence", ["1_go"], ["MissionActionState"], []),
    ("/MISSION/1_safety", "Concurrence", ["1_hover", "2_hover"], ["MissionActionState"] * 2, []),
]

# (time, container, active, last_outcome, info): spawn began before the bag, 1_go is still active at its end
MISSION_STATUS = [
    (0.5, "/MISSION", ["spawn"], "", "heartbeat"),
    (0.5, "/MISSION/1_take_off", [], "", "heartbeat"),
    (1.0, "/MISSION", ["1_take_off"], "completed", "running"),
    (1.0, "/MISSION/1_take_off", ["1_take_off", "2_take_off"], "", "running"),
    (3.0, "/MISSION/1_take_off", ["2_take_off"], "succeeded", "running"),
    (3.2, "/MISSION/1_take_off", [], "succeeded", "running"),
    (3.2, "/MISSION/1_take_off", [], "completed", "finished:completed"),
    (3.2, "/MISSION", ["1_go"], "completed", "running"),
    (3.2, "/MISSION/1_go", ["1_go"], "", "running"),
]
BAG_END = 6.0


def write_bag(path: Path) -> None:
    bag = BagWriter(path)
    try:
        for container, kind, children, types, transitions in MISSION_STRUCTURE:
            bag.write("/magna/sm/mission/structure", bag.structure(0.5, container, kind, children, types,
                                                                   transitions), 0.5)
        bag.write("/magna/world/markers", bag.markers(0.5, [(0, "obstacles", 0, 2, (0.0, 5.0, 1.0), 1.0),
                                                            (0, "geometries", 9, 1, (9.0, 9.0, 9.0), 1.0)]), 0.5)
        statuses = iter(MISSION_STATUS)
        pending = next(statuses)
        for k in range(6, int(round(BAG_END / DT)) + 1):
            t = k * DT
            while pending is not None and pending[0] <= t + 1e-9:
                bag.write("/magna/sm/mission/status", bag.status(*pending), pending[0])
                pending = next(statuses, None)
            for uav in (1, 2):
                bag.write(f"/uav_{uav}/ual/pose", bag.pose_stamped(t, position(uav, t)), t)
                bag.write(f"/uav_{uav}/ual/velocity", bag.twist(t, speed_profile(uav, t)), t)
            if abs(t - 3.3) < 1e-9:
                route = [(0.0, 0.0, 1.0), (2.0, 1.0, 1.0), (4.0, 0.0, 1.0)]
                bag.write("/magna/uav_1/path/raw", bag.path(t, route), t)
                bag.write("/magna/uav_1/path/smoothed", bag.path(t, route[::2]), t)
            if 3.2 <= t <= 4.0:  # the managers publish the current goal at every step
                goal = (4.0, 0.0, 1.0) if t >= 3.6 else (2.0, 1.0, 1.0)
                bag.write("/magna/uav_1/goal", bag.pose_stamped(t, goal), t)
            if abs(t - 5.0) < 1e-9:  # the mission deletes its world
                bag.write("/magna/world/markers", bag.markers(t, [(3, "", 0, 0, (0.0, 0.0, 0.0), 1.0)]), t)
    finally:
        bag.close()


def write_csv(path: Path, uav: int, rows: list[dict]) -> None:
    other = 2 if uav == 1 else 1
    columns = ["time", "uav_id", "role", "pos.x", "pos.y", "pos.z", "vel.x", "vel.y", "vel.z", "nearest_uav_gap",
               "nearest_obstacle_gap", f"uav{other}.gap", "collision", "collided_with"]
    lines = [",".join(columns)]
    for row in rows:
        lines.append(",".join(str(row.get(c, "")) for c in columns))
    path.write_text("\n".join(lines) + "\n")


def csv_rows(uav: int) -> list[dict]:
    """10 Hz rows from 1.0 s to 4.0 s; a UAV contact at 2.0 s (gap -0.1) by the evaluator's verdict."""
    rows = []
    for k in range(10, 41):
        t = k * DT
        p, v = position(uav, t), speed_profile(uav, t)
        gap = -0.1 if k == 20 else 1.4
        rows.append({"time": f"{t:.3f}", "uav_id": uav, "role": "take_off", "pos.x": p[0], "pos.y": p[1],
                     "pos.z": p[2], "vel.x": v[0], "vel.y": v[1], "vel.z": v[2], "nearest_uav_gap": gap,
                     "nearest_obstacle_gap": "nan" if k < 12 else 3.9, f"uav{2 if uav == 1 else 1}.gap": gap,
                     "collision": int(k == 20), "collided_with": f"uav_{2 if uav == 1 else 1}" if k == 20 else ""})
    return rows


def make_simulation(folder: Path, bag: bool = True, csv: bool = True, mission: bool = True) -> Path:
    folder.mkdir(parents=True)
    if bag:
        write_bag(folder / "simulation.bag")
    if csv:
        for uav in (1, 2):
            write_csv(folder / f"uav_{uav}.csv", uav, csv_rows(uav))
    if mission:
        agents = [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": RED},
                  {"ID": 2, "model": "iris", "mode": "sitl", "marker_color": BLUE}]
        (folder / "mission.json").write_text(json.dumps({"Agents_Config": agents, "State_Machine": []}))
    registry = WorldRegistry(seed=3)
    registry.add_file("main", WORLD_FILE)
    (folder / "world.json").write_text(json.dumps(registry.record()))
    (folder / "result.json").write_text(json.dumps({
        "success": True, "outcome": "completed", "message": "mission ended completed", "sim_duration": 5.5,
        "collisions": 1, "hyperparameters": {"world": "Gym", "subworld": "Central_Obstacle_Torus",
                                             "mission": "Test", "submission": "Tiny", "n_simulation": 4}}))
    return folder


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Recording:
    return load_recording(make_simulation(tmp_path_factory.mktemp("tiny") / "simulation_4"))


# --- the whole folder ----------------------------------------------------------------------------------------------

def test_uavs_get_their_mission_colours_airframe_radii_and_the_bags_samples(tiny):
    assert sorted(tiny.uavs) == [1, 2]
    one, two = tiny.uavs[1], tiny.uavs[2]
    assert one.color == (1.0, 0.0, 0.0, 0.5) and two.color == (0.0, 0.0, 1.0, 1.0)
    assert one.model == "iris" and one.safety_radius == pytest.approx(0.3) and one.max_speed == pytest.approx(2.0)
    assert one.position.source == "simulation.bag"  # the bag's 30 Hz stream wins over the CSV's rows
    assert len(one.position) == len(one.velocity) == 55  # 0.6 .. 6.0 s every 0.1 s
    assert np.allclose(one.position.at([4.0])[0], position(1, 4.0))
    assert tiny.start == pytest.approx(0.5) and tiny.end == pytest.approx(BAG_END)
    assert tiny.result.success is True and tiny.result.collisions == 1 and tiny.result.sim_duration == 5.5
    assert tiny.title == "Test/Tiny in Gym/Central_Obstacle_Torus, simulation 4"
    assert tiny.notes == []


def test_paths_and_distinct_goals_come_from_the_bag(tiny):
    one = tiny.uavs[1]
    assert [p.time for p in one.raw_paths] == [pytest.approx(3.3)]
    assert one.raw_paths[0].points.tolist() == [[0.0, 0.0, 1.0], [2.0, 1.0, 1.0], [4.0, 0.0, 1.0]]
    assert one.smoothed_paths[0].points.shape == (2, 3)
    # a goal per step in the bag, two distinct goals
    assert one.goals.xyz.tolist() == [[2.0, 1.0, 1.0], [4.0, 0.0, 1.0]]
    assert one.goals.time == pytest.approx([3.2, 3.6])
    assert tiny.uavs[2].raw_paths == [] and len(tiny.uavs[2].goals) == 0


def test_distances_from_the_bag_use_both_safety_radii_and_the_obstacle_markers(tiny):
    p = tiny.uavs[1].proximity
    assert p.source == "simulation.bag"
    t = p.time
    expected_uav = np.array([np.linalg.norm(position(2, s) - position(1, s)) for s in t])
    assert p.uav_distance == pytest.approx(expected_uav)
    assert p.uav_threshold == pytest.approx(np.full(len(t), 0.6))
    # the obstacle marker: a sphere of scale 1 at (0, 5, 1) -> bounding radius 0.5; deleted at 5.0 s
    alive = t < 5.0 - 1e-9
    expected_obstacle = np.array([np.linalg.norm(position(1, s) - [0.0, 5.0, 1.0]) - 0.5 for s in t[alive]])
    assert p.obstacle_distance[alive] == pytest.approx(expected_obstacle)
    assert np.isnan(p.obstacle_distance[~alive]).all()
    assert p.obstacle_threshold == pytest.approx(0.3)
    # UAV 2 comes within 0.4 m (< 0.6) from 5.5 s to the end: one contact episode, none with obstacles
    assert p.contact_episodes("uav") == [(pytest.approx(5.5), pytest.approx(BAG_END))]
    assert p.contact_episodes("obstacle") == []


def test_the_timeline_has_intervals_outcomes_branches_and_uavs(tiny):
    timeline = tiny.timeline
    got = {i.path: (round(i.start, 3), round(i.end, 3), i.outcome, i.next_state, i.uav_id)
           for i in timeline.intervals}
    assert got == {
        "/MISSION/spawn": (0.5, 1.0, "completed", "1_take_off", None),
        "/MISSION/1_take_off": (1.0, 3.2, "completed", "1_go", None),
        "/MISSION/1_take_off/1_take_off": (1.0, 3.0, "succeeded", None, 1),
        "/MISSION/1_take_off/2_take_off": (1.0, 3.2, "succeeded", None, 2),
        "/MISSION/1_go": (3.2, BAG_END, None, None, None),
        "/MISSION/1_go/1_go": (3.2, BAG_END, None, None, 1),
    }
    assert timeline.intervals_of("/MISSION/spawn")[0].started_before
    assert all(i.unfinished == i.path.startswith("/MISSION/1_go") for i in timeline.intervals)
    assert [s.path for s in timeline.states][:4] == ["/MISSION/spawn", "/MISSION/1_take_off",
                                                    "/MISSION/1_take_off/1_take_off", "/MISSION/1_take_off/2_take_off"]
    assert not timeline.ran("/MISSION/1_safety/1_hover")  # the branch not taken is still a row
    assert timeline.state("/MISSION/1_safety").is_container and timeline.state("/MISSION/1_safety/2_hover").uav_id == 2
    assert timeline.outcome is None  # the mission had not finished when the bag ended


def test_latency_of_the_commands_from_rest(tiny):
    got = [(c.state, c.uav_id, round(c.command_time, 3), round(c.latency, 3)) for c in command_latencies(tiny)]
    assert got == [("/MISSION/1_take_off/1_take_off", 1, 1.0, 0.1),  # moves at 1.1 s
                   ("/MISSION/1_take_off/2_take_off", 2, 1.0, 0.3),  # moves at 1.3 s
                   ("/MISSION/1_go/1_go", 1, 3.2, 0.3)]  # hovering at 3.2 s, moves at 3.5 s
    assert latency_samples(command_latencies(tiny)) == {"UAV 1": [pytest.approx(100.0), pytest.approx(300.0)],
                                                        "UAV 2": [pytest.approx(300.0)]}


def test_without_the_bag_the_csvs_give_tracks_and_the_evaluators_distances(tmp_path):
    recording = load_recording(make_simulation(tmp_path / "sim", bag=False))
    assert recording.bag is None and recording.timeline is None
    assert any("simulation.bag missing" in n for n in recording.notes)
    one = recording.uavs[1]
    assert one.position.source == "uav_1.csv" and len(one.position) == 31
    assert one.raw_paths == [] and len(one.goals) == 0
    p = one.proximity
    assert p.source == "uav_1.csv"
    assert p.uav_distance[0] == pytest.approx(1.4 + 0.6) and p.uav_threshold[0] == pytest.approx(0.6)
    assert np.isnan(p.obstacle_distance[0]) and p.obstacle_distance[-1] == pytest.approx(3.9 + 0.3)
    assert p.contact_episodes("uav") == [(pytest.approx(2.0), pytest.approx(2.0))]
    assert p.contact_episodes("obstacle") == []
    assert command_latencies(recording) == []


def test_without_csvs_or_mission_the_bag_is_enough_and_the_notes_say_what_is_missing(tmp_path):
    recording = load_recording(make_simulation(tmp_path / "sim", csv=False, mission=False))
    assert recording.csvs == {} and sorted(recording.uavs) == [1, 2]
    assert any("no uav_<id>.csv" in n for n in recording.notes)
    assert any("mission.json missing" in n for n in recording.notes)
    one = recording.uavs[1]
    assert math.isnan(one.safety_radius) and math.isnan(one.max_speed)
    assert one.color != recording.uavs[2].color  # made-up colours still tell the UAVs apart
    assert len(recording.timeline.intervals) == 6


def test_nothing_to_plot_is_a_recording_error_naming_the_folder_and_the_fix(tmp_path):
    with pytest.raises(RecordingError, match="no such simulation folder"):
        load_recording(tmp_path / "absent")
    empty = make_simulation(tmp_path / "empty", bag=False, csv=False)
    with pytest.raises(RecordingError, match=r"neither simulation\.bag nor any uav_<id>\.csv.*--no-bag"):
        load_recording(empty)


def test_only_unusable_csvs_and_no_bag_is_a_recording_error(tmp_path):
    sim = make_simulation(tmp_path / "sim", bag=False)
    for uav in (1, 2):
        (sim / f"uav_{uav}.csv").write_text("not,a,recorder\n1,2,3\n")
    with pytest.raises(RecordingError, match=r"no usable uav_<id>\.csv .*uav_1\.csv: not a recorder CSV"):
        load_recording(sim)


def test_an_unreadable_bag_falls_back_to_the_csvs_or_is_an_error_alone(tmp_path):
    with_csvs = make_simulation(tmp_path / "a", bag=False)
    (with_csvs / "simulation.bag").write_bytes(b"not a bag at all")
    recording = load_recording(with_csvs)
    assert recording.bag is None and recording.uavs[1].position.source == "uav_1.csv"
    assert any("simulation.bag cannot be read" in n for n in recording.notes)
    alone = make_simulation(tmp_path / "b", bag=False, csv=False)
    (alone / "simulation.bag").write_bytes(b"not a bag at all")
    with pytest.raises(RecordingError, match=r"simulation\.bag: cannot read the bag"):
        load_recording(alone)


def test_a_csv_that_is_not_a_recorder_csv_is_left_out_with_a_note(tmp_path):
    sim = make_simulation(tmp_path / "sim")
    (sim / "uav_2.csv").write_text("a,b\n1,2\n")
    recording = load_recording(sim)
    assert any("uav_2.csv: not a recorder CSV (no column time" in n for n in recording.notes)
    assert recording.uavs[2].position.source == "simulation.bag"


# --- the world -----------------------------------------------------------------------------------------------------

def test_the_world_is_re_resolved_from_its_file_with_colours_and_the_records_obstacles(tmp_path):
    registry = WorldRegistry(seed=11)
    registry.add_file("main", WORLD_FILE)
    record = registry.record()
    (tmp_path / "world.json").write_text(json.dumps(record))
    world = world_from_record(tmp_path / "world.json")
    assert world.notes == [] and str(WORLD_FILE) in world.source
    assert len(world.geometries) == len(record["parts"]["main"]["geometries"])
    assert [s.name for s in world.obstacles] == [o["name"] for o in record["parts"]["main"]["obstacles"]]
    torus = next(s for s in world.geometries if s.spec.shape == "torus")
    assert torus.color != RECORD_COLOR  # the file's colour, which the record does not keep
    assert np.allclose(world.boundaries, [[-12, 12], [-14, 12], [0, 8]])


def test_a_moved_world_file_is_found_by_world_and_subworld_and_a_lost_one_drawn_from_the_record(tmp_path):
    registry = WorldRegistry(seed=11)
    registry.add_file("main", WORLD_FILE)
    record = registry.record()
    moved = json.loads(json.dumps(record))
    moved["parts"]["main"]["source"] = "/elsewhere/clone/worlds/Gym/Central_Obstacle_Torus.json"
    (tmp_path / "moved.json").write_text(json.dumps(moved))
    world = world_from_record(tmp_path / "moved.json")
    assert world.notes == [] and str(WORLD_FILE) in world.source
    lost = json.loads(json.dumps(record))
    lost["parts"]["main"]["source"] = "/elsewhere/worlds/Nowhere/Nothing.json"
    (tmp_path / "lost.json").write_text(json.dumps(lost))
    world = world_from_record(tmp_path / "lost.json")
    assert "drawn from the record" in world.notes[0] and "world.json record" in world.source
    assert {s.color for s in world.geometries} == {RECORD_COLOR}
    assert [s.frame.translation.tolist() for s in world.obstacles] == [o["position"] for o in
                                                                        record["parts"]["main"]["obstacles"]]


def test_a_world_file_edited_since_the_flight_is_not_trusted(tmp_path):
    registry = WorldRegistry(seed=11)
    registry.add_file("main", WORLD_FILE)
    record = registry.record()
    record["parts"]["main"]["seed"] = 12  # the same file resolves to other random obstacles
    (tmp_path / "world.json").write_text(json.dumps(record))
    world = world_from_record(tmp_path / "world.json", search_path=[])
    assert "other obstacles than the record" in world.notes[0]


def test_without_world_json_the_obstacle_markers_of_the_bag_are_drawn(tmp_path):
    sim = make_simulation(tmp_path / "sim")
    (sim / "world.json").unlink()
    recording = load_recording(sim)
    assert [(s.spec.shape, s.spec.dimensions) for s in recording.world.shapes] == [("sphere", (1.0, 1.0, 1.0))]
    assert recording.world.shapes[0].frame.translation.tolist() == [0.0, 5.0, 1.0]
    assert any("world.json missing" in n for n in recording.notes)


# --- the timeline's logic ------------------------------------------------------------------------------------------

def machine(*containers) -> list[ContainerStructure]:
    return [ContainerStructure(path, kind, tuple(children), tuple(types), ("done",), (), tuple(transitions))
            for path, kind, children, types, transitions in containers]


def test_two_states_ending_in_one_message_get_no_guessed_outcome_and_a_container_end_closes_its_children():
    shapes = machine(("/M", "StateMachine", ["1_pair", "after"], ["Concurrence", "CallbackState"],
                      [("1_pair", "ok", "after")]),
                     ("/M/1_pair", "Concurrence", ["1_a", "2_b"], ["MissionActionState"] * 2, []))
    events = [StatusEvent(0.0, "/M", ("1_pair",), "", "running"),
              StatusEvent(0.0, "/M/1_pair", ("1_a", "2_b"), "", "running"),
              StatusEvent(2.0, "/M/1_pair", (), "succeeded", "running"),  # both at once: whose outcome?
              StatusEvent(3.0, "/M", ("after",), "ok", "running"),
              StatusEvent(4.0, "/M", ("1_pair",), "done", "running"),  # the pair again; its status is not heard
              StatusEvent(4.0, "/M/1_pair", ("1_a", "2_b"), "", "running"),
              StatusEvent(5.0, "/M", (), "aborted", "running"),  # ... and the pair ends with its children open
              StatusEvent(5.0, "/M", (), "aborted", "finished:aborted")]
    timeline = build_timeline(shapes, events, end_time=9.0, uav_ids={1, 2})
    children = [(i.label, i.start, i.end, i.outcome) for i in timeline.intervals if i.container == "/M/1_pair"]
    assert children == [("1_a", 0.0, 2.0, None), ("2_b", 0.0, 2.0, None), ("1_a", 4.0, 5.0, None),
                        ("2_b", 4.0, 5.0, None)]
    pair = timeline.intervals_of("/M/1_pair")
    assert [(i.start, i.end, i.outcome, i.next_state) for i in pair] == [(0.0, 3.0, "ok", "after"),
                                                                          (4.0, 5.0, "aborted", None)]
    assert timeline.outcome == "aborted" and timeline.finished_at == 5.0
    assert not any(i.unfinished for i in timeline.intervals)


def test_a_missed_transition_is_repaired_by_the_next_heartbeat_and_unknown_states_still_get_rows():
    events = [StatusEvent(1.0, "/M", ("a",), "", "running"),
              StatusEvent(2.0, "/M", ("c",), "done", "heartbeat")]  # "b" ran between, unheard
    timeline = build_timeline([], events, end_time=3.0, uav_ids={1})
    assert [(i.label, i.start, i.end, i.outcome, i.unfinished) for i in timeline.intervals] == [
        ("a", 1.0, 2.0, "done", False), ("c", 2.0, 3.0, None, True)]
    assert [s.path for s in timeline.states] == ["/M/a", "/M/c"]


def test_only_leaves_named_after_a_mission_uav_belong_to_it():
    shapes = machine(("/M", "StateMachine", ["3_go", "1_all", "12_go"], ["MissionActionState", "Concurrence",
                                                                         "MissionActionState"], []),
                     ("/M/1_all", "Concurrence", ["1_x"], ["MissionActionState"], []))
    timeline = build_timeline(shapes, [], end_time=1.0, uav_ids={1, 3})
    assert {s.label: s.uav_id for s in timeline.states} == {"3_go": 3, "1_all": None, "1_x": 1, "12_go": None}


# --- latency on hand-made recordings -------------------------------------------------------------------------------

def hand_made(speeds: list[float], intervals) -> Recording:
    t = np.arange(len(speeds)) * DT
    velocity = Samples(t, np.column_stack([np.zeros(len(t)), np.zeros(len(t)), speeds]), "test")
    uav = UavRecord(1, "iris", (1.0, 0.0, 0.0, 1.0), 0.3, 2.0, Samples(t, np.zeros((len(t), 3)), "test"), velocity)
    from magna_viz.recorded_world import RecordedWorld
    from magna_viz.timeline import StateInterval

    timeline = Timeline(intervals=[StateInterval(f"/M/{label}", "/M", label, start, end, None, None, 1, kind,
                                                 before) for label, start, end, kind, before in intervals])
    return Recording(Path("hand"), {1: uav}, RecordedWorld(), timeline, None, None, {}, 0.0, float(t[-1]))


def test_only_action_states_that_start_from_rest_and_with_a_known_start_are_commands():
    speeds = [0.0] * 10 + [0.3] * 10 + [0.02] * 10 + [0.0] * 10  # moving 1.0-2.0 s, near-still after
    recording = hand_made(speeds, [
        ("1_go", 0.5, 1.5, "MissionActionState", False),  # from rest: moves at 1.0
        ("1_turn", 1.2, 1.8, "MissionActionState", False),  # already moving: not a command from rest
        ("1_early", 0.0, 1.5, "MissionActionState", True),  # began before the recording
        ("wait", 0.5, 1.5, "CallbackState", False),  # not an action
        ("1_hold", 2.5, 3.9, "MissionActionState", False),  # hovers (0.02 < 0.05) and never moves
    ])
    got = [(c.state, c.latency) for c in command_latencies(recording)]
    assert got == [("/M/1_go", pytest.approx(0.5)), ("/M/1_hold", None)]
    assert latency_samples(command_latencies(recording)) == {"UAV 1": [pytest.approx(500.0)]}
    # a stricter threshold: 0.02 m/s is motion, so 1_hold now starts while moving
    assert [c.state for c in command_latencies(recording, threshold=0.01)] == ["/M/1_go"]


# --- the real recorded simulation ----------------------------------------------------------------------------------

def test_the_recorded_run_holds_both_uavs_in_their_mission_colours(recorded_run):
    recording = load_recording(recorded_run.sim_dir)
    mission = json.loads((ROOT / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json").read_text())
    colours = {a["ID"]: a["marker_color"] for a in mission["Agents_Config"]}
    assert sorted(recording.uavs) == sorted(colours) == list(recorded_run.uav_ids)
    for uav, (r, g, b, a) in colours.items():
        assert recording.uavs[uav].color == pytest.approx((r / 255, g / 255, b / 255, a))
        assert recording.uavs[uav].position.source == "simulation.bag" and len(recording.uavs[uav].position) > 100
        assert recording.uavs[uav].smoothed_paths and len(recording.uavs[uav].goals) >= 2
    assert recording.notes == []
    assert recording.world.obstacles and recording.world.geometries
    assert recording.result.success is True


def test_the_recorded_run_has_the_missions_states_in_order(recorded_run):
    timeline = load_recording(recorded_run.sim_dir).timeline
    leaves = ["/MISSION/1_take_off/1_take_off", "/MISSION/1_take_off/2_take_off", "/MISSION/1_crossing/1_cross",
              "/MISSION/1_crossing/2_cross", "/MISSION/1_land/1_land", "/MISSION/1_land/2_land"]
    for path in leaves:
        (interval,) = timeline.intervals_of(path)
        assert interval.outcome == "succeeded" and interval.uav_id == int(path.rsplit("/", 1)[1][0])
    starts = [timeline.intervals_of(p)[0].start for p in leaves[::2]]
    assert starts == sorted(starts)
    assert not timeline.ran("/MISSION/1_safety_hover")  # the safety branch was not taken
    assert timeline.outcome == "completed"


def test_the_recorded_runs_distances_from_the_bag_agree_with_the_csvs(recorded_run, tmp_path):
    recording = load_recording(recorded_run.sim_dir)
    for name in ("mission.json", "world.json", "uav_1.csv", "uav_2.csv"):  # the run without its bag
        (tmp_path / name).write_bytes((recorded_run.sim_dir / name).read_bytes())
    from_csv = load_recording(tmp_path)
    for uav in recorded_run.uav_ids:
        bag, csv = recording.uavs[uav].proximity, from_csv.uavs[uav].proximity
        assert bag.source == "simulation.bag" and csv.source == f"uav_{uav}.csv"
        # the managers' poses are at most a few simulator steps old: centimetres at 2 m/s. The bag knows no
        # distance before both UAVs' first poses are in it: on a loaded machine the first seconds may miss.
        for field in ("uav_distance", "obstacle_distance"):
            from_bag = np.interp(csv.time, bag.time, getattr(bag, field))
            both = np.isfinite(getattr(csv, field)) & np.isfinite(from_bag)
            assert both.mean() > 0.5, field
            assert np.median(np.abs(from_bag - getattr(csv, field))[both]) < 0.1, field
