"""magna_worlds.registry: world parts added and deleted by id, queried together, recorded; atomic JSON writes."""
import json

import numpy as np
import pytest

from magna_worlds.errors import WorldError
from magna_worlds.query import QueryError
from magna_worlds.registry import WorldRegistry
from tests.support import CORPUS

CORPUS_WORLDS = CORPUS / "Worlds"
INLINE = [{"name": "Pad", "prefix": "PD", "origin": [[10, 0, 0], [0, 0, 0]], "permits": "geofence",
           "geometries": [{"name": "Zone", "prefix": "z", "shape": "cube", "origin": [[0, 0, 1], [0, 0, 0]],
                           "dimensions": [2, 2, 2],
                           "poses_sets": [{"type": "matrix", "dimensions": [2, 2, 1]}]}]}]


@pytest.fixture
def registry():
    return WorldRegistry(seed=4, search_path=[CORPUS_WORLDS])


def children(registry):
    return [child for _, child, _ in registry.static_transforms()]


def test_add_file_named_and_inline_then_query_across_parts(registry):
    gym = registry.add_file("gym", CORPUS_WORLDS / "Gym" / "1Obs_Central_Cylinder.json")
    inline = registry.add_inline("pad", json.dumps(INLINE))
    assert list(registry.parts) == ["gym", "pad"]
    assert set(gym.volume_frames) == {"Ground_Station", "CentralZone"} and set(inline.volume_frames) == {"Pad"}
    take_off = registry.resolve(["Ground_Station", "Agents_take_off", "matrix", [1, 0, 0]])
    np.testing.assert_allclose(take_off.positions, [[2.5, 0, 0.05]], atol=1e-12)  # 10 m cube, 2 cells
    pad = registry.resolve(["Pad", "Zone", "matrix", "[1, 1, 0]"])
    np.testing.assert_allclose(pad.positions, [[10.5, 0.5, 1.0]], atol=1e-12)
    names = children(registry)
    assert len(names) == len(set(names))
    assert {"Ground_Station", "CentralZone", "GS4_takeoff_pos_1_0_0", "CZ_Obs_obs_0", "Pad", "PD_Zone",
            "PD_z_pos_1_1_0"} <= set(names)


def test_add_named_looks_in_the_search_path(registry):
    part = registry.add_named("delivery", "Delivery", "Delivery")
    assert part.world.source == str(CORPUS_WORLDS / "Delivery" / "Delivery.json")
    with pytest.raises(WorldError) as err:
        registry.add_named("nothing", "Delivery", "Nowhere")
    assert str(err.value).startswith("Delivery/Nowhere: no such world; looked at ")
    assert str(CORPUS_WORLDS / "Delivery" / "Nowhere.json") in str(err.value)
    assert "nothing" not in registry.parts


def test_duplicate_part_ids_are_refused(registry):
    registry.add_file("w", CORPUS_WORLDS / "Gym" / "Empty.json")
    before = children(registry)
    with pytest.raises(WorldError, match=r"id: a part 'w' exists already"):
        registry.add_inline("w", json.dumps(INLINE))
    assert children(registry) == before and list(registry.parts) == ["w"]
    with pytest.raises(WorldError, match=r"give the part an id"):
        registry.add_inline("", json.dumps(INLINE))


def test_duplicate_volume_names_across_parts_are_refused(registry):
    registry.add_file("first", CORPUS_WORLDS / "Gym" / "Empty.json")
    second = CORPUS_WORLDS / "Gym" / "Empty_4_Cylinders.json"
    with pytest.raises(WorldError) as err:
        registry.add_file("second", second)
    assert str(err.value).startswith(f"{second}: scenario.volumes[0].name: volume 'Ground_Station' is already in "
                                     "part 'first'")
    assert list(registry.parts) == ["first"]
    registry.delete("first")
    registry.add_file("second", second)  # free again once the first part is gone
    assert list(registry.parts) == ["second"]


def test_delete_removes_the_parts_frames_and_query_frames(registry):
    registry.add_file("gym", CORPUS_WORLDS / "Gym" / "1Obs_Central_Cylinder.json")
    registry.add_inline("pad", json.dumps(INLINE))
    drawn = registry.resolve(["CentralZone", "Accessible", "random", 3])
    placed = registry.resolve(["Pad", "volume", "coordinates", [[0, 0, 5], [0, 0, 0]]])
    names = set(children(registry))
    assert set(drawn.frames) <= names and set(placed.frames) <= names
    np.testing.assert_allclose(placed.positions, [[10, 0, 5]])
    removed = registry.delete("gym")
    assert set(removed.volume_frames) == {"Ground_Station", "CentralZone"}
    left = children(registry)
    assert set(placed.frames) <= set(left)
    assert not set(drawn.frames) & set(left)
    assert not {n for n in left if n.startswith(("GS4_", "CZ_")) or n in ("Ground_Station", "CentralZone")}
    with pytest.raises(QueryError, match="no volume named .CentralZone."):
        registry.resolve(["CentralZone", "Accessible", "random", 1])
    with pytest.raises(KeyError, match="no world part 'gym'; parts: pad"):
        registry.delete("gym")
    registry.delete("pad")
    assert children(registry) == [] and registry.record() == {"seed": 4, "parts": {}}


def test_bad_inline_parts(registry):
    with pytest.raises(WorldError, match=r"^world part 'p' \(inline\): not valid JSON"):
        registry.add_inline("p", "[{")
    bad = json.loads(json.dumps(INLINE))
    bad[0]["geometries"][0]["shape"] = "cone"
    with pytest.raises(WorldError, match=r"^world part 'p' \(inline\): scenario\.volumes\[0\]\.geometries\[0\]\.shape"):
        registry.add_inline("p", json.dumps(bad))
    assert registry.parts == {}


def test_random_queries_repeat_for_a_seed():
    def run(seed):
        registry = WorldRegistry(seed=seed, search_path=[])
        registry.add_file("gym", CORPUS_WORLDS / "Gym" / "Empty_4_Cylinders.json")
        return np.concatenate([registry.resolve(["LateralAccissibleZones", g, "random", 1]).positions
                               for g in ("X", "-X", "Y", "X")])

    np.testing.assert_array_equal(run(1), run(1))
    assert not np.allclose(run(1), run(2))


def test_record_is_json_and_holds_every_part(registry):
    registry.add_file("delivery", CORPUS_WORLDS / "Delivery" / "Delivery.json")
    registry.add_inline("pad", json.dumps(INLINE))
    record = json.loads(json.dumps(registry.record()))
    assert record["seed"] == 4 and list(record["parts"]) == ["delivery", "pad"]
    delivery = record["parts"]["delivery"]
    assert delivery["world_boundaries"] == [[-50, 50], [-50, 50], [-50, 50]]
    assert record["parts"]["pad"]["world_boundaries"] is None  # an inline part has no boundaries
    frames = [f for g in delivery["geometries"] for s in g["pose_sets"] for f in s["frames"]]
    assert "GS_takeoff_pos_1_0_0" in frames
    assert {o["name"] for o in delivery["obstacles"]} >= {"O1_del_obs_0", "D1_rec_obs_0", "D2_rec_obs_0"}


def test_a_reset_registry_flies_the_next_world_as_a_fresh_one():
    """The world node's reset between a batch's simulations: parts, random poses and query draws start over."""
    def fly(registry):
        registry.add_file("gym", CORPUS_WORLDS / "Gym" / "Empty_4_Cylinders.json")
        drawn = [registry.resolve(["LateralAccissibleZones", g, "random", 2]).positions for g in ("X", "Y", "X")]
        transforms = [(parent, child, frame.translation.tolist(), frame.quaternion().tolist())
                      for parent, child, frame in registry.static_transforms()]
        return registry.record(), np.concatenate(drawn), transforms

    reused = WorldRegistry(seed=1, search_path=[])
    fly(reused)
    reused.add_inline("pad", json.dumps(INLINE))  # a part the next simulation does not have
    reused.reset(7)
    assert reused.parts == {} and reused.static_transforms() == [] and reused.record() == {"seed": 7, "parts": {}}
    record, drawn, transforms = fly(reused)
    fresh_record, fresh_drawn, fresh_transforms = fly(WorldRegistry(seed=7, search_path=[]))
    assert record == fresh_record and transforms == fresh_transforms
    np.testing.assert_array_equal(drawn, fresh_drawn)
    assert not np.array_equal(drawn, fly(WorldRegistry(seed=1, search_path=[]))[1])  # the seed shows in the draws
