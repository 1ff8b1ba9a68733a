"""Bad missions: every problem is reported, at once, as `file: JSON.path: what is wrong; what to do`."""
import json

import pytest

from magna_gs.mission.loader import find_mission, load_mission, resolve_mission_path
from magna_gs.mission.model import MissionError


def problems_of(write_mission, data):
    path = write_mission(data)
    with pytest.raises(MissionError) as error:
        load_mission(path)
    return path, error.value.problems


def test_the_base_mission_is_valid(write_mission, base_mission):
    loaded = load_mission(write_mission(base_mission))
    assert loaded.changes == [] and loaded.warnings == []
    assert [s.label for s in loaded.plan.root.children] == ["spawn", "1_take_off", "1_flight", "1_land"]


def set_in(data, path, value):
    """set_in(data, ["State_Machine", 1, "outcomes", "completed"], v)"""
    *parents, last = path
    for key in parents:
        data = data[key]
    if value is DELETE:
        del data[last]
    else:
        data[last] = value


DELETE = object()

CASES = [  # (where to change, new value, the problem expected: JSON path: message)
    (["State_Machine", 1, "outcomes", "completed"], "1_flihgt",
     "State_Machine[1].outcomes.completed: no state named '1_flihgt'; states here: spawn, 1_take_off, 1_flight, "
     "1_land; or end the mission with completed or failed"),
    (["State_Machine", 2, "outcomes", "collision"], "land",  # the {id}_{name} rule: the state is 1_land
     "State_Machine[2].outcomes.collision: no state named 'land'"),
    (["State_Machine", 0, "type"], "CBstate",
     "State_Machine[0].type: unknown type 'CBstate' (did you mean 'CBState'?)"),
    (["State_Machine", 0, "state_type"], "spawn_uav",
     "State_Machine[0].state_type: unknown state_type 'spawn_uav' (did you mean 'spawn_agents'?)"),
    (["State_Machine", 0, "state_type"], "take_off",
     "State_Machine[0].state_type: 'take_off' is a SimpleActionState type; make this state a SimpleActionState"),
    (["State_Machine", 1, "occurrencies", 0, "parameters", "height"], DELETE,
     "State_Machine[1].occurrencies[0].parameters.height: missing; take_off needs height"),
    (["State_Machine", 1, "occurrencies", 0, "parameters", "height"], -1,
     "State_Machine[1].occurrencies[0].parameters.height: expected a height above the take-off point in m, > 0, "
     "got -1"),
    (["State_Machine", 1, "occurrencies", 0, "ids"], "some",
     "State_Machine[1].occurrencies[0].ids: expected an id (a whole number >= 0), a non-empty list of ids, or "
     "\"all\", got 'some'"),
    (["State_Machine", 1, "occurrencies", 0, "ids_var"], "uavs",
     "State_Machine[1].occurrencies[0].ids_var: unknown ids_var 'uavs'"),
    (["State_Machine", 2, "occurrencies", 1, "parameters", "target_ID"], 7,
     "State_Machine[2].occurrencies[1].parameters.target_ID: no agent 7 in Agents_Config (IDs 1, 2)"),
    (["State_Machine", 2, "occurrencies", 1, "parameters", "target_ID"], 2,
     "State_Machine[2].occurrencies[1].parameters.target_ID: '2_follow' is UAV 2 itself; follow another agent"),
    (["State_Machine", 2, "outcome_cb"], "collision_if_any",
     "State_Machine[2].outcome_cb: unknown outcome_cb 'collision_if_any'; known: collision_if_any_collided"),
    (["State_Machine", 2, "child_termination_cb"], "all_at_once",
     "State_Machine[2].child_termination_cb: unknown child_termination_cb 'all_at_once'; known: all_at_one_collision"),
    (["State_Machine", 2, "occurrencies_outcome_map", "completed"], {"3_path": "succeeded"},
     "State_Machine[2].occurrencies_outcome_map.completed.3_path: no child named '3_path'; children: 1_path, "
     "2_follow (or \"all\")"),
    (["State_Machine", 0, "parameters", "initial_poses", 1], DELETE,
     "State_Machine[0].parameters.initial_poses: 1 pose(s) for 2 agents (1, 2); give one [volume, geometry, kind, "
     "arg] per agent"),
    (["State_Machine", 0, "parameters", "initial_poses", 1, 2], "grid",
     "State_Machine[0].parameters.initial_poses[1][2]: unknown kind 'grid'; use one of matrix, random, coordinates, "
     "path, poses"),
    (["State_Machine", 2, "occurrencies", 0, "parameters", "path", 0], ["CentralZone", "Accessible", "random", 2],
     "State_Machine[2].occurrencies[0].parameters.path[0]: expected {\"definition\": [volume, geometry, kind, arg]}"),
    (["State_Machine", 0, "occurrences"], [],
     "State_Machine[0].occurrences: unknown key (did you mean 'occurrencies'?)"),
    (["State_Machine", 3, "occurrencies"], DELETE,
     "State_Machine[3].occurrencies: missing; a Concurrence lists its states under occurrencies (spelled so)"),
    (["State_Machine", 3, "ids"], DELETE,
     "State_Machine[3].ids: missing; a container is registered as {id}_{name}: give an id (e.g. 1)"),
    (["Agents_Config", 0, "mode"], "simulation",
     "Agents_Config[0].mode: 'simulation' is not one of sitl, hil, real"),
    (["State_Machine", 0, "outcomes", "completed"], "completed",  # no transition leads to 1_take_off any more
     "State_Machine[1]: '1_take_off' is never reached from 'spawn' (the first state of MISSION): no transition "
     "leads to it; add one or remove the state"),
]


# What the original tolerated loads with a warning (test_mission_porting.py); strict mode refuses it.
STRICT_CASES = [
    (["State_Machine", 1, "occurrencies", 0, "ids"], [1, 3],
     "State_Machine[1].occurrencies[0].ids: UAV 3 not in Agents_Config (IDs 1, 2)"),
    (["State_Machine", 2, "occurrencies_outcome_map", "completed"], {"1_path": "succeded"},
     "State_Machine[2].occurrencies_outcome_map.completed: never satisfied: '1_path' never ends with 'succeded'"),
    (["Agents_Config", 1, "ID"], 1,
     "Agents_Config[1].ID: 1 is already the ID of Agents_Config[0]"),
]


@pytest.mark.parametrize("where,value,expected", STRICT_CASES, ids=[str(c[2])[:60] for c in STRICT_CASES])
def test_strict_mode_refuses_what_is_otherwise_a_warning(write_mission, base_mission, where, value, expected):
    set_in(base_mission, where, value)
    path = write_mission(base_mission)
    loaded = load_mission(path)
    assert any(w.startswith(f"{path}: {expected}") for w in loaded.warnings), loaded.warnings
    with pytest.raises(MissionError) as error:
        load_mission(path, strict=True)
    assert any(p.startswith(f"{path}: {expected}") and p.endswith("strict mode turns warnings into errors]")
               for p in error.value.problems), error.value.problems


@pytest.mark.parametrize("where,value,expected", CASES, ids=[str(c[2])[:60] for c in CASES])
def test_each_bad_input_names_the_file_and_the_json_path(write_mission, base_mission, where, value, expected):
    set_in(base_mission, where, value)
    path, problems = problems_of(write_mission, base_mission)
    assert any(p.startswith(f"{path}: {expected}") for p in problems), problems
    assert all(p.startswith(f"{path}: ") for p in problems)


def test_a_cb_state_named_like_an_outcome_is_refused(write_mission, base_mission):
    base_mission["State_Machine"][0]["name"] = "completed"
    path, problems = problems_of(write_mission, base_mission)
    assert f"{path}: State_Machine[0].name: label 'completed' is also an outcome of the container (MISSION); " \
           "rename the state" in problems


def test_every_problem_is_reported_at_once(write_mission, base_mission):
    base_mission["State_Machine"][0]["type"] = "CBstate"
    base_mission["State_Machine"][1]["occurrencies"][0]["parameters"]["height"] = "high"
    base_mission["State_Machine"][2]["occurrencies"][1]["parameters"]["distance"] = 0
    base_mission["Agents_Config"][0]["model"] = "irsi"
    path, problems = problems_of(write_mission, base_mission)
    assert [p.split(": ")[1] for p in problems] == [
        "Agents_Config[0].model", "State_Machine[0].type", "State_Machine[1].occurrencies[0].parameters.height",
        "State_Machine[2].occurrencies[1].parameters.distance"]


def test_bad_parameters_and_structural_problems_come_together(write_mission, base_mission):
    base_mission["State_Machine"][1]["occurrencies"][0]["parameters"]["height"] = "high"
    base_mission["State_Machine"][3]["outcomes"]["completed"] = "finished"
    path, problems = problems_of(write_mission, base_mission)
    assert [p.split(": ")[1] for p in problems] == [
        "State_Machine[1].occurrencies[0].parameters.height", "State_Machine[3].outcomes.completed"]


def test_a_state_that_cannot_be_read_stops_the_structural_checks(write_mission, base_mission):
    base_mission["State_Machine"][1]["type"] = "Concurency"  # 1_take_off is unknown: its siblings' transitions
    path, problems = problems_of(write_mission, base_mission)  # to it would fail for nothing
    assert problems == [f"{path}: State_Machine[1].type: unknown type 'Concurency' (did you mean 'Concurrence'?); use "
                        "one of CBState, SimpleActionState, StateMachine, Concurrence, Sequence"]


def test_structural_problems_are_also_all_reported(write_mission, base_mission):
    base_mission["State_Machine"][1]["occurrencies"][0]["ids_var"] = "wp"
    base_mission["State_Machine"][2]["outcome_cb"] = "nope"
    base_mission["State_Machine"][3]["outcomes"]["completed"] = "finished"
    path, problems = problems_of(write_mission, base_mission)
    assert [p.split(": ")[1] for p in problems] == [
        "State_Machine[1].occurrencies[0].ids_var", "State_Machine[2].outcome_cb",
        "State_Machine[3].outcomes.completed"]


def test_legacy_files_are_named_by_their_own_keys(write_mission, base_mission):
    base_mission["UAVs_Config"] = base_mission.pop("Agents_Config")
    base_mission["UAVs_Config"][1]["uav_manager_on_gs"] = "yes"
    follow = base_mission["State_Machine"][2]["occurrencies"][1]
    follow["state_type"] = "follow_uav_ad"
    follow["parameters"]["time"] = -3
    path, problems = problems_of(write_mission, base_mission)
    assert problems == [
        f"{path}: UAVs_Config[1].uav_manager_on_gs: expected true or false, got 'yes'",
        f"{path}: State_Machine[2].occurrencies[1].parameters.time: expected seconds to follow, >= 0 (0: until "
        "preempted), got -3"]


@pytest.mark.parametrize("text,expected", [
    ("{\"Agents_Config\": [", "not valid JSON: Expecting value at line 1 column 20"),
    ("[]", "the top level must be an object {\"Agents_Config\": [...], \"State_Machine\": [...]}, got a list"),
    ("{\"Agents_Config\": []}", "Agents_Config: no agents; a mission needs at least one"),
    ("{\"Agents_Config\": [], \"UAVs_Config\": [], \"State_Machine\": []}", "UAVs_Config: give the agents once"),
])
def test_files_that_are_not_missions(write_mission, text, expected):
    path = write_mission(text)
    with pytest.raises(MissionError) as error:
        load_mission(path)
    assert error.value.problems[0].startswith(f"{path}: {expected}")


def test_a_missing_file_and_a_missing_name(tmp_path):
    with pytest.raises(MissionError, match=r"nowhere.json: no such file; check the path"):
        load_mission(tmp_path / "nowhere.json")
    with pytest.raises(MissionError) as error:
        find_mission("Gym/Nothing", [tmp_path])
    assert str(error.value).startswith(f"Gym/Nothing: no such mission; looked at {tmp_path}/Gym/Nothing.json, "
                                       f"{tmp_path}/Missions/Gym/Nothing.json.")


def test_missions_are_found_by_name_in_the_search_path(tmp_path, monkeypatch, write_mission, base_mission):
    from tests.support import CORPUS

    corpus = find_mission("Gym/only_world", [tmp_path, CORPUS])  # a ROS-MAGNA tree: <dir>/Missions/...
    assert corpus == CORPUS / "Missions" / "Gym" / "only_world.json"
    mine = write_mission(base_mission, "Test/Mine")
    monkeypatch.setenv("MAGNA_MISSIONS_PATH", str(mine.parents[1]))
    assert find_mission("Test/Mine") == mine
    assert resolve_mission_path("Test/Mine") == mine
    assert resolve_mission_path(str(mine)) == mine
    assert json.loads(mine.read_text()) == base_mission
