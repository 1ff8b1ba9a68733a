"""The UTM library: plan files (with their errors), planned times, plan changes and the conflict check."""
import json

import numpy as np
import pytest

from magna_gs.utm import (
    ConflictLimits,
    FlightPlan,
    Utm,
    UtmPlanError,
    find_conflicts,
    load_plan,
    mission_plan,
    mission_uses_utm,
    parse_plan,
    timed,
)

LIMITS = ConflictLimits(distance=3.0, time=3.0)


def plan(uav_id, points, times):
    return FlightPlan(uav_id, np.asarray(points, dtype=float), np.asarray(times, dtype=float))


# --- conflicts --------------------------------------------------------------------------------
def test_crossing_plans_at_the_same_time_conflict_at_the_crossing():
    a = plan(1, [[-10, 0, 5], [10, 0, 5]], [0, 10])
    b = plan(2, [[0, -10, 5], [0, 10, 5]], [0, 10])
    [conflict] = find_conflicts([a, b], LIMITS)
    assert conflict.uav_ids == (1, 2) and conflict.segments == (0, 0)
    assert conflict.distance == pytest.approx(0.0)
    np.testing.assert_allclose(conflict.points[0], [0, 0, 5], atol=1e-9)
    assert conflict.times == pytest.approx((5.0, 5.0))


def test_crossing_plans_separated_in_time_or_height_do_not_conflict():
    a = plan(1, [[-10, 0, 5], [10, 0, 5]], [0, 10])
    late = plan(2, [[0, -10, 5], [0, 10, 5]], [20, 30])  # at the crossing 20 s after UAV 1
    assert find_conflicts([a, late], LIMITS) == []
    slightly_late = plan(2, [[0, -10, 5], [0, 10, 5]], [2, 12])  # 2 s < 3 s
    assert len(find_conflicts([a, slightly_late], LIMITS)) == 1
    above = plan(2, [[0, -10, 9], [0, 10, 9]], [0, 10])  # 4 m above > 3 m
    assert find_conflicts([a, above], LIMITS) == []
    assert len(find_conflicts([a, above], ConflictLimits(distance=5.0, time=3.0))) == 1


def test_parallel_plans_side_by_side():
    a = plan(1, [[0, 0, 5], [20, 0, 5]], [0, 20])
    together = plan(2, [[0, 2, 5], [20, 2, 5]], [0, 20])  # 2 m apart, abreast
    [conflict] = find_conflicts([a, together], LIMITS)
    assert conflict.distance == pytest.approx(2.0)
    assert conflict.time_gap == pytest.approx(0.0)
    far = plan(2, [[0, 4, 5], [20, 4, 5]], [0, 20])  # 4 m apart
    assert find_conflicts([a, far], LIMITS) == []
    # one behind the other on the same line, 10 s apart: never within 3 s of each other at a point
    trailing = plan(2, [[0, 0, 5], [20, 0, 5]], [10, 30])
    assert find_conflicts([a, trailing], LIMITS) == []
    # head-on on the same line: they meet in the middle at t = 10
    head_on = plan(2, [[20, 0, 5], [0, 0, 5]], [0, 20])
    [meeting] = find_conflicts([a, head_on], LIMITS)
    np.testing.assert_allclose(meeting.points[0], [10, 0, 5], atol=1e-9)
    assert meeting.times == pytest.approx((10.0, 10.0))


def test_parallel_segments_end_to_end_meet_at_their_ends():
    a = plan(1, [[0, 0, 5], [10, 0, 5]], [0, 10])
    b = plan(2, [[11, 0, 5], [20, 0, 5]], [10, 19])
    [conflict] = find_conflicts([a, b], LIMITS)
    assert conflict.distance == pytest.approx(1.0) and conflict.time_gap == pytest.approx(0.0)


def test_a_hovering_plan_is_a_point():
    a = plan(1, [[0, 0, 5]], [0])
    passing = plan(2, [[-10, 1, 5], [10, 1, 5]], [-10, 10])
    [conflict] = find_conflicts([a, passing], LIMITS)
    assert conflict.distance == pytest.approx(1.0)


def test_a_uav_never_conflicts_with_itself():
    a = plan(1, [[0, 0, 5], [10, 0, 5]], [0, 10])
    assert find_conflicts([a, a], LIMITS) == []


# --- planned times ------------------------------------------------------------------------------
def test_times_from_speed_and_given_times():
    times = timed([[0, 0, 0], [4, 0, 0], [4, 3, 0]], [None, None, 10.0], 1.0, 2.0)
    assert times.tolist() == pytest.approx([1.0, 3.0, 10.0])
    # from the UAV's position, and never earlier than the point before
    times = timed([[6, 0, 0], [8, 0, 0]], [None, 0.0], 0.0, 2.0, start=np.zeros(3))
    assert times.tolist() == pytest.approx([3.0, 3.0])


# --- plan changes over time -------------------------------------------------------------------
def test_plans_are_issued_when_due_and_counted_per_uav():
    utm = Utm(parse_plan({"flight_plans": [
        {"ids": [1], "at": 40, "waypoints": [[0, 0, 5]]},
        {"ids": [1, 2], "at": 0, "waypoints": [[1, 0, 5], ["V", "G", "matrix", [0, 0, 0]]]}]}, "plan.json"))
    resolve = {("V", "G", "matrix", (0, 0, 0)): [np.array([2.0, 0, 5])]}

    def resolver(definition):
        return resolve[tuple(definition[:3]) + (tuple(definition[3]),)]

    first = utm.due(0.0, resolver)
    assert [(p.uav_id, p.version, len(p.points)) for p in first] == [(1, 1, 2), (2, 1, 2)]
    assert utm.due(39.9, resolver) == []
    [change] = utm.due(40.0, resolver)
    assert (change.uav_id, change.version) == (1, 2)
    assert utm.snapshot()["plans"]["1"]["waypoints"] == [[0.0, 0.0, 5.0]]
    assert utm.due(100.0, resolver) == []


def test_a_definition_that_does_not_resolve_names_the_entry():
    utm = Utm(parse_plan({"flight_plans": [{"ids": [1], "at": 0, "waypoints": [["V", "G", "path", "Nope"]]}]},
                         "plan.json"))

    def resolver(definition):
        raise ValueError("no path 'Nope' in V/G")

    with pytest.raises(UtmPlanError, match=r"plan.json: flight_plans\[0\].waypoints\[0\]: no path 'Nope'"):
        utm.due(0.0, resolver)


def test_filed_paths_take_part_in_the_conflict_check():
    utm = Utm(parse_plan({"flight_plans": [{"ids": [1], "at": 0, "waypoints": [[-10, 0, 5], [10, 0, 5]]}],
                          "speed": 2.0}, "plan.json"))
    utm.due(0.0, lambda d: [])
    utm.file(2, [[0, -10, 5], [0, 10, 5]], 0.0)
    [conflict] = utm.conflicts()
    assert conflict.uav_ids == (1, 2)


# --- the file -----------------------------------------------------------------------------------
def test_a_plan_file_with_limits_and_speed(tmp_path):
    path = tmp_path / "plan.json"
    path.write_text(json.dumps({"flight_plans": [{"ids": 1, "at": 5, "waypoints": [[0, 0, 5, 7.5]]}],
                                "conflict": {"distance": 5, "time": 1}, "speed": 1.5}))
    loaded = load_plan(path)
    assert loaded.limits == ConflictLimits(5.0, 1.0) and loaded.speed == 1.5
    [issue] = loaded.issues
    assert issue.ids == (1,) and issue.at == 5.0 and issue.waypoints[0].time == 7.5


@pytest.mark.parametrize("data, where, fix", [
    ([], "the top level must be an object", "flight_plans"),
    ({"flightplans": []}, "flightplans: unknown key", "flight_plans"),
    ({"flight_plans": {}}, "flight_plans: expected a list", "flight_plans"),
    ({"flight_plans": [{"ids": [], "waypoints": [[0, 0, 1]]}]}, r"flight_plans\[0\].ids", "e.g. \\[1\\]"),
    ({"flight_plans": [{"ids": [1], "at": -1, "waypoints": [[0, 0, 1]]}]}, r"flight_plans\[0\].at", "0 or more"),
    ({"flight_plans": [{"ids": [1], "waypoints": []}]}, r"flight_plans\[0\].waypoints", "non-empty list"),
    ({"flight_plans": [{"ids": [1], "waypoints": [[0, 0]]}]}, r"flight_plans\[0\].waypoints\[0\]", r"\[x, y, z\]"),
    ({"flight_plans": [{"ids": [1], "waypoints": [["V", "G", "path"]]}]}, r"waypoints\[0\]",
     "volume, geometry, kind, arg"),
    ({"flight_plans": [{"ids": [1], "when": 3, "waypoints": [[0, 0, 1]]}]}, r"flight_plans\[0\].when",
     "ids, at, waypoints"),
    ({"conflict": {"distance": "far"}}, "conflict.distance", "metres"),
    ({"conflict": {"dist": 3}}, "conflict.dist", "distance"),
    ({"speed": 0}, "speed", "more than 0"),
])
def test_bad_plans_name_the_file_the_json_path_and_the_fix(data, where, fix):
    with pytest.raises(UtmPlanError, match=rf"^plan.json: .*{where}.*{fix}"):
        parse_plan(data, "plan.json")


def test_unreadable_and_broken_files(tmp_path):
    with pytest.raises(UtmPlanError, match="missing.json: cannot read the UTM plan"):
        load_plan(tmp_path / "missing.json")
    broken = tmp_path / "broken.json"
    broken.write_text('{"flight_plans": [}')
    with pytest.raises(UtmPlanError, match=r"broken.json: line 1 column \d+: not JSON"):
        load_plan(broken)


def test_a_mission_names_or_holds_its_plan(tmp_path):
    (tmp_path / "plan.json").write_text(json.dumps({"flight_plans": [{"ids": [1], "waypoints": [[0, 0, 1]]}]}))
    mission_file = tmp_path / "m.json"
    assert mission_plan({"UTM": "plan.json"}, mission_file).issues[0].ids == (1,)
    inline = mission_plan({"UTM": {"flight_plans": [], "speed": 3}}, mission_file)
    assert inline.speed == 3.0 and inline.source.endswith("m.json: UTM")
    assert mission_plan({"State_Machine": []}, mission_file) is None
    with pytest.raises(UtmPlanError, match=r"m.json: UTM: speed"):
        mission_plan({"UTM": {"speed": -1}}, mission_file)


def test_which_missions_use_the_utm():
    assert mission_uses_utm({"State_Machine": [{"parameters": {"path": "from utm"}}]})
    assert mission_uses_utm({"UTM": {"flight_plans": []}, "State_Machine": []})
    # mapping the outcome alone is no use of the UTM: without a plan it never comes
    assert not mission_uses_utm({"State_Machine": [{"outcomes": {"utm_new_flightplan": "x"}}]})
    assert not mission_uses_utm({"State_Machine": [{"parameters": {"path": [{"definition": ["a", "b", "c", 1]}]}}]})


def test_which_plan_a_simulation_flies(tmp_path):
    from magna_gs.utm import choose_plan

    plan_file = tmp_path / "plan.json"
    plan_file.write_text(json.dumps({"flight_plans": [{"ids": [2], "waypoints": [[0, 0, 1]]}]}))
    flies = {"State_Machine": [{"parameters": {"path": "from utm"}}]}
    given, warning = choose_plan(plan_file, flies, "m.json")
    assert given.issues[0].ids == (2,) and warning == ""
    own = {**flies, "UTM": {"flight_plans": []}}
    given, warning = choose_plan(plan_file, own, "m.json")
    assert given.issues[0].ids == (2,) and "m.json: UTM: replaced by the plan given to the run" in warning
    given, warning = choose_plan("", own, "m.json")
    assert given.issues == () and warning == ""
    given, warning = choose_plan("", flies, "m.json")
    assert given.issues == () and warning.startswith("m.json: the mission flies UTM flight plans")
    assert "--utm-plan FILE" in warning and "utm_plan:=FILE" in warning
    assert choose_plan("", {"State_Machine": []}, "m.json")[1] == ""


def _utm_mission(utm):
    return {"Agents_Config": [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]}],
            "UTM": utm,
            "State_Machine": [{"type": "CBState", "state_type": "spawn_agents", "name": "spawn",
                               "parameters": {"initial_poses": [["Ground_Station", "Agents_take_off", "matrix",
                                                                 [0, 0, 0]]]},
                               "outcomes": {"completed": "1_utm"}},
                              {"type": "SimpleActionState", "state_type": "follow_path", "name": "utm", "ids": 1,
                               "parameters": {"path": "from utm", "dynamic": "position"},
                               "outcomes": {"succeeded": "completed", "utm_new_flightplan": "1_utm"}}]}


def test_a_mission_may_carry_its_own_plan_and_a_bad_one_is_refused_when_the_mission_loads(tmp_path):
    from magna_gs.mission.loader import load_mission
    from magna_gs.mission.model import MissionError

    good = tmp_path / "good.json"
    good.write_text(json.dumps(_utm_mission({"flight_plans": [{"ids": [1], "at": 0, "waypoints": [[0, 0, 3]]}]})))
    assert load_mission(good).mission.agent_ids == [1]
    (tmp_path / "plan.json").write_text(json.dumps({"flight_plans": [{"ids": [1], "waypoints": [[0, 0, 3]]}]}))
    named = tmp_path / "named.json"
    named.write_text(json.dumps(_utm_mission("plan.json")))  # a plan file beside the mission
    load_mission(named)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(_utm_mission({"flight_plans": [{"ids": [1], "at": -1, "waypoints": [[0, 0, 3]]}]})))
    with pytest.raises(MissionError) as refused:
        load_mission(bad)
    assert "bad.json: UTM" in str(refused.value) and "flight_plans[0].at" in str(refused.value)
