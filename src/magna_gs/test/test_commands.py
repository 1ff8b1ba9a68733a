"""Operator commands are checked before anything is sent: unknown UAVs, targets outside the world."""
import math

import numpy as np
import pytest

from magna_gs.commands import CommandRefused, Param, UavStatus, plan_command

BOUNDS = np.array([[-10, 10], [-10, 10], [0, 8]], dtype=float)
UAVS = {1: UavStatus(1, np.array([0.0, 0.0, 3.0]), 0.0, "follow_path", 4, 0.8),
        2: UavStatus(2, np.array([2.0, 0.0, 3.0]), math.pi / 2, "idle", 4, 0.35)}


def plan(intent, action, agent, *params):
    return plan_command(intent, action, agent, params, UAVS, BOUNDS)


def test_take_off_land_move_turn_follow_become_action_goals():
    assert plan("basic_action", "take_off", "1", Param("height", 2.0, unit="m")).orders[0].fields == {"height": 2.0}
    assert [o.uav_id for o in plan("basic_action", "land", "all").orders] == [1, 2]
    move = plan("basic_action", "move", "2", Param("direction", text="up"), Param("distance", 1.5, unit="m"))
    assert move.orders[0].action == "basic_move"
    assert move.orders[0].fields["direction"] == "up" and move.orders[0].fields["value"] == 1.5
    back = plan("basic_action", "move", "1", Param("direction", text="forward"), Param("distance", -2, unit="m"))
    assert back.orders[0].fields["direction"] == "backward" and back.orders[0].fields["value"] == 2
    turn = plan("basic_action", "turn", "1", Param("angle", -90, unit="deg"))
    assert turn.orders[0].fields["move_type"] == "rotation" and turn.orders[0].fields["direction"] == "right"
    follow = plan("basic_action", "follow", "2", Param("target", 1))
    assert follow.orders[0].fields == {"target_id": 1, "distance": 2.0, "duration": 0.0}


def test_moves_that_leave_the_world_are_refused_with_the_reason():
    # UAV 2 faces +y: forward 8 m ends at y = 8 (inside), 12 m at y = 12 (outside)
    plan("basic_action", "move", "2", Param("direction", text="forward"), Param("distance", 8, unit="m"))
    with pytest.raises(CommandRefused, match="would leave the world"):
        plan("basic_action", "move", "2", Param("direction", text="forward"), Param("distance", 12, unit="m"))
    with pytest.raises(CommandRefused, match="above the world's ceiling of 8 m"):
        plan("basic_action", "take_off", "1", Param("height", 6, unit="m"))


@pytest.mark.parametrize(("args", "reason"), [
    (("basic_action", "land", "7"), "UAV 7 is not in this mission"),
    (("basic_action", "land", "drone"), "not a UAV id"),
    (("basic_action", "fly", "1"), "basic action 'fly' is unknown"),
    (("basic_action", "move", "1", Param("direction", text="sideways"), Param("distance", 1, unit="m")),
     "parameter 'direction' is 'sideways'"),
    (("basic_action", "move", "1", Param("direction", text="up")), "parameter 'distance' is missing"),
    (("basic_action", "move", "1", Param("direction", text="up"), Param("distance", 100, unit="cm")),
     "is in 'cm': give it in m"),
    (("basic_action", "follow", "1", Param("target", 1)), "cannot follow itself"),
    (("basic_action", "follow", "1", Param("target", 5)), "UAV 5 to follow is not in this mission"),
    (("algorithms", "set", "1", Param("algorithm", text="magic")), "parameter 'algorithm' is 'magic'"),
    (("mission", "pause", "all"), "give standby, resume, critical"),
    (("parameters", "get", "1", Param("altitude")), "cannot tell 'altitude'"),
    (("chat", "hello", "1"), "intent 'chat' is unknown"),
])
def test_bad_commands_are_refused_naming_what_is_wrong(args, reason):
    with pytest.raises(CommandRefused, match=reason):
        plan(*args)


def test_questions_are_answered_from_what_the_ground_station_knows():
    answer = plan("parameters", "get", "all", Param("battery"), Param("state"))
    values = {a.name: (a.number, a.text, a.unit) for a in answer.answers}
    assert values["uav_1.battery"] == (pytest.approx(80.0), "", "%")
    assert values["uav_2.state"] == (0.0, "idle", "")
    assert "uav_2.battery 35.0%" in answer.message


def test_algorithm_and_mission_commands():
    assert plan("algorithms", "set", "all", Param("algorithm", text="orca3")).algorithm == ("orca3", [1, 2])
    assert plan("mission", "standby", "all").mission == "standby"
    assert plan("mission", "resume", "").mission == "resume"
    assert plan("mission", "critical", "all").mission == "critical"
