"""A real UAV takes no operator command unless its mission allows it: `"Operator_Commands": {"allow_real": [...]}`
(issue 26, item 10). Questions and mission-wide commands still reach it; sitl and hil UAVs need no permission."""
import numpy as np
import pytest

from magna_gs.commands import CommandRefused, Param, UavStatus, plan_command
from magna_gs.mission.loader import mission_from_data
from magna_gs.mission.model import MissionError
from magna_uav.roles import FLYING_AUTO

UAVS = {1: UavStatus(1, np.array([0.0, 0.0, 3.0]), ual_state=FLYING_AUTO),
        2: UavStatus(2, np.array([2.0, 0.0, 3.0]), ual_state=FLYING_AUTO)}
UP = (Param("direction", text="up"), Param("distance", 1.0, unit="m"))


def mission(base, operator_commands=None, mode_2="real"):
    base["Agents_Config"][1]["mode"] = mode_2
    if operator_commands is not None:
        base["Operator_Commands"] = operator_commands
    return mission_from_data(base, "m.json").mission


def test_a_real_uav_is_locked_unless_the_mission_allows_it(base_mission):
    assert mission(base_mission).operator_locked_ids == {2}
    assert mission(base_mission, {"allow_real": [2]}).operator_locked_ids == set()
    assert mission(base_mission, {"allow_real": "all"}).operator_locked_ids == set()
    assert mission(base_mission, mode_2="hil").operator_locked_ids == set()


def test_commands_for_a_locked_uav_are_refused_whole_with_the_fix(base_mission):
    locked = mission(base_mission).operator_locked_ids
    for agent in ("2", "all"):  # "all" sends nothing, not even to the sitl UAV
        with pytest.raises(CommandRefused, match=r"UAV 2 is a real UAV .* nothing was sent. To allow them, add "
                                                 r"\"Operator_Commands\": \{\"allow_real\": \[2\]\}"):
            plan_command("basic_action", "move", agent, UP, UAVS, locked=locked)
    with pytest.raises(CommandRefused, match="real UAV"):
        plan_command("algorithms", "set", "2", [Param("algorithm", text="simple")], UAVS, locked=locked)
    assert plan_command("basic_action", "move", "1", UP, UAVS, locked=locked).orders[0].uav_id == 1
    assert plan_command("parameters", "get", "2", [Param("position")], UAVS, locked=locked).answers
    assert plan_command("mission", "critical", "all", [], UAVS, locked=locked).mission == "critical"


def test_allowed_real_uavs_take_commands(base_mission):
    allowed = mission(base_mission, {"allow_real": [2]}).operator_locked_ids
    assert [o.uav_id for o in plan_command("basic_action", "land", "all", [], UAVS, locked=allowed).orders] == [1, 2]


@pytest.mark.parametrize(("operator_commands", "problem"), [
    ({"allow_real": [1]}, "Operator_Commands.allow_real[0]: UAV 1 is sitl: the operator commands sitl and hil UAVs "
                          "without permission"),
    ({"allow_real": [7]}, "Operator_Commands.allow_real[0]: UAV 7 is not in Agents_Config"),
    ({"allow_real": "2"}, "Operator_Commands.allow_real: expected a list of UAV ids or \"all\", got a string"),
    ({"allow_reel": [2]}, "Operator_Commands.allow_reel: unknown key (did you mean 'allow_real'?)"),
    ([2], "Operator_Commands: expected {\"allow_real\": [ids of real UAVs] or \"all\"}, got a list"),
])
def test_a_bad_permission_is_a_located_problem(base_mission, operator_commands, problem):
    with pytest.raises(MissionError) as error:
        mission(base_mission, operator_commands)
    assert any(p.startswith(f"m.json: {problem}") for p in error.value.problems), error.value.problems
