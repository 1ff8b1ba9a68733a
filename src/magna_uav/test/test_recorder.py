"""The recorder: a fixed, documented column set; one row per control step; files written all or nothing."""
import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from magna_uav import recorder
from magna_uav.recorder import HeardStamps, Recorder, column_kind, columns, depth_path, read_csv, read_depth
from magna_uav.world_view import AgentState, Obstacle, WorldView

README = Path(__file__).resolve().parents[1] / "README.md"


def make_view(with_depth=False):
    view = WorldView(1, boundaries=[[-10, 10], [-10, 10], [0, 10]])
    depth = np.arange(12, dtype=np.float64).reshape(3, 4) / 10 if with_depth else None
    view.update_agent(AgentState(1, [0, 0, 1], [0, 0, 0.6, 0.8], [1, 0, 0], yaw_rate=0.1, ual_state=4,
                                 battery=0.9, safety_radius=0.5, depth=depth))
    view.update_agent(AgentState(2, [3, 0, 1], velocity=[-1, 0, 0], safety_radius=0.5))
    view.set_obstacles([Obstacle("far", np.array([0, 9, 1.0]), 1.0), Obstacle("near", np.array([0, -3, 1.0]), 1.0),
                        Obstacle("mid", np.array([0, 5, 1.0]), 0.5)])
    return view


def record_one(rec, view, **kwargs):
    args = dict(time=1.5, role="path", algorithm="orca3", goal_position=[5, 0, 1], chosen_velocity=[0.5, 0, 0],
                view=view)
    args.update(kwargs)
    return rec.record(**args)


def test_column_set_and_order_for_two_other_uavs_and_two_obstacles():
    assert columns([3, 2], n_obstacles=2) == [
        "time", "uav_id", "role", "algorithm", "goal.x", "goal.y", "goal.z",
        "goal_vel.x", "goal_vel.y", "goal_vel.z", "goal_dist", "sel_vel.x", "sel_vel.y", "sel_vel.z",
        "teacher_vel.x", "teacher_vel.y", "teacher_vel.z", "fallback",
        "pos.x", "pos.y", "pos.z", "ori.x", "ori.y", "ori.z", "ori.w", "vel.x", "vel.y", "vel.z", "yaw_rate",
        "uav2.pos.x", "uav2.pos.y", "uav2.pos.z", "uav2.vel.x", "uav2.vel.y", "uav2.vel.z",
        "uav3.pos.x", "uav3.pos.y", "uav3.pos.z", "uav3.vel.x", "uav3.vel.y", "uav3.vel.z",
        "nearest_uav_gap", "nearest_obstacle_gap", "uav2.gap", "uav3.gap",
        "obs0.name", "obs0.pos.x", "obs0.pos.y", "obs0.pos.z", "obs0.gap",
        "obs1.name", "obs1.pos.x", "obs1.pos.y", "obs1.pos.z", "obs1.gap",
        "collision", "collided_with", "out_of_bounds", "low_battery", "battery", "ual_state", "feasible", "outcome"]
    assert len(columns([], 0)) == 29 + 2 + 8
    assert len(columns([2], 5)) == 29 + 6 + 2 + 1 + 5 * 5 + 8
    assert Recorder(1, [3, 2], n_obstacles=2).columns == columns([2, 3], 2)


def test_bad_recorder_arguments_are_refused():
    with pytest.raises(ValueError, match="own id"):
        Recorder(1, [1, 2])
    with pytest.raises(ValueError, match="repeat"):
        Recorder(1, [2, 2])
    with pytest.raises(ValueError, match="n_obstacles"):
        Recorder(1, [2], n_obstacles=-1)


def test_the_readme_documents_every_column_rule():
    text = README.read_text()
    section = text.split("## Recorder CSV columns", 1)[1]
    documented = set(re.findall(r"^\| `([^`]+)`", section, flags=re.M))
    generic = {name.replace("uav7", "uav{j}").replace("obs0", "obs{k}") for name in columns([7], 1)}
    assert generic <= documented, generic - documented


def test_one_row_per_record_call_with_the_view_and_the_sphere_gaps():
    rec = Recorder(1, [2, 3], n_obstacles=2)
    view = make_view()
    assert rec.rows == 0
    assert record_one(rec, view) == 0
    assert record_one(rec, view, time=1.6) == 1
    assert rec.rows == 2
    row = rec.row(0)
    assert (row["time"], row["uav_id"], row["role"], row["algorithm"]) == (1.5, 1, "path", "orca3")
    assert [row[f"goal.{a}"] for a in "xyz"] == [5, 0, 1]
    assert [row[f"sel_vel.{a}"] for a in "xyz"] == [0.5, 0, 0]
    assert [row[f"ori.{a}"] for a in "xyzw"] == [0, 0, 0.6, 0.8]
    assert [row[f"vel.{a}"] for a in "xyz"] + [row["yaw_rate"]] == [1, 0, 0, 0.1]
    assert [row[f"uav2.{k}.{a}"] for k in ("pos", "vel") for a in "xyz"] == [3, 0, 1, -1, 0, 0]
    assert row["uav2.gap"] == pytest.approx(2.0) and row["nearest_uav_gap"] == pytest.approx(2.0)
    # UAV 3 was never heard of: NaN everywhere
    assert all(math.isnan(row[c]) for c in rec.columns if c.startswith("uav3."))
    # the two nearest obstacles, nearest first: near (gap 3-1-0.5), mid (5-0.5-0.5); far left out
    assert (row["obs0.name"], row["obs0.gap"], row["obs1.name"], row["obs1.gap"]) == ("near", 1.5, "mid", 4.0)
    assert [row[f"obs0.pos.{a}"] for a in "xyz"] == [0, -3, 1]
    assert row["nearest_obstacle_gap"] == 1.5
    assert (row["collision"], row["collided_with"], row["out_of_bounds"], row["low_battery"]) == (0, "", 0, 0)
    assert (row["battery"], row["ual_state"], row["feasible"], row["outcome"]) == (0.9, 4, None, "")


def test_the_evaluation_decides_gaps_and_events_and_missing_obstacle_slots_are_empty():
    rec = Recorder(1, [2, 3], n_obstacles=5)
    evaluation = SimpleNamespace(nearest_agent_gap=-0.2, nearest_obstacle_gap=0.7, agent_gaps={2: -0.2},
                                 obstacle_gaps={"far": 0.7, "near": 1.1, "mid": 2.0}, collided_with=[2, "near"],
                                 out_of_bounds=True, low_battery=True)
    record_one(rec, make_view(), evaluation=evaluation, feasible=False, outcome="collision")
    row = rec.row(0)
    assert (row["nearest_uav_gap"], row["nearest_obstacle_gap"], row["uav2.gap"]) == (-0.2, 0.7, -0.2)
    assert math.isnan(row["uav3.gap"])
    assert [row[f"obs{k}.name"] for k in range(5)] == ["far", "near", "mid", "", ""]  # ranked by the evaluation
    assert all(math.isnan(row[f"obs4.{c}"]) for c in ("pos.x", "pos.y", "pos.z", "gap"))
    assert (row["collision"], row["collided_with"], row["out_of_bounds"], row["low_battery"]) == (1, "2;near", 1, 1)
    assert (row["feasible"], row["outcome"]) == (0, "collision")
    # a partial evaluation (the attributes it lacks take their defaults)
    record_one(rec, make_view(), evaluation=SimpleNamespace(collided_with=[]), feasible=True)
    row = rec.row(1)
    assert (row["collision"], row["low_battery"], row["feasible"], row["uav2.gap"]) == (0, 0, 1, pytest.approx(2.0))


def test_infinite_gaps_are_written_nan_and_a_gap_by_a_repeated_name_is_not_trusted():
    rec = Recorder(1, [2], n_obstacles=3)
    view = make_view()
    view.set_obstacles([*view.obstacles, Obstacle("near", np.array([0, -8, 1.0]), 1.0)])  # a second "near"
    evaluation = SimpleNamespace(nearest_agent_gap=math.inf, nearest_obstacle_gap=math.inf, agent_gaps={},
                                 obstacle_gaps={"near": 1.5, "mid": -0.1})
    record_one(rec, view, evaluation=evaluation)
    row = rec.row(0)
    assert math.isnan(row["nearest_uav_gap"]) and math.isnan(row["nearest_obstacle_gap"])
    assert row["uav2.gap"] == pytest.approx(2.0)  # the evaluation had no gap for UAV 2: the view's
    ranked = [(row[f"obs{k}.name"], row[f"obs{k}.pos.y"], row[f"obs{k}.gap"]) for k in range(3)]
    assert ranked == [("mid", 5, -0.1), ("near", -3, 1.5), ("near", -8, 6.5)]


def test_unknown_goal_and_own_pose_give_nan_and_out_of_bounds_comes_from_the_view():
    rec = Recorder(1, [2], n_obstacles=1)
    view = WorldView(1, boundaries=[[-1, 1], [-1, 1], [0, 2]])
    record_one(rec, view, goal_position=None, chosen_velocity=None)  # no own pose heard yet
    row = rec.row(0)
    assert all(math.isnan(row[c]) for c in ("goal.x", "goal_vel.y", "goal_dist", "sel_vel.z", "pos.x", "ori.w",
                                            "battery", "nearest_uav_gap"))
    assert (row["ual_state"], row["out_of_bounds"]) == (0, 0)
    view.update_agent(AgentState(1, [5, 0, 1]))
    record_one(rec, view)
    assert rec.row(1)["out_of_bounds"] == 1


def test_the_goal_target_velocity_and_distance_follow_the_goal_and_are_nan_without_one():
    rec = Recorder(1, [2])
    record_one(rec, make_view(), role="agent_ad", goal_velocity=[1.0, -0.5, 0.25], goal_distance=2.0)
    record_one(rec, make_view(), role="agent_ap", goal_velocity=np.array([0.0, 1.0, 0.0]))
    record_one(rec, make_view())  # a path step: no target
    target = [[rec.row(i)[c] for c in ("goal_vel.x", "goal_vel.y", "goal_vel.z", "goal_dist")] for i in range(3)]
    assert target[0] == [1.0, -0.5, 0.25, 2.0]
    assert target[1][:3] == [0.0, 1.0, 0.0] and math.isnan(target[1][3])
    assert all(math.isnan(v) for v in target[2])
    assert list(rec.row(0))[4:11] == ["goal.x", "goal.y", "goal.z", "goal_vel.x", "goal_vel.y", "goal_vel.z",
                                      "goal_dist"]
    with pytest.raises(ValueError, match="expected 3 values"):
        record_one(rec, make_view(), goal_velocity=[1.0, 2.0])


def test_each_new_row_goes_to_on_row_as_recorded_with_the_stamps_of_its_messages():
    seen = []
    rec = Recorder(1, [3, 2], on_row=lambda index, row, heard: seen.append((index, row, heard)))
    view = make_view()
    record_one(rec, view, feasible=True)
    view.update_agent(AgentState(3, [0, 3, 1], pose_stamp_ns=7_000_000_001, velocity_stamp_ns=6_900_000_000))
    view.update_agent(AgentState(1, [0, 0, 1], pose_stamp_ns=7_100_000_000, velocity_stamp_ns=7_050_000_000))
    record_one(rec, view, time=1.6, algorithm="ual", chosen_velocity=[0, 0, 0])
    assert [(index, row) for index, row, _ in seen] == [(0, rec.row(0)), (1, rec.row(1))]
    assert (seen[1][1]["time"], seen[1][1]["algorithm"]) == (1.6, "ual")
    # own first, then the others in the CSV's order (by id); only the UAVs in the view (3 came before row 1)
    assert seen[0][2] == [HeardStamps(1, 0, 0), HeardStamps(2, 0, 0)]
    assert seen[1][2] == [HeardStamps(1, 7_100_000_000, 7_050_000_000), HeardStamps(2, 0, 0),
                          HeardStamps(3, 7_000_000_001, 6_900_000_000)]


def test_set_outcome_marks_the_last_row():
    rec = Recorder(1, [])
    with pytest.raises(LookupError):
        rec.set_outcome("succeeded")
    record_one(rec, make_view())
    record_one(rec, make_view())
    rec.set_outcome("succeeded")
    assert [rec.row(i)["outcome"] for i in range(2)] == ["", "succeeded"]


def test_read_csv_round_trip_keeps_every_value_and_type(tmp_path):
    rec = Recorder(1, [2, 3], n_obstacles=2)
    evaluation = SimpleNamespace(collided_with=["a,b", 'q"uote'], out_of_bounds=False, low_battery=False)
    record_one(rec, make_view(), role="path, with comma", feasible=True)
    record_one(rec, make_view(), time=0.1 + 0.2, evaluation=evaluation, outcome="succeeded")
    written = rec.save_csv(tmp_path / "uav_1.csv")
    assert written == tmp_path / "uav_1.csv"
    header, rows = read_csv(written)
    assert header == rec.columns and len(rows) == 2
    for index, row in enumerate(rows):
        expected = rec.row(index)
        for column in header:
            got, want = row[column], expected[column]
            if isinstance(want, float) and math.isnan(want):
                assert isinstance(got, float) and math.isnan(got), column
            else:
                assert got == want and type(got) is type(want), column
    assert rows[1]["time"] == 0.1 + 0.2  # shortest round-trip form, not rounded
    assert rows[1]["collided_with"] == 'a,b;q"uote' and rows[0]["role"] == "path, with comma"
    assert {column_kind(c) for c in header} == {"text", "int", "float", "flag?"}


def test_read_csv_refuses_a_file_that_is_not_a_recorder_csv(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time,uav_id\n1,2\n")
    with pytest.raises(ValueError, match=r"bad.csv: not a recorder CSV header \(missing \['role'"):
        read_csv(bad)
    rec = Recorder(1, [2])
    record_one(rec, make_view())
    good = rec.save_csv(tmp_path / "good.csv")
    lines = good.read_text().splitlines()
    (tmp_path / "short.csv").write_text(lines[0] + "\n" + lines[1].rsplit(",", 1)[0] + "\n")
    with pytest.raises(ValueError, match=r"short.csv:2: \d+ cells for \d+ columns"):
        read_csv(tmp_path / "short.csv")


@pytest.mark.parametrize("missing", recorder.LEGACY_GENERATIONS, ids=["no_teacher", "no_goal_target"])
def test_read_csv_reads_a_file_of_an_older_recorder_with_nan_in_the_columns_it_lacks(tmp_path, missing):
    rec = Recorder(1, [2], n_obstacles=1)
    record_one(rec, make_view(), goal_velocity=[1, 2, 3], goal_distance=4.0, teacher_velocity=[0.1, 0.2, 0.3],
               fallback=True)
    record_one(rec, make_view(), time=1.6, outcome="succeeded")
    new = rec.save_csv(tmp_path / "new.csv")
    # the same file as an older recorder wrote it: the columns of that generation cut out
    lines = [line.split(",") for line in new.read_text().splitlines()]
    keep = [i for i, name in enumerate(lines[0]) if name not in missing]
    assert len(keep) == len(lines[0]) - len(missing)
    old = tmp_path / "old.csv"
    old.write_text("".join(",".join(cells[i] for i in keep) + "\n" for cells in lines))
    header, rows = read_csv(old)
    assert header == rec.columns  # one layout for callers, whatever the file's age
    assert [list(row) for row in rows] == [rec.columns] * 2
    for index, row in enumerate(rows):
        assert all(row[c] is None if c == "fallback" else math.isnan(row[c]) for c in missing)
        assert row["outcome"] == rec.row(index)["outcome"] and row["goal.x"] == 5 and row["uav2.pos.x"] == 3
    if "goal_dist" not in missing:
        assert rows[0]["goal_dist"] == 4.0
    # a header missing other columns as well is still refused
    (tmp_path / "older.csv").write_text(",".join(lines[0][i] for i in keep if lines[0][i] != "yaw_rate") + "\n")
    with pytest.raises(ValueError, match=rf"older.csv: not a recorder CSV header \(missing \['{missing[0]}'"):
        read_csv(tmp_path / "older.csv")


def test_the_teacher_columns_hold_the_teachers_answer_and_the_fallback_flag(tmp_path):
    rec = Recorder(1, [2])
    record_one(rec, make_view(), algorithm="neural_network", teacher_velocity=[0.25, -0.5, 1.0], fallback=False)
    record_one(rec, make_view(), algorithm="neural_network", teacher_velocity=[1.0, 0.0, 0.0], fallback=True)
    record_one(rec, make_view(), algorithm="orca3d")
    _, rows = read_csv(rec.save_csv(tmp_path / "uav_1.csv"))
    assert [[row[f"teacher_vel.{a}"] for a in "xyz"] for row in rows[:2]] == [[0.25, -0.5, 1.0], [1.0, 0.0, 0.0]]
    assert [row["fallback"] for row in rows] == [0, 1, None]
    assert all(math.isnan(rows[2][f"teacher_vel.{a}"]) for a in "xyz")


def test_an_existing_file_is_refused_unless_overwrite(tmp_path):
    target = tmp_path / "uav_1.csv"
    target.write_text("precious\n")
    rec = Recorder(1, [2])
    record_one(rec, make_view())
    with pytest.raises(FileExistsError, match="uav_1.csv: already exists"):
        rec.save_csv(target)
    assert target.read_text() == "precious\n"
    assert rec.save_csv(target, overwrite=True) == target
    assert len(read_csv(target)[1]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["uav_1.csv"]


def test_save_creates_the_folder_and_keeps_the_rows_until_clear(tmp_path):
    rec = Recorder(1, [2])
    record_one(rec, make_view())
    rec.save_csv(tmp_path / "a" / "b" / "uav_1.csv")
    assert rec.rows == 1
    rec.clear()
    assert rec.rows == 0
    rec.save_csv(tmp_path / "empty.csv")
    header, rows = read_csv(tmp_path / "empty.csv")
    assert header == rec.columns and rows == []


def test_a_crash_mid_write_leaves_no_target_and_no_temporary_file(tmp_path, monkeypatch):
    rec = Recorder(1, [2])
    for n in range(50):
        record_one(rec, make_view(), time=n * 0.1)
    real = Recorder._write_csv

    def crash_half_way(self, out):
        real(self, out)  # every row is out ...
        out.flush()
        assert out.tell() > 1000  # ... and on disk, in the temporary file
        raise OSError("disk full")

    monkeypatch.setattr(Recorder, "_write_csv", crash_half_way)
    with pytest.raises(OSError, match="disk full"):
        rec.save_csv(tmp_path / "uav_1.csv")
    assert list(tmp_path.iterdir()) == []
    # with overwrite the old file survives the crash untouched
    (tmp_path / "uav_1.csv").write_text("old\n")
    with pytest.raises(OSError, match="disk full"):
        rec.save_csv(tmp_path / "uav_1.csv", overwrite=True)
    assert [p.name for p in tmp_path.iterdir()] == ["uav_1.csv"] and (tmp_path / "uav_1.csv").read_text() == "old\n"


def test_a_crash_in_the_csv_after_the_depth_file_removes_the_new_depth_file(tmp_path, monkeypatch):
    rec = Recorder(1, [2], depth=True)
    record_one(rec, make_view(with_depth=True))

    def crash(self, out):
        out.write("time,uav")
        raise RuntimeError("killed")

    monkeypatch.setattr(Recorder, "_write_csv", crash)
    with pytest.raises(RuntimeError, match="killed"):
        rec.save_csv(tmp_path / "uav_1.csv")
    assert list(tmp_path.iterdir()) == []


def test_depth_frames_round_trip_by_row_index(tmp_path):
    rec = Recorder(1, [2], depth=True)
    with_depth, without = make_view(with_depth=True), make_view()
    record_one(rec, with_depth, time=0.0)
    record_one(rec, without, time=0.1)  # no frame on this step
    with_depth.own.depth = with_depth.own.depth + 1.0  # a new image arrives
    record_one(rec, with_depth, time=0.2)
    record_one(rec, with_depth, time=0.3)  # the same image again: not stored twice
    assert rec.depth_frames == 2 and rec.rows == 4
    csv_path = rec.save_csv(tmp_path / "uav_1.csv")
    assert depth_path(csv_path) == tmp_path / "uav_1_depth.npz" and depth_path(csv_path).exists()
    frames, rows = read_depth(csv_path)
    assert frames.dtype == np.float32 and frames.shape == (2, 3, 4)
    assert rows.tolist() == [0, 2]
    expected = np.arange(12, dtype=np.float32).reshape(3, 4) / 10
    assert np.allclose(frames[0], expected) and np.allclose(frames[1], expected + 1)
    # the depth file is refused like the CSV, and nothing is written then
    (tmp_path / "uav_1.csv").unlink()
    with pytest.raises(FileExistsError, match="uav_1_depth.npz"):
        rec.save_csv(csv_path)
    assert not csv_path.exists()
    rec.save_csv(csv_path, overwrite=True)
    assert read_depth(csv_path)[1].tolist() == [0, 2]


def test_depth_on_without_frames_and_mismatched_frames(tmp_path):
    rec = Recorder(1, [], depth=True)
    record_one(rec, make_view())
    frames, rows = read_depth(rec.save_csv(tmp_path / "uav_1.csv"))
    assert frames.shape[0] == 0 and rows.shape == (0,)
    view = make_view(with_depth=True)
    record_one(rec, view)
    view.own.depth = np.zeros((5, 5))
    with pytest.raises(ValueError, match="depth frame shape"):
        record_one(rec, view)
    assert rec.rows == 2 and rec.depth_frames == 1  # the refused step left no row behind
    no_depth = Recorder(1, [])
    record_one(no_depth, make_view(with_depth=True))
    no_depth.save_csv(tmp_path / "plain.csv")
    assert not depth_path(tmp_path / "plain.csv").exists() and no_depth.depth_frames == 0


def test_the_recorder_module_imports_without_ros():
    import subprocess
    import sys

    code = ("import sys; sys.modules['rospy'] = sys.modules['nav_msgs'] = sys.modules['geometry_msgs'] = None; "
            "import magna_uav.recorder as r; print(len(r.columns([2], 1)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) == len(recorder.columns([2], 1))


# --- the node's NavigationStep: the same numbers as the row -----------------------------------------------------

def test_a_row_becomes_the_navigation_step_with_its_values():
    from magna_msgs.msg import NavigationStep

    from magna_uav.ros_navigation import navigation_msg

    rec = Recorder(1, [2])
    record_one(rec, make_view(), time=12.3, role="agent_ad", goal_velocity=[1.0, -0.5, 0.25], goal_distance=2.0,
               feasible=False)
    record_one(rec, make_view(), time=0.1 + 0.2, algorithm="ual", goal_position=None, chosen_velocity=[0, 0, 0])
    heard = [HeardStamps(1, 12_299_999_999, 12_266_666_667), HeardStamps(2, 12_250_000_000, 0)]
    first, second = navigation_msg(0, rec.row(0), 3, heard), navigation_msg(1, rec.row(1), 4, [])
    assert (first.row, first.role_number, first.role, first.algorithm) == (0, 3, "agent_ad", "orca3")
    assert (first.header.stamp.secs, first.header.stamp.nsecs, first.header.frame_id) == (12, 300000000, "map")
    assert [first.goal.x, first.goal.y, first.goal.z] == [5, 0, 1]
    assert [first.goal_velocity.x, first.goal_velocity.y, first.goal_velocity.z, first.goal_distance] == \
        [1.0, -0.5, 0.25, 2.0]
    assert [first.selected_velocity.x, first.selected_velocity.y, first.selected_velocity.z] == [0.5, 0, 0]
    assert first.feasible == NavigationStep.INFEASIBLE == 0
    assert list(first.uav_ids) == [1, 2]
    assert [(t.secs, t.nsecs) for t in first.pose_stamps] == [(12, 299999999), (12, 250000000)]
    assert [(t.secs, t.nsecs) for t in first.velocity_stamps] == [(12, 266666667), (0, 0)]  # 0: none heard
    assert (list(second.uav_ids), list(second.pose_stamps), list(second.velocity_stamps)) == ([], [], [])
    # rounded to the ns (0.30000000000000004 s), NaN where the row has NaN, unknown feasibility -1
    assert (second.header.stamp.secs, second.header.stamp.nsecs) == (0, 300000000)
    assert math.isnan(second.goal.x) and math.isnan(second.goal_velocity.y) and math.isnan(second.goal_distance)
    assert second.feasible == NavigationStep.FEASIBILITY_UNKNOWN == -1


@pytest.mark.ros
def test_a_late_subscriber_first_gets_every_step_sent_so_far(rospy_node):
    from magna_msgs.msg import NavigationStep

    from magna_uav.ros_navigation import NavigationPublisher
    from tests.support import wait_until

    rospy = rospy_node
    topic = "/magna/test_recorder/navigation"
    publisher = NavigationPublisher(topic)
    for row in range(3):  # nobody listens yet: a simulation's first steps before rosbag subscribes
        publisher.publish(NavigationStep(row=row, role_number=1, role="take_off", algorithm="ual"))
    heard = []
    subscriber = rospy.Subscriber(topic, NavigationStep, lambda msg: heard.append(msg.row), queue_size=100)
    try:
        wait_until(lambda: len(heard) >= 3, "the replayed steps")
        publisher.publish(NavigationStep(row=3, role_number=2, role="path", algorithm="orca3d"))
        wait_until(lambda: 3 in heard, "the next step")
        assert sorted(set(heard)) == [0, 1, 2, 3] and heard[:3] == [0, 1, 2]
    finally:
        subscriber.unregister()
        publisher.publisher.unregister()
