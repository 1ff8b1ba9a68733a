"""check_against_world: every place a mission names is found in the world, at its JSON path; nothing spawns."""
import pytest

from magna_gs.mission.loader import mission_from_data
from magna_gs.mission.world_check import check_against_world, check_in_world, pose_definitions
from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world
from tests.support import CORPUS

WORLD = CORPUS / "Worlds" / "Gym" / "1Obs_Central_Cylinder.json"  # boundaries -9..9 m on every axis


@pytest.fixture(scope="module")
def gym():
    return resolve_world(load_world(WORLD, search_path=[]), 0)


def check(data, world):
    return check_against_world(mission_from_data(data, "m.json").mission, world)


def test_the_base_mission_resolves_and_its_definitions_are_listed(base_mission, gym):
    mission = mission_from_data(base_mission, "m.json").mission
    assert check_against_world(mission, gym) == []
    assert [d.json_path for d in pose_definitions(mission)] == [
        "State_Machine[0].parameters.initial_poses[0]", "State_Machine[0].parameters.initial_poses[1]",
        "State_Machine[2].occurrencies[0].parameters.path[0].definition"]


def test_a_geometry_the_world_lacks(base_mission, gym):
    base_mission["State_Machine"][2]["occurrencies"][0]["parameters"]["path"][0]["definition"][1] = "Acessible"
    assert check(base_mission, gym) == [
        "m.json: State_Machine[2].occurrencies[0].parameters.path[0].definition[1]: volume 'CentralZone' has no "
        "geometry 'Acessible'; it has Accessible, Obstacles (or use \"volume\")"]


def test_a_volume_and_a_matrix_cell_the_world_lacks_are_both_reported(base_mission, gym):
    poses = base_mission["State_Machine"][0]["parameters"]["initial_poses"]
    poses[0][0] = "Groundstation"
    poses[1][3] = [0, 0, 4]
    problems = check(base_mission, gym)
    assert problems[0].startswith("m.json: State_Machine[0].parameters.initial_poses[0][0]: no volume named "
                                  "'Groundstation'; volumes: CentralZone, Ground_Station")
    assert problems[1].startswith("m.json: State_Machine[0].parameters.initial_poses[1][3]: GS4_Agents_take_off has "
                                  "no cell [0, 0, 4]")


def test_agents_spawned_on_top_of_each_other(base_mission, gym):
    base_mission["State_Machine"][0]["parameters"]["initial_poses"][1][3] = [0, 0, 0]
    assert check(base_mission, gym) == [
        "m.json: State_Machine[0].parameters.initial_poses[1]: agents 1 and 2 would spawn 0.00 m apart, closer than "
        "their safety radii (0.3 + 0.3 m); give them other places"]


def test_a_path_point_outside_the_world_boundaries_warns_and_strict_refuses_it(base_mission, gym):
    base_mission["State_Machine"][2]["occurrencies"][0]["parameters"]["path"].append(
        {"definition": ["Ground_Station", "volume", "coordinates", [[0, 12, 3], [0, 0, 0]]]})
    where = ("m.json: State_Machine[2].occurrencies[0].parameters.path[1].definition: [Ground_Station, volume, "
             "coordinates, [[0, 12, 3], [0, 0, 0]]] gives a pose at (0.00, 12.00, 3.00), outside the world "
             "boundaries x -9..9 y -9..9 z -9..9 m")
    mission = mission_from_data(base_mission, "m.json").mission
    found = check_in_world(mission, gym)  # the original loaded it; flying there ended the UAV's role
    assert found.problems == [] and len(found.warnings) == 1
    assert found.warnings[0].startswith(where + "; loaded as the original did") and "'aborted'" in found.warnings[0]
    assert check_in_world(mission, gym, strict=True).problems == [
        where + "; UAVs may not fly there (refused with --strict)"]
    assert check(base_mission, gym) == check_in_world(mission, gym, strict=True).problems


EXTRA_PART = [{"name": "Extra", "prefix": "EX", "origin": [[5, 5, 0], [0, 0, 0]], "permits": "geofence",
               "geometries": [{"name": "Pad", "prefix": "pad", "shape": "cube", "id": 0,
                               "origin": [[0, 0, 2], [0, 0, 0]], "dimensions": [1, 1, 1], "color": [0, 0, 0],
                               "alpha": 0.5}]}]


def test_world_parts_the_mission_adds_inline_count(base_mission, gym):
    path = base_mission["State_Machine"][2]["occurrencies"][0]["parameters"]["path"]
    path.append({"definition": ["Extra", "Pad", "random", 1]})
    assert check(base_mission, gym)[0].startswith(
        "m.json: State_Machine[2].occurrencies[0].parameters.path[1].definition[0]: no volume named 'Extra'")
    base_mission["State_Machine"].insert(0, {
        "type": "CBState", "state_type": "world_config", "name": "add extra",
        "parameters": {"action": "add", "id": "extra", "world_part_def": EXTRA_PART},
        "outcomes": {"completed": "spawn"}})
    assert check(base_mission, gym) == []
    bad_part = [dict(EXTRA_PART[0], geometries=[dict(EXTRA_PART[0]["geometries"][0], shape="cone")])]
    base_mission["State_Machine"][0]["parameters"]["world_part_def"] = bad_part
    problems = check(base_mission, gym)
    assert problems[0].startswith("m.json: State_Machine[0].parameters.world_part_def: "
                                  "scenario.volumes[0].geometries[0].shape: unknown shape 'cone'")
