"""magna_worlds.query: the definitions of the real missions resolve; bad ones name the element; random repeats."""
import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world, world_from_data
from magna_worlds.query import PoseQueries, QueryError
from magna_worlds.shapes import contains
from tests.support import CORPUS

CORPUS_WORLDS = CORPUS / "Worlds"
CORPUS_MISSIONS = CORPUS / "Missions"
# The worlds each mission folder is meant for (a mission does not name its world; see the corpus README).
CANDIDATES = {
    "Gym": ["Gym/1Obs_Central_Cylinder.json", "Gym/Empty_4_Cylinders.json"],
    "Delivery": ["Delivery/Delivery.json"],
}


def corpus_missions():
    """The corpus files; without the corpus, one path that does not exist, so the tests using it fail (not skip)."""
    return sorted(CORPUS_MISSIONS.glob("*/*.json")) or [CORPUS_MISSIONS / "missing" / "corpus.json"]


def definitions_of(mission) -> list:
    """Every pose definition of a mission: each `definition`, and each entry of each `initial_poses`."""
    found = []

    def walk(node):
        if isinstance(node, dict):
            for key, value in node.items():
                if key == "definition":
                    found.append(value)
                elif key == "initial_poses":
                    found.extend(value)
                walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)

    walk(mission)
    return found


def resolved_corpus(relative, seed=0):
    return resolve_world(load_world(CORPUS_WORLDS / relative, search_path=[]), seed)


def world_for(path, definitions):
    """The first candidate world holding every volume the mission names."""
    named = {d[0] for d in definitions}
    for relative in CANDIDATES[path.parent.name]:
        resolved = resolved_corpus(relative)
        if named <= set(resolved.volume_frames):
            return resolved
    raise AssertionError(f"{path.name}: no candidate world has the volumes {sorted(named)}")


@pytest.mark.parametrize("path", corpus_missions(), ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_definition_of_every_corpus_mission_resolves(path):
    definitions = definitions_of(json.loads(path.read_text()))
    if path.stem == "only_world":
        assert definitions == []  # it only loads a world
        return
    assert definitions, f"{path.name}: no pose definitions found"
    resolved = world_for(path, definitions)
    queries = PoseQueries(seed=1)
    for definition in definitions:
        assert len(definition) in (4, 5)
        volume, geometry, kind, arg = definition[:4]
        result = queries.resolve([resolved], definition)
        assert result.positions.shape[1] == 3 and result.quaternions.shape == (len(result.positions), 4)
        assert len(result.frames) == len(result.positions) >= 1
        np.testing.assert_allclose(np.linalg.norm(result.quaternions, axis=1), 1.0)
        if geometry == "volume":
            assert kind == "coordinates"
            np.testing.assert_allclose(result.positions, resolved.volume_frames[volume].apply([arg[0]]), atol=1e-12)
            continue
        placed = resolved.geometry(volume, geometry)
        local = placed.frame.inverse().apply(result.positions)
        assert contains(placed.geometry.spec, local, tolerance=1e-9).all(), f"{definition}: outside its geometry"
        if kind == "matrix":
            pose_set = next(s for s in placed.poses() if s.cells is not None)
            row = pose_set.cells[tuple(arg)]
            assert result.frames == [pose_set.frames[row]]
            assert result.frames[0] == f"{placed.base_name}_pos_{arg[0]}_{arg[1]}_{arg[2]}"
            np.testing.assert_allclose(result.positions[0], pose_set.positions[row])
        elif kind == "random":
            assert len(result.positions) == arg
            assert all(name.startswith(f"{placed.base_name}_rnd_") for name in result.frames)


def test_corpus_missions_pick_the_intended_worlds():
    picked = {}
    for path in corpus_missions():
        definitions = definitions_of(json.loads(path.read_text()))
        if definitions:
            picked[path.stem] = world_for(path, definitions).world.source.rsplit("/", 1)[1]
    assert picked["2UAVs_2paths_Central_Cylinder"] == "1Obs_Central_Cylinder.json"
    assert picked["3UAVs_3paths_4_Cylinders"] == "Empty_4_Cylinders.json"  # it names cell [2, 0, 0]
    assert picked["2UAVs_follow_ap"] == "Delivery.json"


def test_matrix_take_off_poses_of_a_mission_by_hand():
    resolved = resolved_corpus("Delivery/Delivery.json")
    queries = PoseQueries()
    first = queries.resolve([resolved], ["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]])
    second = queries.resolve([resolved], ["Ground_Station", "above_take_off", "matrix", [1, 0, 0]])
    np.testing.assert_allclose(first.positions, [[-1.0, 0.0, 0.05]], atol=1e-12)
    np.testing.assert_allclose(second.positions, [[1.0, 0.0, 4.0]], atol=1e-12)
    assert first.frames == ["GS_takeoff_pos_0_0_0"] and second.frames == ["GS_aTO_pos_1_0_0"]
    assert first.new_frames == []  # a matrix pose is already published


# --- a rotated world for the rest ------------------------------------------------------------------------------

ZIGZAG = {"type": "zigzag", "height": 0.5, "spacing": [0, 1], "margins": [0.1, 0.1]}
WORLD = {"scenario": {"world_boundaries": [[-20, 20], [-20, 20], [-20, 20]], "volumes": [
    {"name": "Zone", "prefix": "Z", "origin": [[2, 3, 1], [0.0, 0.0, math.pi / 2]], "permits": "geofence",
     "geometries": [
         {"name": "Ring", "prefix": "r", "shape": "torus", "origin": [[1, 0, 2], [0.3, 0, 0]],
          "dimensions": [4, 6, 2], "poses_sets": [{"type": "matrix", "dimensions": [4, 2, 1]},
                                                  {"type": "random", "quantity": 5}]},
         {"name": "Field", "prefix": "f", "shape": "prism", "origin": [[-5, 0, 0], [0, 0, 0]],
          "dimensions": [2, [[0, 0], [4, 0], [4, 3], [0, 3]]],
          "poses_sets": [ZIGZAG, dict(ZIGZAG, spacing=[0, 0.5], initial_sense="left")]},
     ]},
    {"name": "Other", "prefix": "O", "origin": [[0, 0, 0], [0, 0, 0]], "permits": "geofence",
     "geometries": [{"name": "Box", "prefix": "b", "shape": "cube", "origin": [[0, 0, 0], [0, 0, 0]],
                     "dimensions": [1, 1, 1]}]},
]}}


@pytest.fixture
def world():
    return resolve_world(world_from_data(WORLD, "test.json"), seed=0)


def test_random_draws_new_poses_inside_the_geometry(world):
    queries = PoseQueries(seed=3)
    placed = world.geometry("Zone", "Ring")
    first = queries.resolve([world], ["Zone", "Ring", "random", 7])
    second = queries.resolve([world], ["Zone", "Ring", "random", 7])
    for result in (first, second):
        assert len(result.positions) == 7
        local = placed.frame.inverse().apply(result.positions)
        assert contains(placed.geometry.spec, local).all()
        assert [parent for parent, _, _ in result.new_frames] == ["Z_Ring"] * 7
        for (_, name, frame), position in zip(result.new_frames, result.positions, strict=True):
            np.testing.assert_allclose(placed.frame.apply(frame.translation), position, atol=1e-12)
            assert name in result.frames
    assert not np.allclose(first.positions, second.positions)  # each call draws new ones
    assert set(first.frames).isdisjoint(second.frames)
    # the geometry's own random set is not what a query returns
    assert not np.isclose(first.positions[:, None, :], placed.pose_sets[1].positions[None]).all(axis=2).any()


def test_random_repeats_for_the_same_seed(world):
    def draws(seed):
        queries = PoseQueries(seed=seed)
        return [queries.resolve([world], ["Zone", "Ring", "random", 4]).positions for _ in range(3)]

    for a, b in zip(draws(11), draws(11), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.allclose(draws(11)[0], draws(12)[0])


def test_coordinates_on_the_volume_are_in_the_volume_frame(world):
    result = PoseQueries().resolve([world], ["Zone", "volume", "coordinates", [[1, 0, 0], [0, 0, 0.5]]])
    # the volume sits at (2, 3, 1) turned a quarter about z: its x is the map's y
    np.testing.assert_allclose(result.positions, [[2, 4, 1]], atol=1e-12)
    yaw = Rotation.from_quat(result.quaternions[0]).as_euler("xyz")[2]
    assert yaw == pytest.approx(math.pi / 2 + 0.5)
    assert result.new_frames[0][0] == "Zone" and result.frames[0].startswith("Z_pos_")


def test_coordinates_on_a_geometry_are_in_its_frame_and_may_be_several(world):
    placed = world.geometry("Zone", "Ring")
    poses = [[[0, 0, 0], [0, 0, 0]], [[1, 2, 3], [0, 0, 0, 1]]]
    result = PoseQueries().resolve([world], ["Zone", "Ring", "coordinates", poses])
    np.testing.assert_allclose(result.positions, placed.frame.apply([[0, 0, 0], [1, 2, 3]]), atol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(result.quaternions[1]).as_matrix(), placed.frame.rotation,
                               atol=1e-12)
    assert [parent for parent, _, _ in result.new_frames] == ["Z_Ring", "Z_Ring"]


def test_json_text_arguments_as_ros_sends_them(world):
    queries = PoseQueries()
    as_list = queries.resolve([world], ["Zone", "Ring", "matrix", [3, 1, 0]])
    as_text = queries.resolve([world], ["Zone", "Ring", "matrix", "[3,1,0]"])
    assert as_text.frames == as_list.frames == ["Z_r_pos_3_1_0"]
    np.testing.assert_array_equal(as_text.positions, as_list.positions)
    assert len(queries.resolve([world], ["Zone", "Ring", "random", "3"]).positions) == 3
    text = queries.resolve([world], ["Zone", "volume", "coordinates", "[[1, 0, 0], [0, 0, 0]]"])
    np.testing.assert_allclose(text.positions, [[2, 4, 1]], atol=1e-12)
    with_yaw = queries.resolve([world], ["Zone", "Ring", "matrix", "[0, 0, 0]", "1.57"])  # the spawn yaw is ignored
    assert with_yaw.frames == ["Z_r_pos_0_0_0"]
    assert queries.resolve([world], ["Zone", "Field", "path", "Zigzag_1"]).frames[0].startswith("Z_f_pos_")


def test_path_and_poses(world):
    queries = PoseQueries()
    placed = world.geometry("Zone", "Field")
    first, second = placed.poses()
    for arg in (None, "", "Zigzag", "zigzag", 0):
        np.testing.assert_array_equal(queries.resolve([world], ["Zone", "Field", "path", arg]).positions,
                                      first.positions)
    for arg in ("Zigzag_1", 1):
        assert queries.resolve([world], ["Zone", "Field", "path", arg]).frames == second.frames
    assert len(second) > len(first)
    all_ring = queries.resolve([world], ["Zone", "Ring", "poses", 1])
    np.testing.assert_array_equal(all_ring.positions, world.geometry("Zone", "Ring").pose_sets[1].positions)


@pytest.mark.parametrize("definition, message", [
    (["Nowhere", "Ring", "matrix", [0, 0, 0]], r"^definition\[0\]: no volume named 'Nowhere'; volumes: Other, Zone"),
    (["Zone", "Square", "matrix", [0, 0, 0]],
     r"^definition\[1\]: volume 'Zone' has no geometry 'Square'; it has Ring, Field"),
    (["Zone", "Ring", "spiral", 1], r"^definition\[2\]: unknown kind 'spiral'; use one of matrix, random"),
    (["Zone", "Ring", "matrix", [4, 0, 0]], r"^definition\[3\]: Z_Ring has no cell \[4, 0, 0\]; its cells run up to "
                                            r"\[3, 1, 0\]"),
    (["Zone", "Ring", "matrix", [0, 0]], r"^definition\[3\]: a matrix cell is \[i, j, k\]"),
    (["Zone", "Field", "matrix", [0, 0, 0]], r"^definition\[2\]: Z_Field has no matrix set of poses"),
    (["Other", "Box", "path", "Zigzag"], r"^definition\[2\]: O_Box has no zigzag path"),
    (["Zone", "Field", "path", "Spiral"], r"^definition\[3\]: no path 'Spiral' in Z_Field; it has Zigzag, Zigzag_1"),
    (["Zone", "Field", "path", 2], r"^definition\[3\]: no path 2 in Z_Field"),
    (["Zone", "Ring", "poses", 2], r"^definition\[3\]: Z_Ring has 2 set\(s\) of poses; give an index 0..1, got 2"),
    (["Zone", "Ring", "random", 0], r"^definition\[3\]: random takes how many poses to draw"),
    (["Zone", "Ring", "random", "many"], r"^definition\[3\]: random takes how many poses to draw"),
    (["Zone", "volume", "random", 1], r"^definition\[2\]: a volume itself only takes coordinates"),
    (["Zone", "volume", "coordinates", [[0, 0], [0, 0, 0]]], r"^definition\[3\]: a pose is \[\[x, y, z\]"),
    (["Zone", "volume", "coordinates", [[[0, 0, 0], [0, 0, 0]], [[0, 0, 0], [0, 0]]]], r"^definition\[3\]\[1\]: "),
    (["Zone", "volume", "coordinates", [[0, 0, 0], [0, 0, 0, 0]]], r"^definition\[3\]: a zero quaternion"),
    (["Zone", "Ring", "matrix"], r"^definition: expected \[volume, geometry, kind, arg\]"),
    ("Zone Ring matrix", r"^definition: expected"),
])
def test_errors_name_the_element(world, definition, message):
    with pytest.raises(QueryError, match=message):
        PoseQueries().resolve([world], definition)


def test_definitions_search_several_worlds():
    gym = resolved_corpus("Gym/Empty_4_Cylinders.json")
    delivery_volumes = resolved_corpus("Delivery/Delivery.json")
    queries = PoseQueries()
    result = queries.resolve([delivery_volumes, gym], ["LateralAccissibleZones", "-Y", "random", 2])
    placed = gym.geometry("LateralAccissibleZones", "-Y")
    assert contains(placed.geometry.spec, placed.frame.inverse().apply(result.positions)).all()
    with pytest.raises(QueryError, match="volumes: .*Delivery_1.*LateralAccissibleZones"):
        queries.resolve([delivery_volumes, gym], ["Atlantis", "X", "random", 1])
