"""The mission designer: missions of both schemas open migrated, checks are `magna mission check`'s on the fields
they name (against a world too), the graph is `magna mission draw`'s with each state findable, and the forms
cover every state type the parser reads."""
import copy
import json
import re
import subprocess

import pytest

from magna_gs.mission.loader import mission_from_data
from magna_gs.mission.model import ACTION_TYPES, CALLBACK_TYPES, CONTAINER_TYPES, LEAF_TYPES, MissionError
from magna_studio.documents import DesignError, save_document
from magna_studio.mission_design import check_mission, new_mission, open_mission, state_types
from magna_studio.world_design import open_world, pose_choices
from tests.support import CORPUS, ROOT

LEGACY_STATE_TYPES = ("new_world", "spawn_uavs", "follow_uav_ad", "follow_uav_ap")


def magna_mission(*args):
    return subprocess.run([str(ROOT / "magna"), "mission", *args], capture_output=True, text=True, timeout=120)


def state_type_names(data):
    found = []

    def walk(nodes):
        for node in nodes:
            found.append(node.get("state_type"))
            walk(node.get("occurrencies", []))

    walk(data["State_Machine"])
    return found


@pytest.mark.parametrize("name, agents_key", [("Delivery/2UAVs_follow_ap", "UAVs_Config"),
                                              ("Gym/2UAVs_2paths_Central_Cylinder", "Agents_Config")])
def test_the_originals_missions_of_both_schemas_open_migrated_with_the_commands_findings(name, agents_key):
    file = CORPUS / "Missions" / f"{name}.json"
    assert agents_key in json.loads(file.read_text())
    opened = open_mission(name, [CORPUS])
    assert opened["path"] == str(file) and opened["name"] == name
    assert opened["schema"] == "legacy" and opened["changes"]
    assert "UAVs_Config" not in opened["data"] and opened["data"]["Agents_Config"]
    assert not set(LEGACY_STATE_TYPES) & set(state_type_names(opened["data"]))
    mission_from_data(opened["data"], "migrated", strict=False)  # the migrated document loads on its own
    assert ("UAVs_Config -> Agents_Config" in opened["changes"]) == (agents_key == "UAVs_Config")

    done = magna_mission("check", name, "--search-path", str(CORPUS))
    assert done.returncode == 0, done.stderr
    assert [f"magna mission: {d['line']}" for d in opened["diagnostics"]] == done.stderr.splitlines()
    assert f"schema      legacy parts migrated to the current schema: {len(opened['changes'])} change(s)" \
        in done.stdout
    assert all(f"  {change}" in done.stdout for change in opened["changes"])
    assert all(d["severity"] == "warning" and d["path"] for d in opened["diagnostics"])
    assert opened["graph_svg"].lstrip().startswith("<?xml") and opened["states"][0]["path"] == "/MISSION"


def test_a_project_mission_is_of_the_current_schema():
    opened = open_mission("Gym/Safe_Stop", [])
    assert opened["schema"] == "current" and opened["changes"] == []
    assert opened["data"] == json.loads((ROOT / "missions" / "Gym" / "Safe_Stop.json").read_text())


def test_findings_of_a_legacy_file_are_placed_on_the_migrated_fields(tmp_path):
    states = [  # the January 2019 schema: the file is the state list alone
        {"type": "CBState", "name": "new_world", "outcomes": {"completed": "wait"}},
        {"type": "CBState", "state_type": "wait", "name": "wait", "parameters": {"time": -1},
         "outcomes": {"completed": "nowhere"}},
    ]
    file = tmp_path / "Old.json"
    file.write_text(json.dumps(states))
    opened = open_mission(str(file), [])
    assert opened["schema"] == "legacy" and "[1].parameters.time -> duration" in opened["changes"]
    assert opened["data"]["State_Machine"][1]["parameters"] == {"duration": -1, "exit_type": "time"}
    assert opened["graph_svg"] is None and opened["states"] == []
    by_path = {d["path"]: d for d in opened["diagnostics"]}
    assert set(by_path) == {"State_Machine[1].parameters.duration", "State_Machine[1].outcomes.completed"}
    assert by_path["State_Machine[1].parameters.duration"]["line"] == \
        f"{file}: [1].parameters.time: expected seconds to wait, >= 0, got -1"  # the command's, of the file
    done = magna_mission("check", str(file))
    assert done.returncode == 2
    assert done.stderr.splitlines() == [f"magna mission: {d['line']}" for d in opened["diagnostics"]]


def test_a_broken_transition_is_an_error_on_it_and_mending_it_brings_the_graph_back():
    data = new_mission()
    data["State_Machine"][0]["outcomes"]["completed"] = "1_take_off"
    found = check_mission(data, "New.json", None, [])
    [error] = found["diagnostics"]
    assert error["severity"] == "error" and error["path"] == "State_Machine[0].outcomes.completed"
    assert error["message"].startswith("no state named '1_take_off'")
    assert found["graph_svg"] is None and found["states"] == []
    data["State_Machine"][0]["outcomes"]["completed"] = "completed"
    mended = check_mission(data, "New.json", None, [])
    assert mended["diagnostics"] == [] and "data-state=\"/MISSION/new_world\"" in mended["graph_svg"]


def flight(world_choices):
    """new_mission plus a spawn on the first take-off pad the world offers, a take-off, a landing."""
    pad = next(c for c in world_choices if "matrix" in c["kinds"] and c["geometry"] == "Agents_take_off")
    mission = new_mission()
    machine = mission["State_Machine"]
    machine[0]["outcomes"] = {"completed": "spawn", "failed": "failed"}
    on_failure = {"collision": "failed", "low_battery": "failed", "GS_critical_event": "failed",
                  "utm_new_flightplan": "failed", "aborted": "failed"}
    machine += [
        {"type": "CBState", "state_type": "spawn_agents", "name": "spawn",
         "parameters": {"initial_poses": [[pad["volume"], pad["geometry"], "matrix", pad["matrix_cells"][0]]]},
         "outcomes": {"completed": "1_take_off", "failed": "failed"}},
        {"type": "SimpleActionState", "state_type": "take_off", "name": "take_off", "ids": 1,
         "parameters": {"height": 2.0}, "outcomes": {"succeeded": "1_land", **on_failure}},
        {"type": "SimpleActionState", "state_type": "land", "name": "land", "ids": 1, "parameters": {},
         "outcomes": {"succeeded": "completed", **on_failure}},
    ]
    return mission


def test_a_mission_built_from_new_mission_passes_the_real_check_in_its_world(tmp_path):
    world = open_world("Gym/Four_Cylinders", [])
    mission = flight(pose_choices(world["data"], world["path"], []))
    file = save_document(mission, tmp_path / "Flight.json")
    found = check_mission(mission, str(file), {"data": world["data"], "source": world["path"]}, [])
    assert found["diagnostics"] == []
    assert [(s["path"], s["type"]) for s in found["states"]] == [
        ("/MISSION", "StateMachine"), ("/MISSION/new_world", "world_config"), ("/MISSION/spawn", "spawn_agents"),
        ("/MISSION/1_take_off", "take_off"), ("/MISSION/1_land", "land")]
    done = magna_mission("check", str(file), "--world", "Gym/Four_Cylinders", "--strict")
    assert done.returncode == 0, done.stderr
    assert done.stderr == "" and "world       " in done.stdout and "1 pose definition(s) resolve" in done.stdout


def test_a_place_the_world_does_not_have_is_an_error_on_the_definition_with_the_commands_line(tmp_path):
    world = open_world("Gym/Four_Cylinders", [])
    mission = flight(pose_choices(world["data"], world["path"], []))
    mission["State_Machine"][1]["parameters"]["initial_poses"][0][3] = [9, 0, 0]
    file = save_document(mission, tmp_path / "Far.json")
    found = check_mission(mission, str(file), {"data": world["data"], "source": world["path"]}, [])
    [error] = found["diagnostics"]
    assert error["path"] == "State_Machine[1].parameters.initial_poses[0][3]"
    assert "has no cell [9, 0, 0]" in error["message"]
    assert found["graph_svg"] is not None  # the structure is sound: the graph stays
    done = magna_mission("check", str(file), "--world", str(ROOT / "worlds" / "Gym" / "Four_Cylinders.json"))
    assert done.returncode == 2
    assert done.stderr.splitlines() == [f"magna mission: {error['line']}"]


def test_a_world_that_does_not_load_is_one_error_about_the_world():
    world = open_world("Gym/Four_Cylinders", [])
    broken = copy.deepcopy(world["data"])
    broken["scenario"]["volumes"][0]["geometries"][0]["shape"] = "cone"
    found = check_mission(new_mission(), "New.json", {"data": broken, "source": "Broken.json"}, [])
    [error] = found["diagnostics"]
    assert error["path"] == "" and error["line"].startswith("Broken.json: scenario.volumes[0].geometries[0].shape: ")


def test_the_graph_is_the_commands_drawing_with_every_state_marked_by_its_path(tmp_path):
    file = ROOT / "missions" / "Gym" / "Safe_Stop.json"
    opened = open_mission(str(file), [])
    svg = opened["graph_svg"]
    marked = set(re.findall(r'data-state="([^"]*)"', svg))
    assert marked == {state["path"] for state in opened["states"]}
    assert "/MISSION/1_take_off/1_take_off" in marked  # a leaf inside a container, as introspection names it
    assert re.search(r'<g id="node\d+" class="node" data-state="/MISSION/1_take_off/2_take_off">\s*'
                     r'<title>/MISSION/1_take_off/2_take_off</title>', svg)
    assert re.search(r'class="cluster" data-state="/MISSION/1_take_off">', svg)
    assert 'data-outcome="/MISSION/1_take_off/:collision"' in svg
    drawn = tmp_path / "Safe_Stop.svg"
    done = magna_mission("draw", str(file), "-o", str(drawn))
    assert done.returncode == 0, done.stderr
    assert re.sub(r' data-(state|outcome)="[^"]*"', "", svg) == drawn.read_text()


def test_a_mission_that_cannot_be_opened_is_a_design_error_naming_the_file(tmp_path):
    with pytest.raises(DesignError, match="Gym/Nowhere: no such mission; looked at"):
        open_mission("Gym/Nowhere", [])
    broken = tmp_path / "Broken.json"
    broken.write_text('{"State_Machine": [')
    with pytest.raises(DesignError, match=f"{broken}: not valid JSON"):
        open_mission(str(broken), [])
    with pytest.raises(DesignError, match="no such folder"):
        open_mission("Gym/Safe_Stop", [tmp_path / "nowhere"])


def test_a_new_mission_passes_the_strict_check():
    loaded = mission_from_data(new_mission(), "New.json", strict=True)
    assert loaded.changes == [] and loaded.warnings == []


# --- the forms -----------------------------------------------------------------------------------------------------

def test_the_forms_cover_every_state_type_and_container_the_parser_accepts():
    forms = state_types()
    assert set(forms["states"]) == set(ACTION_TYPES) | set(CALLBACK_TYPES)
    assert {leaf: entry["state_types"] for leaf, entry in forms["leaf_types"].items()} == \
        {"SimpleActionState": list(ACTION_TYPES), "CBState": list(CALLBACK_TYPES)}
    assert set(forms["leaf_types"]) == set(LEAF_TYPES) and set(forms["containers"]) == set(CONTAINER_TYPES)
    assert forms["states"]["save_csv"]["leaf_types"] == ["CBState", "SimpleActionState"]
    json.dumps(forms)


def single_state(leaf, state_type, parameters):
    node = {"type": leaf, "state_type": state_type, "name": "s", "parameters": parameters, "ids": 1}
    return {"Agents_Config": [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]}],
            "State_Machine": [node]}


def every_form():
    forms = state_types()["states"]
    return [(leaf, state_type, forms[state_type]["parameters"])
            for state_type in forms for leaf in forms[state_type]["leaf_types"]]


@pytest.mark.parametrize("leaf, state_type, fields", every_form(), ids=lambda value: str(value)[:20])
def test_each_forms_fields_are_the_parameters_the_parser_reads(leaf, state_type, fields):
    """Filled with its examples, a form makes parameters the parser reads without a problem or an unread key; with
    a required field left out, the parser asks for that field; an optional one left out, it does not."""
    parameters = {field["name"]: field["example"] for field in fields if field["example"] is not None}
    loaded = mission_from_data(single_state(leaf, state_type, parameters), "Form.json", validate=False)
    assert loaded.warnings == []
    assert {field["kind"] for field in fields} <= {"number", "text", "bool", "choice", "pose", "uav", "list"}
    required = {field["name"]: field["example"] for field in fields if field["required"]}
    for field in fields:
        assert field["example"] is not None or not field["required"]
        if field["choices"]:
            assert field["example"] in field["choices"] or field["example"] is None
        # the others required only: a legacy wait with a duration gets its exit_type
        cases = [{k: v for k, v in required.items() if k != field["name"]}] if field["required"] else []
        cases += [{**required, key: value} for key, values in field.get("required_when", {}).items()
                  for value in values]
        for without in cases:
            with pytest.raises(MissionError) as refused:
                mission_from_data(single_state(leaf, state_type, without), "Form.json", validate=False)
            assert any(p.startswith(f"Form.json: State_Machine[0].parameters.{field['name']}: missing")
                       for p in refused.value.problems)
        if not field["required"] and "required_when" not in field:  # optional: the parser takes its default
            without = {k: v for k, v in parameters.items() if k != field["name"]}
            mission_from_data(single_state(leaf, state_type, without), "Form.json", validate=False)

