"""The one search path of worlds and missions: its order, the layouts it knows, and what it says it looked at."""
from pathlib import Path

import pytest

from magna_common.errors import UsageError
from magna_common.search_path import (
    MISSIONS,
    WORLDS,
    candidates,
    check_search_dirs,
    find,
    find_world_file,
    looked_at,
    mission_folders,
    world_candidates,
    world_folders,
)
from magna_common.workspace import find_root

ROOT = find_root()


def touch(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("{}")
    return path


def test_search_folders_come_in_order_and_once(tmp_path, monkeypatch):
    monkeypatch.setenv("MAGNA_WORLDS_PATH", f"{tmp_path / 'env_a'}:{tmp_path / 'env_b'}:{tmp_path / 'given'}")
    monkeypatch.setenv("MAGNA_MISSIONS_PATH", "")
    assert world_folders([tmp_path / "given"]) == [tmp_path / "given", tmp_path / "env_a", tmp_path / "env_b",
                                                   ROOT / "worlds"]
    assert mission_folders() == [ROOT / "missions"]


def test_each_folder_is_looked_at_in_its_lower_case_folder_itself_and_its_ros_magna_folder(tmp_path):
    own = tmp_path / "own"  # laid out like this project: own/missions/
    (own / "missions").mkdir(parents=True)
    corpus = tmp_path / "corpus"  # laid out like ROS-MAGNA's Code/JSONs: corpus/Missions/, absent here
    assert candidates(MISSIONS, "Gym/Two", [own, corpus]) == [
        own / "missions" / "Gym" / "Two.json", own / "Gym" / "Two.json", own / "Missions" / "Gym" / "Two.json",
        corpus / "Gym" / "Two.json", corpus / "Missions" / "Gym" / "Two.json"]
    assert candidates(MISSIONS, "Gym/Two.json", [corpus]) == candidates(MISSIONS, "Gym/Two", [corpus])
    assert find(MISSIONS, "Gym/Two", [own, corpus]) is None
    found = touch(corpus / "Missions" / "Gym" / "Two.json")
    assert find(MISSIONS, "Gym/Two", [own, corpus]) == found
    first = touch(own / "missions" / "Gym" / "Two.json")
    assert find(MISSIONS, "Gym/Two", [own, corpus]) == first


def test_worlds_are_found_by_world_and_subworld(tmp_path):
    world = touch(tmp_path / "Worlds" / "Gym" / "Ring.json")
    assert find_world_file("Gym", "Ring", [tmp_path]) == world
    assert find(WORLDS, "Gym/Ring", [tmp_path]) == world
    assert find_world_file("Gym", "None", [tmp_path]) is None
    assert world_candidates("Gym", "None", [tmp_path]) == (f"{tmp_path}/Gym/None.json, "
                                                           f"{tmp_path}/Worlds/Gym/None.json")
    assert world_candidates("Gym", "None", []) == looked_at([]) == "nowhere (no search path)"


def test_the_project_folders_hold_the_project_worlds_and_missions():
    assert find_world_file("Gym", "Central_Obstacle_Torus", world_folders()) is not None
    assert find(MISSIONS, "Gym/2UAVs_Crossing_ORCA", mission_folders()) is not None


def test_a_search_path_folder_that_is_not_there_is_a_usage_error(tmp_path):
    check_search_dirs([tmp_path])
    with pytest.raises(UsageError, match=f"--search-path {tmp_path / 'nope'}: no such folder"):
        check_search_dirs([tmp_path, tmp_path / "nope"])
