"""What the designers share: findings placed on their fields, files found as `magna run` finds them, atomic saves."""
import json
import os

import pytest

from magna_common.search_path import find_world_file
from magna_studio.documents import (
    DesignError,
    Diagnostic,
    DocumentExists,
    current_path,
    finding,
    format_document,
    list_files,
    save_document,
)
from tests.support import CORPUS, ROOT

MISSION = {"Agents_Config": [{"ID": 1}], "State_Machine": [{"type": "CBState", "outcomes": {"completed": "x"}}]}


# --- diagnostics ---------------------------------------------------------------------------------------------------

def test_a_finding_is_placed_on_the_path_it_names_and_keeps_the_commands_line():
    text = "m.json: State_Machine[0].outcomes.completed: no state named 'x'; states here: a: b"
    diagnostic = finding("error", text, "m.json", MISSION)
    assert diagnostic == Diagnostic("error", "State_Machine[0].outcomes.completed",
                                    "no state named 'x'; states here: a: b", text)
    assert diagnostic.to_json() == {"severity": "error", "path": "State_Machine[0].outcomes.completed",
                                    "message": "no state named 'x'; states here: a: b", "line": text}


def test_a_missing_key_is_a_place_but_a_path_through_nothing_is_not():
    missing = finding("error", "m.json: State_Machine[0].state_type: missing; give one", "m.json", MISSION)
    assert missing.path == "State_Machine[0].state_type" and missing.message == "missing; give one"
    nowhere = finding("error", "m.json: State_Machine[4].name: bad", "m.json", MISSION)
    assert nowhere.path == "" and nowhere.message == "State_Machine[4].name: bad"


def test_a_finding_without_a_path_or_about_another_file_is_about_the_whole_file():
    unreadable = finding("error", "m.json: not valid JSON: Expecting value at line 1", "m.json", MISSION)
    assert unreadable.path == "" and unreadable.message == "not valid JSON: Expecting value at line 1"
    other = finding("warning", "w.json: scenario.foo: unknown field,\n  ignored", "m.json", MISSION)
    assert other == Diagnostic("warning", "", "w.json: scenario.foo: unknown field, ignored",
                               "warning: w.json: scenario.foo: unknown field, ignored")


def test_a_path_of_the_file_as_written_maps_to_the_migrated_document():
    renamed = {"scenario.volumes[0].geometries[1].poses_sets": "scenario.volumes[0].geometries[1].divisions",
               "State_Machine[2]": "[2]"}
    assert current_path(renamed, "scenario.volumes[0].geometries[1].divisions[3].type") == \
        "scenario.volumes[0].geometries[1].poses_sets[3].type"
    assert current_path(renamed, "[2].parameters") == "State_Machine[2].parameters"
    assert current_path(renamed, "[20].parameters") == "[20].parameters"
    assert current_path(renamed, "scenario.volumes[0].geometries[1].divisionsX") == \
        "scenario.volumes[0].geometries[1].divisionsX"


# --- saving --------------------------------------------------------------------------------------------------------

def test_a_document_is_written_as_the_originals_files_are_and_reads_back_the_same(tmp_path):
    data = {"scenario": {"world_boundaries": [[-1, 1], [-2, 2], [0, 3]], "volumes": [{"name": "Zoné", "x": {}}]}}
    path = save_document(data, tmp_path / "W.json")
    text = path.read_text(encoding="utf-8")
    assert json.loads(text) == data
    assert text == format_document(data)
    assert '        "world_boundaries": [[-1, 1], [-2, 2], [0, 3]],\n' in text  # a list of numbers on one line
    assert '                "name": "Zoné",\n' in text  # objects one key a line, 4 spaces a level


def test_an_existing_file_is_replaced_only_when_asked(tmp_path):
    path = tmp_path / "M.json"
    path.write_text("the user's own file\n")
    with pytest.raises(DocumentExists, match="already exists"):
        save_document(MISSION, path)
    assert path.read_text() == "the user's own file\n"
    save_document(MISSION, path, overwrite=True)
    assert json.loads(path.read_text()) == MISSION


def test_a_write_that_fails_leaves_the_old_file_whole_and_no_partial_one(tmp_path, monkeypatch):
    path = tmp_path / "M.json"
    path.write_text("the old mission\n")

    def refuse(source, target):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", refuse)  # the last step of an atomic write: the new text is complete by then
    with pytest.raises(DesignError, match="No space left on device"):
        save_document(MISSION, path, overwrite=True)
    assert path.read_text() == "the old mission\n"
    assert [p.name for p in tmp_path.iterdir()] == ["M.json"]


@pytest.mark.parametrize("name, data, message", [
    ("missing/M.json", MISSION, "folder .*missing does not exist"),
    ("M.txt", MISSION, r"name it \*\.json"),
    ("M.json", {"x": float("nan")}, "cannot be written as JSON"),
])
def test_a_document_that_cannot_be_saved_says_why_and_writes_nothing(tmp_path, name, data, message):
    with pytest.raises(DesignError, match=message):
        save_document(data, tmp_path / name)
    assert list(tmp_path.iterdir()) == []


# --- finding files -------------------------------------------------------------------------------------------------

def test_the_projects_worlds_and_missions_are_listed_by_the_names_magna_run_takes():
    worlds = {entry["name"]: entry for entry in list_files("world", [])}
    assert worlds["Gym/Four_Cylinders"] == {"name": "Gym/Four_Cylinders", "origin": "project",
                                            "path": str(ROOT / "worlds" / "Gym" / "Four_Cylinders.json")}
    assert set(worlds) == {f"{p.parent.name}/{p.stem}" for p in (ROOT / "worlds").glob("*/*.json")}
    missions = {entry["name"] for entry in list_files("mission", [])}
    assert missions == {f"{p.parent.name}/{p.stem}" for p in (ROOT / "missions").glob("*/*.json")}


def test_a_search_folder_comes_first_and_other_kinds_of_json_are_left_out():
    worlds = list_files("world", [CORPUS])
    by_name = {entry["name"]: entry for entry in worlds}
    assert by_name["Delivery/Delivery"] == {"name": "Delivery/Delivery", "origin": str(CORPUS),
                                           "path": str((CORPUS / "Worlds" / "Delivery" / "Delivery.json").resolve())}
    assert [e["origin"] for e in worlds].index("project") > [e["origin"] for e in worlds].index(str(CORPUS))
    assert not any(name.startswith("Agent_Configurations/") for name in by_name)  # airframes beside the worlds
    missions = {entry["name"]: entry for entry in list_files("mission", [CORPUS])}
    assert missions["Gym/only_world"]["origin"] == str(CORPUS)
    assert not any(name.startswith(("Agent_Configurations/", "Worlds/")) for name in missions)


def test_a_name_in_two_folders_is_listed_once_as_the_file_magna_run_would_open(tmp_path):
    mine = tmp_path / "worlds" / "Gym"
    mine.mkdir(parents=True)
    (mine / "Four_Cylinders.json").write_text('{"scenario": {"volumes": []}}')
    (mine / "Broken.json").write_text('{"scenario": ')  # listed: opening it says what is wrong
    (mine / "Airframe.json").write_text('{"autopilot": "px4"}')
    entries = [e for e in list_files("world", [tmp_path]) if e["name"] == "Gym/Four_Cylinders"]
    assert entries == [{"name": "Gym/Four_Cylinders", "origin": str(tmp_path),
                        "path": str(mine / "Four_Cylinders.json")}]
    assert find_world_file("Gym", "Four_Cylinders", [tmp_path, ROOT / "worlds"]) == mine / "Four_Cylinders.json"
    names = {e["name"] for e in list_files("world", [tmp_path])}
    assert "Gym/Broken" in names and "Gym/Airframe" not in names


def test_a_search_folder_that_does_not_exist_is_a_design_error(tmp_path):
    with pytest.raises(DesignError, match="no such folder"):
        list_files("mission", [tmp_path / "nowhere"])
