"""magna_worlds.loader: the real worlds load; includes resolve; bad input gets one error naming file and JSON path."""
import copy
import json
import math

import numpy as np
import pytest

from magna_common.search_path import world_folders
from magna_worlds.errors import WorldError
from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world, world_from_data
from tests.support import CORPUS

CORPUS_WORLDS = CORPUS / "Worlds"


def corpus_worlds():
    """The corpus files; without the corpus, one path that does not exist, so the tests using it fail (not skip)."""
    return sorted(CORPUS_WORLDS.glob("*/*.json")) or [CORPUS_WORLDS / "missing" / "corpus.json"]


def geometry(name="G", prefix="g", shape="cube", dimensions=(2.0, 2.0, 2.0), **extra):
    out = {"name": name, "prefix": prefix, "shape": shape, "id": 0, "origin": [[0, 0, 0], [0, 0, 0]],
           "dimensions": list(dimensions), "color": [10, 20, 30], "alpha": 0.5}
    out.update(extra)
    return out


def volume(name="V", prefix="v", geometries=None, origin=((0, 0, 0), (0, 0, 0))):
    return {"name": name, "prefix": prefix, "origin": [list(origin[0]), list(origin[1])], "permits": "geofence",
            "geometries": [geometry()] if geometries is None else geometries}


def world(*volumes):
    return {"scenario": {"world_boundaries": [[-10, 10], [-10, 10], [0, 10]], "volumes": list(volumes)}}


def write(path, data):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return path


def include(world_name, subworld):
    return {"name": "JSON", "world": world_name, "subworld": subworld}


# --- the real worlds --------------------------------------------------------------------------------------------

def test_the_corpus_has_worlds():
    names = {f"{f.parent.name}/{f.stem}" for f in corpus_worlds()}
    assert {"Gym/1Obs_Central_Cylinder", "Gym/Empty_4_Cylinders", "Delivery/Delivery", "Empty/Empty"} <= names


@pytest.mark.parametrize("path", corpus_worlds(), ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_corpus_world_loads(path):
    raw = json.loads(path.read_text())["scenario"]
    loaded = load_world(path, search_path=[])
    assert loaded.source == str(path)
    assert len(loaded.volumes) == len(raw["volumes"])
    assert sum(len(v.geometries) for v in loaded.volumes) == sum(len(v["geometries"]) for v in raw["volumes"])
    np.testing.assert_array_equal(loaded.boundaries, np.array(raw["world_boundaries"], dtype=float))
    for raw_volume, vol in zip(raw["volumes"], loaded.volumes, strict=True):
        assert (vol.name, vol.prefix, vol.permits) == (raw_volume["name"], raw_volume["prefix"],
                                                      raw_volume["permits"])
        np.testing.assert_allclose(vol.origin.translation, raw_volume["origin"][0])
        for raw_geometry, geo in zip(raw_volume["geometries"], vol.geometries, strict=True):
            assert (geo.name, geo.prefix, geo.spec.shape) == (raw_geometry["name"], raw_geometry["prefix"],
                                                             raw_geometry["shape"])
            assert geo.spec.dimensions == tuple(float(d) for d in raw_geometry["dimensions"])
            assert geo.alpha == raw_geometry["alpha"]
            assert geo.color == pytest.approx(tuple(c / 255 for c in raw_geometry["color"]))
            assert len(geo.pose_sets) == len(raw_geometry.get("poses_sets", []))
            assert [s.type for s in geo.pose_sets] == [s["type"] for s in raw_geometry.get("poses_sets", [])]
    assert loaded.warnings == ()
    resolve_world(loaded, seed=0)  # every set lays out


def test_a_corpus_geometry_in_detail():
    loaded = load_world(CORPUS_WORLDS / "Gym" / "1Obs_Central_Cylinder.json", search_path=[])
    zone = loaded.volume("CentralZone")
    torus = zone.geometry("Accessible")
    assert torus.spec.shape == "torus" and torus.spec.dimensions == (6.0, 9.0, 3.0)
    np.testing.assert_allclose(torus.origin.translation, [0, 0, 2.5])
    obstacles = zone.geometry("Obstacles").pose_sets[0]
    assert (obstacles.type, obstacles.use, obstacles.quantity) == ("random", "obstacles", 3)
    assert obstacles.obstacle.shapes == ("sphere",)
    assert obstacles.obstacle.dimension_ranges == ((0.5, 0.5),) * 3
    takeoff = loaded.volume("Ground_Station").geometry("Agents_take_off").pose_sets[0]
    assert (takeoff.matrix_type, takeoff.matrix_dimensions, takeoff.density) == ("dimension", (2, 1, 1), 1.0)
    assert takeoff.set_yaw == 1.5
    assert takeoff.orientation.ranges == ((0.0, 0.0), (1.25, 1.25), (1.5, 1.5)) and takeoff.orientation.fixed
    assert takeoff.source_path == "scenario.volumes[0].geometries[0].poses_sets[0]"
    assert loaded.volume("Nowhere") is None and zone.geometry("Nowhere") is None


# --- includes ---------------------------------------------------------------------------------------------------

def test_include_resolves_next_to_the_including_file(tmp_path):
    root = tmp_path / "worlds"
    part = write(root / "Parts" / "Ring.json", world(volume("Ring", "R"), volume("Hub", "H")))
    main = write(root / "Main" / "Sub.json", world(volume("Base", "B"), include("Parts", "Ring"), volume("Top", "T")))
    loaded = load_world(main, search_path=[])
    assert [v.name for v in loaded.volumes] == ["Base", "Ring", "Hub", "Top"]
    assert loaded.included == (str(part),)
    assert loaded.volume("Ring").source == str(part)  # the volume remembers its own file
    assert loaded.volume("Ring").source_path == "scenario.volumes[0]"
    assert loaded.volume("Top").source == str(main)


def test_include_resolves_through_the_search_path(tmp_path):
    elsewhere = tmp_path / "library"
    part = write(elsewhere / "Parts" / "Ring.json", world(volume("Ring", "R")))
    main = write(tmp_path / "worlds" / "Main" / "Sub.json", world(include("Parts", "Ring")))
    with pytest.raises(WorldError):
        load_world(main, search_path=[])
    loaded = load_world(main, search_path=[tmp_path / "empty", elsewhere])
    assert [v.name for v in loaded.volumes] == ["Ring"] and loaded.included == (str(part),)


def test_the_including_files_root_comes_before_the_search_path(tmp_path):
    write(tmp_path / "library" / "Parts" / "Ring.json", world(volume("FromLibrary", "L")))
    main = write(tmp_path / "worlds" / "Main" / "Sub.json", world(include("Parts", "Ring")))
    write(tmp_path / "worlds" / "Parts" / "Ring.json", world(volume("Beside", "B")))
    loaded = load_world(main, search_path=[tmp_path / "library"])
    assert [v.name for v in loaded.volumes] == ["Beside"]


def test_nested_includes_resolve_next_to_each_file(tmp_path):
    lib = tmp_path / "lib"
    write(lib / "Deep" / "Leaf.json", world(volume("Leaf", "L")))
    write(lib / "Mid" / "Branch.json", world(volume("Branch", "B"), include("Deep", "Leaf")))
    main = write(tmp_path / "worlds" / "Main" / "Sub.json", world(include("Mid", "Branch")))
    loaded = load_world(main, search_path=[lib])
    assert [v.name for v in loaded.volumes] == ["Branch", "Leaf"]
    assert [p.rsplit("/", 2)[-2] for p in loaded.included] == ["Mid", "Deep"]


def test_included_world_needs_no_boundaries(tmp_path):
    root = tmp_path / "worlds"
    write(root / "Parts" / "Bare.json", {"scenario": {"volumes": [volume("Bare", "b")]}})
    main = write(root / "Main" / "Sub.json", world(include("Parts", "Bare")))
    assert [v.name for v in load_world(main, search_path=[]).volumes] == ["Bare"]


def test_search_path_from_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("MAGNA_WORLDS_PATH", f"{tmp_path / 'a'}:{tmp_path / 'b'}")
    path = world_folders()
    assert path[:2] == [tmp_path / "a", tmp_path / "b"]
    assert path[-1].name == "worlds"
    write(tmp_path / "b" / "Parts" / "Ring.json", world(volume("Ring", "R")))
    main = write(tmp_path / "worlds" / "Main" / "Sub.json", world(include("Parts", "Ring")))
    assert [v.name for v in load_world(main).volumes] == ["Ring"]


def test_an_include_loop_is_refused(tmp_path):
    root = tmp_path / "worlds"
    a = write(root / "W" / "A.json", world(volume("A", "a"), include("W", "B")))
    write(root / "W" / "B.json", world(volume("B", "b"), include("W", "A")))
    with pytest.raises(WorldError) as err:
        load_world(a, search_path=[])
    message = str(err.value)
    assert message.startswith(str(root / "W" / "B.json") + ": scenario.volumes[1]: ")
    assert "W/A includes itself" in message and "remove the loop" in message


def test_a_file_including_itself_is_refused(tmp_path):
    path = write(tmp_path / "worlds" / "W" / "Self.json", world(include("W", "Self")))
    with pytest.raises(WorldError, match=r"scenario\.volumes\[0\]: W/Self includes itself"):
        load_world(path, search_path=[])


def test_including_the_same_part_twice_repeats_its_volume_names(tmp_path):
    root = tmp_path / "worlds"
    write(root / "Parts" / "Ring.json", world(volume("Ring", "R")))
    main = write(root / "Main" / "Sub.json", world(include("Parts", "Ring"), include("Parts", "Ring")))
    with pytest.raises(WorldError) as err:
        load_world(main, search_path=[])
    assert str(err.value).startswith(str(root / "Parts" / "Ring.json") + ": scenario.volumes[0].name: ")
    assert "volume 'Ring' is defined twice" in str(err.value)


def test_missing_included_file(tmp_path):
    main = write(tmp_path / "worlds" / "Main" / "Sub.json", world(volume(), include("Parts", "Nowhere")))
    with pytest.raises(WorldError) as err:
        load_world(main, search_path=[tmp_path / "lib"])
    message = str(err.value)
    assert message.startswith(f"{main}: scenario.volumes[1]: included world Parts/Nowhere not found")
    assert str(tmp_path / "worlds" / "Parts" / "Nowhere.json") in message
    assert str(tmp_path / "lib" / "Parts" / "Nowhere.json") in message


# --- bad input: one error naming the file and the JSON path ----------------------------------------------------

def base_world():
    return world(volume("V", "v", [geometry("A", "a"), geometry("B", "b")]), volume("W", "w"))


def broken(edit):
    data = base_world()
    edit(data["scenario"])
    return data


def set_(path, value):
    """An edit that sets data[path...] = value (path: keys and indices under `scenario`)."""
    def edit(scenario):
        target = scenario
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return edit


def delete(path):
    def edit(scenario):
        target = scenario
        for key in path[:-1]:
            target = target[key]
        del target[path[-1]]
    return edit


def prism(dimensions):
    """An edit that turns geometry B into a prism of these dimensions."""
    def edit(scenario):
        scenario["volumes"][0]["geometries"][1].update(shape="prism", dimensions=dimensions)
    return edit


G1 = ("volumes", 0, "geometries", 1)
MATRIX = {"type": "matrix", "use": "poses", "matrix_type": "dimension", "dimensions": [2, 2, 2]}

BAD = [
    # (id, edit, JSON path, words in the message)
    ("unknown shape", set_(G1 + ("shape",), "cone"), "scenario.volumes[0].geometries[1].shape", "unknown shape 'cone'"),
    ("missing shape", delete(G1 + ("shape",)), "scenario.volumes[0].geometries[1].shape", "missing"),
    ("missing geometry origin", delete(G1 + ("origin",)), "scenario.volumes[0].geometries[1].origin", "missing"),
    ("missing volume name", delete(("volumes", 1, "name")), "scenario.volumes[1].name", "missing"),
    ("missing volumes", delete(("volumes",)), "scenario.volumes", "missing"),
    ("prism with two vertices", prism([1.0, [[0, 0, 0], [1, 0, 0]]]),
     "scenario.volumes[0].geometries[1].dimensions[1]", "3 or more base vertices"),
    ("prism with crossing edges", prism([1.0, [[0, 0], [1, 1], [1, 0], [0, 1]]]),
     "scenario.volumes[0].geometries[1].dimensions[1]", "edges 0 and 2 cross"),
    ("prism height", prism([0, [[0, 0, 0], [1, 0, 0], [0, 1, 0]]]),
     "scenario.volumes[0].geometries[1].dimensions[0]", "must be positive"),
    ("prism vertex", prism([1.0, [[0, 0, 0], [1, 0, 0], [0, "1", 0]]]),
     "scenario.volumes[0].geometries[1].dimensions[1][2][1]", "expected a finite number"),
    ("negative size", set_(G1 + ("dimensions",), [1, -1, 1]), "scenario.volumes[0].geometries[1].dimensions[1]",
     "must be positive"),
    ("dimension as text", set_(G1 + ("dimensions",), [1, "1", 1]), "scenario.volumes[0].geometries[1].dimensions[1]",
     "expected a finite number"),
    ("name not a string", set_(G1 + ("name",), 5), "scenario.volumes[0].geometries[1].name",
     "expected a non-empty string"),
    ("empty prefix", set_(("volumes", 1, "prefix"), ""), "scenario.volumes[1].prefix", "expected a non-empty string"),
    ("id not an integer", set_(G1 + ("id",), "0"), "scenario.volumes[0].geometries[1].id", "expected an integer"),
    ("geometries not a list", set_(("volumes", 1, "geometries"), {}), "scenario.volumes[1].geometries",
     "expected a list"),
    ("volume not an object", set_(("volumes", 1), [1]), "scenario.volumes[1]", "expected an object"),
    ("origin shape", set_(("volumes", 1, "origin"), [[0, 0, 0]]), "scenario.volumes[1].origin",
     "[[x, y, z], [roll, pitch, yaw]]"),
    ("origin rpy length", set_(G1 + ("origin",), [[0, 0, 0], [0, 0]]), "scenario.volumes[0].geometries[1].origin[1]",
     "[roll, pitch, yaw]"),
    ("origin value", set_(G1 + ("origin",), [[0, None, 0], [0, 0, 0]]),
     "scenario.volumes[0].geometries[1].origin[0][1]", "expected a finite number"),
    ("alpha above 1", set_(G1 + ("alpha",), 1.5), "scenario.volumes[0].geometries[1].alpha", "must be 0..1"),
    ("alpha below 0", set_(G1 + ("alpha",), -0.1), "scenario.volumes[0].geometries[1].alpha", "must be 0..1"),
    ("alpha as text", set_(G1 + ("alpha",), "0.5"), "scenario.volumes[0].geometries[1].alpha",
     "expected a finite number"),
    ("colour above 255", set_(G1 + ("color",), [0, 256, 0]), "scenario.volumes[0].geometries[1].color", "0-255"),
    ("colour length", set_(G1 + ("color",), [0, 0]), "scenario.volumes[0].geometries[1].color", "[r, g, b]"),
    ("duplicate volume names", set_(("volumes", 1, "name"), "V"), "scenario.volumes[1].name",
     "volume 'V' is defined twice"),
    ("boundaries reversed", set_(("world_boundaries",), [[0, 1], [3, 2], [0, 1]]), "scenario.world_boundaries[1]",
     "min must be below max"),
    ("origin_geo latitude", set_(("origin_geo",), [91, 0, 0]), "scenario.origin_geo", "latitude must be"),
    ("unknown set type", set_(G1 + ("poses_sets",), [{"type": "spiral"}]),
     "scenario.volumes[0].geometries[1].poses_sets[0].type", "unknown value 'spiral'"),
    ("unknown use", set_(G1 + ("poses_sets",), [dict(MATRIX, use="landing")]),
     "scenario.volumes[0].geometries[1].poses_sets[0].use", "unknown value 'landing'"),
    ("matrix count not whole", set_(G1 + ("poses_sets",), [dict(MATRIX, dimensions=[2, 1.5, 1])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].dimensions[1]", "a whole number >= 1"),
    ("matrix zero spacing",
     set_(G1 + ("poses_sets",), [dict(MATRIX, matrix_type="distance", dimensions=[1, 0, 1])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].dimensions[1]", "a spacing must be positive"),
    ("density", set_(G1 + ("poses_sets",), [dict(MATRIX, density=0)]),
     "scenario.volumes[0].geometries[1].poses_sets[0].density", "(0, 1]"),
    ("random quantity", set_(G1 + ("poses_sets",), [{"type": "random", "quantity": 2.5}]),
     "scenario.volumes[0].geometries[1].poses_sets[0].quantity", "whole number >= 1"),
    ("random without quantity", set_(G1 + ("poses_sets",), [{"type": "random"}]),
     "scenario.volumes[0].geometries[1].poses_sets[0].quantity", "missing"),
    ("coordinates pose", set_(G1 + ("poses_sets",), [{"type": "coordinates", "coordinates": [[[0, 0, 0]]]}]),
     "scenario.volumes[0].geometries[1].poses_sets[0].coordinates[0]", "[[x, y, z], [roll, pitch, yaw]]"),
    ("zigzag on a cube", set_(G1 + ("poses_sets",), [{"type": "zigzag", "height": 1, "spacing": [0, 1]}]),
     "scenario.volumes[0].geometries[1].poses_sets[0].type", "a zigzag sweeps a prism's polygon"),
    ("orientation range", set_(G1 + ("poses_sets",), [dict(MATRIX, poses_orientation=[0, [1, 0], 0])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].poses_orientation[1]", "low must not exceed high"),
    ("obstacle shape", set_(G1 + ("poses_sets",), [dict(MATRIX, use="obstacles", obstacles_shape=["cube", "cone"],
                                                         obstacles_dimensions=[1, 1, 1])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].obstacles_shape[1]", "unknown value 'cone'"),
    ("obstacle range", set_(G1 + ("poses_sets",), [dict(MATRIX, use="obstacles", obstacles_shape=["cube"],
                                                         obstacles_dimensions=[1, [2, 1], 1])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].obstacles_dimensions[1]", "need 0 < low <= high"),
    ("obstacle torus", set_(G1 + ("poses_sets",), [dict(MATRIX, use="obstacles", obstacles_shape=["sphere", "torus"],
                                                         obstacles_dimensions=[2, 2, 1])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].obstacles_dimensions", "outer diameter must be"),
    ("obstacle prism vertices", set_(G1 + ("poses_sets",), [dict(MATRIX, use="obstacles", obstacles_shape=["prism"],
                                                                 obstacles_dimensions=[1, [[0, 0], [1, 0]]])]),
     "scenario.volumes[0].geometries[1].poses_sets[0].obstacles_dimensions[1]", "3 or more base vertices"),
]


@pytest.mark.parametrize("edit, path, words", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_input_names_file_and_json_path(tmp_path, edit, path, words):
    file = write(tmp_path / "worlds" / "Bad" / "bad.json", broken(edit))
    with pytest.raises(WorldError) as err:
        load_world(file, search_path=[])
    message = str(err.value)
    assert message.startswith(f"{file}: {path}: "), message
    assert words in message, message
    assert (err.value.source, err.value.path) == (str(file), path)
    assert err.value.exit_status == 2


# What the original tolerated loads with one warning; strict refuses it at the same place (test_porting.py has
# the constructs of the original's history one by one).
TOLERATED = [
    ("missing boundaries", delete(("world_boundaries",)), "scenario.world_boundaries", "missing"),
    ("duplicate geometry names", set_(G1 + ("name",), "A"), "scenario.volumes[0].geometries[0].name",
     "defines a geometry 'A' again at scenario.volumes[0].geometries[1]"),
]


@pytest.mark.parametrize("edit, path, words", [b[1:] for b in TOLERATED], ids=[b[0] for b in TOLERATED])
def test_tolerated_input_warns_and_strict_refuses_it(tmp_path, edit, path, words):
    file = write(tmp_path / "worlds" / "Odd" / "odd.json", broken(edit))
    loaded = load_world(file, search_path=[])
    assert len(loaded.warnings) == 1 and loaded.warnings[0].startswith(f"{file}: {path}: "), loaded.warnings
    assert words in loaded.warnings[0]
    with pytest.raises(WorldError) as err:
        load_world(file, search_path=[], strict=True)
    assert (err.value.source, err.value.path) == (str(file), path)
    assert words in err.value.message and err.value.message.endswith("(refused with --strict)")


def test_the_good_base_world_loads(tmp_path):
    file = write(tmp_path / "worlds" / "Good" / "good.json", base_world())
    loaded = load_world(file, search_path=[])
    assert [v.name for v in loaded.volumes] == ["V", "W"] and loaded.warnings == ()
    assert loaded.volume("V").geometry("B").color == pytest.approx((10 / 255, 20 / 255, 30 / 255))


def test_file_level_errors(tmp_path):
    missing = tmp_path / "nope.json"
    with pytest.raises(WorldError, match=r"nope\.json: no such file"):
        load_world(missing, search_path=[])
    not_json = write(tmp_path / "x.json", '{"scenario": [1, 2,')
    with pytest.raises(WorldError) as err:
        load_world(not_json, search_path=[])
    assert str(err.value).startswith(f"{not_json}: not valid JSON") and "line 1" in str(err.value)
    no_scenario = write(tmp_path / "y.json", {"volumes": []})
    with pytest.raises(WorldError) as err:
        load_world(no_scenario, search_path=[])
    assert str(err.value).startswith(f"{no_scenario}: scenario: missing")


def test_distance_matrix_that_does_not_fit_is_refused_by_resolve_world(tmp_path):
    sets = [dict(MATRIX, matrix_type="distance", dimensions=[0.5, 3.0, 0.5])]  # the cube is 2 m wide
    file = write(tmp_path / "worlds" / "Bad" / "fit.json", broken(set_(G1 + ("poses_sets",), sets)))
    loaded = load_world(file, search_path=[])  # the spacing is a valid number: the loader accepts it
    with pytest.raises(WorldError) as err:
        resolve_world(loaded)
    message = str(err.value)
    assert message.startswith(f"{file}: scenario.volumes[0].geometries[1].poses_sets[0].dimensions[1]: ")
    assert "a spacing of 3 m does not fit" in message and "2 m along y" in message


def test_coordinates_outside_the_geometry_are_refused_by_resolve_world(tmp_path):
    sets = [{"type": "coordinates", "coordinates": [[[0, 0, 0], [0, 0, 0]], [[0, 0, 1.5], [0, 0, 0]]]}]
    file = write(tmp_path / "worlds" / "Bad" / "out.json", broken(set_(G1 + ("poses_sets",), sets)))
    with pytest.raises(WorldError) as err:
        resolve_world(load_world(file, search_path=[]))
    assert str(err.value).startswith(f"{file}: scenario.volumes[0].geometries[1].poses_sets[0].coordinates[1]: ")


def test_error_in_an_included_file_names_that_file(tmp_path):
    root = tmp_path / "worlds"
    bad = copy.deepcopy(world(volume("R", "r", [geometry(shape="cone")])))
    part = write(root / "Parts" / "Ring.json", bad)
    main = write(root / "Main" / "Sub.json", world(volume(), include("Parts", "Ring")))
    with pytest.raises(WorldError) as err:
        load_world(main, search_path=[])
    assert str(err.value).startswith(f"{part}: scenario.volumes[0].geometries[0].shape: unknown shape 'cone'")


def test_unknown_fields_warn_and_do_not_fail(tmp_path):
    data = base_world()
    data["scenario"]["comment"] = "hello"
    data["scenario"]["volumes"][0]["colour"] = [1, 2, 3]
    data["scenario"]["volumes"][0]["geometries"][1]["mass"] = 3
    data["scenario"]["volumes"][1]["geometries"][0]["poses_sets"] = [dict(MATRIX, spin=1)]
    file = write(tmp_path / "worlds" / "W" / "warn.json", data)
    loaded = load_world(file, search_path=[])
    assert [v.name for v in loaded.volumes] == ["V", "W"]
    assert loaded.warnings == (
        f"{file}: scenario.comment: unknown field, ignored",
        f"{file}: scenario.volumes[0].colour: unknown field, ignored",
        f"{file}: scenario.volumes[0].geometries[1].mass: unknown field, ignored",
        f"{file}: scenario.volumes[1].geometries[0].poses_sets[0].spin: unknown field, ignored",
    )


def test_optional_fields_take_their_defaults(tmp_path):
    g = geometry()
    for key in ("id", "color", "alpha"):
        del g[key]
    v = volume(geometries=[g])
    del v["permits"]
    file = write(tmp_path / "worlds" / "W" / "min.json", world(v))
    loaded = load_world(file, search_path=[])
    geo = loaded.volumes[0].geometries[0]
    assert (geo.id, geo.alpha, geo.pose_sets) == (0, 1.0, ())
    assert geo.color == pytest.approx((128 / 255,) * 3)
    assert loaded.volumes[0].permits == ""
    assert loaded.origin_geo is None


def test_origin_is_read_as_xyz_and_rpy(tmp_path):
    v = volume(origin=((1, 2, 3), (0, 0, math.pi / 2)))
    file = write(tmp_path / "worlds" / "W" / "o.json", world(v))
    frame = load_world(file, search_path=[]).volumes[0].origin
    np.testing.assert_allclose(frame.translation, [1, 2, 3])
    np.testing.assert_allclose(frame.apply([[1, 0, 0]]), [[1, 3, 3]], atol=1e-12)


def test_pose_set_options(tmp_path):
    sets = [
        dict(MATRIX, poses_orientation="random_yaw", set_orientation=[0, 0, 0.25]),
        {"type": "random", "quantity": 3, "poses_orientation": "random"},
        {"type": "coordinates", "coordinates": [[[0, 0, 0], [0, 0, 0, 2]], [[0.5, 0, 0], [0, 0, math.pi / 2]]]},
        {"type": "random", "quantity": 2, "use": "obstacles", "obstacles_shape": "sphere",
         "obstacles_dimensions": [[0.2, 0.4], 1, 1], "poses_orientation": [[0, 0.1], 0, [-1, 1]]},
    ]
    file = write(tmp_path / "worlds" / "W" / "sets.json", broken(set_(G1 + ("poses_sets",), sets)))
    specs = load_world(file, search_path=[]).volumes[0].geometries[1].pose_sets
    assert specs[0].orientation.ranges[2] == (-math.pi, math.pi) and specs[0].set_yaw == 0.25
    assert specs[1].orientation.any_rotation and not specs[1].orientation.fixed
    (p0, q0), (p1, q1) = specs[2].coordinates
    assert q0 == (0.0, 0.0, 0.0, 1.0)  # normalised
    assert q1 == pytest.approx((0, 0, math.sqrt(0.5), math.sqrt(0.5)))
    assert specs[3].obstacle.shapes == ("sphere",)
    assert specs[3].obstacle.dimension_ranges == ((0.2, 0.4), (1.0, 1.0), (1.0, 1.0))
    assert specs[3].orientation.ranges == ((0.0, 0.1), (0.0, 0.0), (-1.0, 1.0))


def test_world_from_data_takes_a_bare_list_of_volumes():
    loaded = world_from_data([volume("Inline", "in")], "mission part")
    assert [v.name for v in loaded.volumes] == ["Inline"]
    assert np.isinf(loaded.boundaries).all()
    with pytest.raises(WorldError) as err:
        world_from_data([volume("Inline", "in", [geometry(alpha=2)])], "mission part")
    assert str(err.value).startswith("mission part: scenario.volumes[0].geometries[0].alpha: must be 0..1")


def test_an_inline_include_without_a_search_path_says_so(tmp_path):
    with pytest.raises(WorldError, match=r"^inline: scenario\.volumes\[0\]: included world W/S not found; looked at "
                                         r"nowhere \(no search path\)"):
        world_from_data([include("W", "S")], "inline")
    write(tmp_path / "W" / "S.json", world(volume("Found", "f")))
    assert [v.name for v in world_from_data([include("W", "S")], "inline", search_path=[tmp_path]).volumes] == [
        "Found"]
