"""Operator commands are checked before anything is sent: unknown UAVs, targets outside the world, UAVs whose
UAL state does not let them do it; an accepted command's message says what will happen."""
import dataclasses
import math

import numpy as np
import pytest

from magna_gs.commands import CommandRefused, Param, UavStatus, plan_command
from magna_uav.roles import (
    FLYING_AUTO,
    FLYING_MANUAL,
    LANDED_ARMED,
    LANDED_DISARMED,
    LANDING,
    TAKING_OFF,
    UNINITIALIZED,
)

BOUNDS = np.array([[-10, 10], [-10, 10], [0, 8]], dtype=float)
UAVS = {1: UavStatus(1, np.array([0.0, 0.0, 3.0]), 0.0, "follow_path", FLYING_AUTO, 0.8),
        2: UavStatus(2, np.array([2.0, 0.0, 3.0]), math.pi / 2, "idle", FLYING_AUTO, 0.35)}
GROUND = {1: UavStatus(1, np.array([0.0, 0.0, 0.0]), 0.0, "idle", LANDED_ARMED, 0.9),
          2: UavStatus(2, np.array([2.0, 0.0, 0.0]), 0.0, "idle", LANDED_ARMED, 0.9)}
UP = (Param("direction", text="up"), Param("distance", 2.0, unit="m"))


def plan(intent, action, agent, *params):
    return plan_command(intent, action, agent, params, UAVS, BOUNDS)


def on_ground(intent, action, agent, *params):
    return plan_command(intent, action, agent, params, GROUND, BOUNDS)


def message(action, agent, *params, uavs=UAVS):
    return plan_command("basic_action", action, agent, params, uavs, BOUNDS).message


def refusal(action, agent, *params, uavs=UAVS):
    with pytest.raises(CommandRefused) as refused:
        plan_command("basic_action", action, agent, params, uavs, BOUNDS)
    return str(refused.value)


def with_states(**states):
    """UAVS with the UAL states given as uav_1=LANDING, ..."""
    return {i: dataclasses.replace(uav, ual_state=states.get(f"uav_{i}", uav.ual_state)) for i, uav in UAVS.items()}


def test_take_off_land_move_turn_follow_become_action_goals():
    assert on_ground("basic_action", "take_off", "1", Param("height", 2.0, unit="m")).orders[0].fields == {
        "height": 2.0}
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
        on_ground("basic_action", "take_off", "1", Param("height", 9, unit="m"))


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


def test_accepted_commands_say_what_will_happen():
    # UAV 1 at (0, 0, 3) heading +x; UAV 2 at (2, 0, 3) heading +y
    assert message("move", "2", Param("direction", text="up"), Param("distance", 4, unit="m")) == (
        "UAV 2 climbing to 7 m")
    assert message("move", "1", Param("direction", text="down"), Param("distance", 1.5, unit="m")) == (
        "UAV 1 descending to 1.5 m")
    assert message("move", "1", Param("direction", text="z"), Param("distance", -1, unit="m")) == (
        "UAV 1 descending to 2 m")
    assert message("move", "1", Param("direction", text="forward"), Param("distance", 3, unit="m")) == (
        "UAV 1 moving 3 m forward to (3, 0, 3)")
    assert message("move", "2", Param("direction", text="forward"), Param("distance", 3, unit="m")) == (
        "UAV 2 moving 3 m forward to (2, 3, 3)")  # along its heading
    assert message("move", "1", Param("direction", text="forward"), Param("distance", -2, unit="m")) == (
        "UAV 1 moving 2 m backward to (-2, 0, 3)")
    assert message("move", "2", Param("direction", text="left"), Param("distance", 1.25, unit="m")) == (
        "UAV 2 moving 1.25 m left to (0.8, 0, 3)")
    # a float32 from the wire is said as the operator gave it, never "2.200000047"
    assert message("move", "1", Param("direction", text="right"), Param("distance", float(np.float32(2.2)),
                                                                          unit="m")) == (
        "UAV 1 moving 2.2 m right to (0, -2.2, 3)")
    assert message("take_off", "1", Param("height", 3, unit="m"), uavs=GROUND) == "UAV 1 taking off to 3 m"
    assert message("take_off", "all", uavs=GROUND) == "UAVs 1, 2 taking off to 2 m"
    assert message("land", "1") == "UAV 1 landing"
    assert message("land", "all") == "UAVs 1, 2 landing"
    assert message("turn", "2", Param("angle", 90, unit="deg"), Param("direction", text="right")) == (
        "UAV 2 turning 90 degrees right")
    assert message("turn", "1", Param("angle", -45, unit="deg")) == "UAV 1 turning 45 degrees right"
    assert message("follow", "2", Param("target", 1), Param("distance", 3, unit="m")) == "UAV 2 following UAV 1 at 3 m"
    assert message("follow", "2", Param("target", text="uav_1")) == "UAV 2 following UAV 1 at 2 m"
    # "all": one sentence per different thing done
    assert message("move", "all", *UP) == "UAVs 1, 2 climbing to 5 m"
    assert message("move", "all", Param("direction", text="forward"), Param("distance", 1, unit="m")) == (
        "UAV 1 moving 1 m forward to (1, 0, 3); UAV 2 moving 1 m forward to (2, 1, 3)")
    assert plan("algorithms", "set", "1", Param("algorithm", text="orca3d")).message == "algorithm orca3d for UAV 1"
    assert plan("mission", "standby", "all").message == "mission paused"
    assert plan("mission", "resume", "all").message == "mission resumed"
    orders = plan("basic_action", "move", "2", *UP).orders
    assert [(o.sentence, o.verb) for o in orders] == [("UAV 2 climbing to 5 m", "move")]


@pytest.mark.parametrize(("action", "params", "state", "reason"), [
    ("move", UP, LANDING, "UAV 1 is landing, so it cannot move"),
    ("move", UP, LANDED_ARMED, "UAV 1 is on the ground, so it cannot move: take off first"),
    ("turn", (Param("angle", 90, unit="deg"),), LANDED_DISARMED,
     "UAV 1 is on the ground, so it cannot turn: take off first"),
    ("follow", (Param("target", 2),), TAKING_OFF, "UAV 1 is taking off, so it cannot follow: wait until it is up"),
    ("move", UP, FLYING_MANUAL, "UAV 1 is flown by its pilot, so it cannot move"),
    ("move", UP, UNINITIALIZED, "UAV 1's state is not known yet, so it cannot move"),
    ("move", UP, 9, "UAV 1 reports UAL state 9, so it cannot move"),
    ("take_off", (), FLYING_AUTO, "UAV 1 is already flying, so it cannot take off"),
    ("take_off", (), TAKING_OFF, "UAV 1 is already taking off, so it cannot take off"),
    ("take_off", (), LANDING, "UAV 1 is landing, so it cannot take off"),
    ("take_off", (), UNINITIALIZED, "UAV 1's state is not known yet, so it cannot take off"),
    ("take_off", (), LANDED_DISARMED, "UAV 1 is on the ground disarmed, so it cannot take off: arm it first"),
    ("land", (), LANDING, "UAV 1 is already landing, so it cannot land"),
    ("land", (), LANDED_ARMED, "UAV 1 is already on the ground, so it cannot land"),
    ("land", (), TAKING_OFF, "UAV 1 is taking off, so it cannot land: wait until it is up"),
])
def test_a_uav_whose_ual_state_does_not_allow_the_command_is_refused_saying_why(action, params, state, reason):
    assert refusal(action, "1", *params, uavs=with_states(uav_1=state)) == reason


def test_a_uav_whose_ual_arms_it_takes_off_from_landed_disarmed():
    disarmed = {1: dataclasses.replace(GROUND[1], ual_state=LANDED_DISARMED, arms_on_take_off=True)}
    assert message("take_off", "1", uavs=disarmed) == "UAV 1 taking off to 2 m"


def test_all_is_refused_whole_naming_each_uav_that_cannot():
    assert refusal("move", "all", *UP, uavs=with_states(uav_1=LANDING, uav_2=LANDED_ARMED)) == (
        "UAV 1 is landing and UAV 2 is on the ground, so they cannot move; nothing was sent")
    assert refusal("move", "all", *UP, uavs=with_states(uav_2=LANDED_ARMED)) == (
        "UAV 2 is on the ground, so it cannot move: take off first; nothing was sent")
    assert refusal("take_off", "all", uavs={**GROUND, 2: UAVS[2]}) == (
        "UAV 2 is already flying, so it cannot take off; nothing was sent")


def test_the_state_is_checked_after_the_command_is_known_and_before_its_parameters():
    landing = with_states(uav_1=LANDING)
    assert "basic action 'fly' is unknown" in refusal("fly", "1", uavs=landing)
    assert refusal("move", "1", Param("direction", text="sideways"), uavs=landing) == (
        "UAV 1 is landing, so it cannot move")
    assert "UAV 7 is not in this mission" in refusal("land", "7", uavs=landing)


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
