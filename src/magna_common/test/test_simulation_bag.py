"""magna_common.simulation_bag: a small bag written with rosbags' writer, read back by kind."""
from __future__ import annotations

from pathlib import Path

import pytest

from magna_common.errors import UserError
from magna_common.simulation_bag import BagError, read_simulation_bag, topic_kind

MSG_DIR = Path(__file__).resolve().parents[2] / "magna_msgs" / "msg"
S = 10**9  # ns per s


@pytest.fixture(scope="module")
def store():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg((MSG_DIR / "SMStatus.msg").read_text(), "magna_msgs/msg/SMStatus"))
    return store


def header(store, ns: int):
    t = store.types
    return t["std_msgs/msg/Header"](seq=0, stamp=t["builtin_interfaces/msg/Time"](sec=ns // S, nanosec=ns % S),
                                    frame_id="map")


def pose(store, ns: int, xyz):
    t = store.types
    return t["geometry_msgs/msg/PoseStamped"](header=header(store, ns), pose=t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))


def write_bag(store, path: Path) -> Path:
    """(log time, topic, message): stamped and unstamped poses, a path, a state-machine status, markers and a
    topic the reader does not know."""
    t = store.types
    items = [
        (1 * S, "/magna/world/markers", t["visualization_msgs/msg/MarkerArray"](markers=[])),
        (2 * S, "/uav_1/ual/pose", pose(store, 2 * S - S // 10, (1.0, 2.0, 3.0))),
        (3 * S, "/uav_2/ual/pose", pose(store, 0, (4.0, 5.0, 6.0))),  # unstamped: counts from its log time
        (4 * S, "/magna/uav_1/path/smoothed", t["nav_msgs/msg/Path"](
            header=header(store, 4 * S), poses=[pose(store, 0, (0.0, 0.0, 1.0)), pose(store, 0, (2.0, 0.0, 1.0))])),
        (5 * S, "/magna/sm/mission/status", t["magna_msgs/msg/SMStatus"](
            header=header(store, 5 * S), path="/MISSION", active_states=["spawn"], initial_states=[],
            last_outcome="", preempt_requested=False, info="running")),
        (6 * S, "/rosout_agg", t["std_msgs/msg/String"](data="not one of ours")),
        (7 * S, "/uav_1/ual/pose", pose(store, 7 * S, (1.0, 2.0, 4.0))),
    ]
    from rosbags.rosbag1 import Writer

    with Writer(path) as writer:
        connections = {}
        for ns, topic, msg in items:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=store)
            writer.write(connections[topic], ns, store.serialize_ros1(msg, msg.__msgtype__))
    return path


def test_topics_are_sorted_into_kinds_with_their_owner():
    assert topic_kind("/uav_12/ual/velocity") == ("velocity", 12)
    assert topic_kind("/magna/uav_3/path/raw") == ("path/raw", 3)
    assert topic_kind("/magna/uav_3/navigation") == ("navigation", 3)
    assert topic_kind("/magna/sm/mission/structure") == ("structure", "mission")
    assert topic_kind("/magna/world/markers") == ("markers", None)
    assert topic_kind("/uav_1/ual/pose/extra") is None and topic_kind("/clock") is None


def test_a_bag_reads_back_by_kind_with_stamps_or_log_times(store, tmp_path):
    bag = read_simulation_bag(write_bag(store, tmp_path / "simulation.bag"))
    assert (bag.start, bag.end, bag.message_count) == (1 * S, 7 * S, 7)
    assert bag.duration == 6.0
    assert "/rosout_agg" in bag.topics and bag.uav_ids() == [1, 2] and bag.uav_ids("path/smoothed") == [1]
    poses = bag.by_owner("pose")
    assert [m.stamp for m in poses[1]] == [2 * S - S // 10, 7 * S] and poses[1][0].time == 1.9
    assert [m.msg.pose.position.z for m in poses[1]] == [3.0, 4.0]
    assert poses[2][0].stamp == 3 * S and poses[2][0].log_time == 3 * S  # unstamped
    (path,) = bag.of("path/smoothed")
    assert (path.owner, path.stamp, [p.pose.position.x for p in path.msg.poses]) == (1, 4 * S, [0.0, 2.0])
    (status,) = bag.of("status")
    assert (status.owner, status.msg.path, list(status.msg.active_states)) == ("mission", "/MISSION", ["spawn"])
    (markers,) = bag.of("markers")
    assert (markers.owner, markers.stamp) == (None, 1 * S)  # a MarkerArray has no header: its log time
    assert bag.of("velocity") == [] and bag.by_owner("goal") == {}


def test_only_the_kinds_asked_for_are_read(store, tmp_path):
    bag = read_simulation_bag(write_bag(store, tmp_path / "simulation.bag"), kinds=("path/smoothed",))
    assert list(bag.messages) == ["path/smoothed"] and bag.message_count == 7 and bag.uav_ids() == [1, 2]
    assert read_simulation_bag(tmp_path / "simulation.bag", kinds=()).messages == {}
    with pytest.raises(ValueError, match="unknown message kinds \\['poses'\\]"):
        read_simulation_bag(tmp_path / "simulation.bag", kinds=("poses",))


def test_a_file_that_is_not_a_bag_is_a_user_error_naming_it(tmp_path):
    junk = tmp_path / "simulation.bag"
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(BagError, match=f"^{junk}: not a readable ROS bag \\(") as caught:
        read_simulation_bag(junk)
    assert isinstance(caught.value, UserError) and caught.value.path == junk
    with pytest.raises(BagError, match=f"{tmp_path / 'missing.bag'}: not a readable ROS bag \\(no such file\\)"):
        read_simulation_bag(tmp_path / "missing.bag")
