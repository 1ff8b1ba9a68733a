"""World files of every era of the original ROS-MAGNA: one small world per construct found in its history.

Tolerated by the original -> loads with one precise warning, refused with strict=True.
An older format -> migrated, each change listed. Crashed the original -> refused with file, JSON path and fix.
"""
import json
import subprocess

import numpy as np
import pytest

from magna_worlds.errors import WorldError
from magna_worlds.generate import resolve_world
from magna_worlds.loader import BOUNDARY_MARGIN, load_world, load_world_checked
from magna_worlds.migrate import migrate
from tests.support import ROOT


def cube(name="Box", prefix="b", origin=(0, 0, 1), sets=None, size=(2, 2, 2)):
    out = {"name": name, "prefix": prefix, "shape": "cube", "id": 0, "origin": [list(origin), [0, 0, 0]],
           "dimensions": list(size), "color": [0, 0, 0], "alpha": 0.3}
    if sets is not None:
        out["poses_sets"] = sets
    return out


def volume(geometries, name="V", prefix="v", origin=(0, 0, 0)):
    return {"name": name, "prefix": prefix, "origin": [list(origin), [0, 0, 0]], "permits": "geofence",
            "geometries": geometries}


def write(tmp_path, volumes, boundaries=((-20, 20), (-20, 20), (0, 20)), name="odd.json"):
    scenario = {"volumes": volumes}
    if boundaries is not None:
        scenario["world_boundaries"] = [list(b) for b in boundaries]
    path = tmp_path / "worlds" / "Old" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"scenario": scenario}))
    return path


MATRIX = {"type": "matrix", "use": "poses", "matrix_type": "dimension", "dimensions": [2, 1, 1], "density": 1,
          "poses_orientation": [0, 0, 0]}


def only_warning(world_or_resolved, path, file):
    warnings = list(world_or_resolved.warnings)
    assert len(warnings) == 1, warnings
    assert warnings[0].startswith(f"{file}: {path}: "), warnings[0]
    return warnings[0]


def refused_when_strict(file, path):
    with pytest.raises(WorldError) as err:
        load_world_checked(file, search_path=[], strict=True)
    assert (err.value.source, err.value.path) == (str(file), path)
    assert str(err.value).endswith("(refused with --strict)")


# --- tolerated: one warning each ----------------------------------------------------------------------------

def test_no_world_boundaries_uses_the_box_around_the_geometries(tmp_path):
    # SolarPlant files (Feb 2019) predate the field; Safedrone parts (Jun 2019) are only included by other worlds
    file = write(tmp_path, [volume([cube(origin=(5, 0, 1), sets=[MATRIX])])], boundaries=None)
    world = load_world(file, search_path=[])
    m = BOUNDARY_MARGIN
    np.testing.assert_allclose(world.boundaries, [[4 - m, 6 + m], [-1 - m, 1 + m], [0 - m, 2 + m]])
    assert world.boundaries_defaulted
    warning = only_warning(world, "scenario.world_boundaries", file)
    assert f"MAGNA uses the box around every geometry plus {m:g} m on each side" in warning
    assert "aborts a UAV that leaves it" in warning
    refused_when_strict(file, "scenario.world_boundaries")


def test_an_included_part_needs_no_world_boundaries(tmp_path):
    write(tmp_path, [volume([cube()], name="Part", prefix="p")], boundaries=None, name="Part.json")
    main = write(tmp_path, [{"name": "JSON", "world": "Old", "subworld": "Part"}], name="Main.json")
    world = load_world(main, search_path=[])
    assert world.warnings == () and not world.boundaries_defaulted


def test_a_volume_without_prefix_is_named_after_its_volume(tmp_path):
    # GAUSSUseCase1/Geofence1: a part that added a geometry to the volume Forest of the running world
    file = write(tmp_path, [{"name": "Forest", "origin": [[0, 0, 0], [0, 0, 0]], "geometries": [cube(sets=[MATRIX])]}])
    resolved = resolve_world(load_world(file, search_path=[]))
    warning = only_warning(resolved, "scenario.volumes[0].prefix", file)
    assert "MAGNA uses the volume's name, 'Forest', to name its frames" in warning
    assert resolved.geometries[0].frame_name == "Forest_Box" and resolved.geometries[0].poses()[0].frames[0] == \
        "Forest_b_pos_0_0_0"
    refused_when_strict(file, "scenario.volumes[0].prefix")


def test_poses_outside_the_boundaries_are_kept(tmp_path):
    # GAUSSUseCase1 CropField, Event, PowerLine: their ground stations lie outside their own boundaries
    file = write(tmp_path, [volume([cube(origin=(30, 0, 1), sets=[MATRIX])])])
    checked = load_world_checked(file, search_path=[])
    assert checked.resolved.pose_count() == 2
    warning = only_warning(checked, "scenario.volumes[0].geometries[0].poses_sets[0]", file)
    assert "puts 2 of its 2 poses outside scenario.world_boundaries [[-20, 20], [-20, 20], [0, 20]]" in warning
    assert "they are kept (the original did not check)" in warning
    refused_when_strict(file, "scenario.volumes[0].geometries[0].poses_sets[0]")


def test_a_repeated_geometry_name_keeps_both_and_the_name_finds_the_later(tmp_path):
    # GAUSSUseCase1/PowerLine (Mar 2019) wrote Base5 twice; the original's dict of geometries kept the later
    first, second = cube("Base5", "base5", (8, 0, 1), [MATRIX]), cube("Base5", "base5", (0, 0, 1), [MATRIX])
    file = write(tmp_path, [volume([first, second], prefix="PL")])
    resolved = resolve_world(load_world(file, search_path=[]))
    warning = only_warning(resolved, "scenario.volumes[0].geometries[0].name", file)
    assert "defines a geometry 'Base5' again at scenario.volumes[0].geometries[1]" in warning
    assert "this one is kept as 'Base5_0'" in warning
    assert resolved.geometry("V", "Base5").frame.translation[0] == 0
    assert resolved.geometry("V", "Base5_0").frame.translation[0] == 8
    frames = [child for _, child, _ in resolved.static_transforms()]
    assert len(frames) == len(set(frames))
    refused_when_strict(file, "scenario.volumes[0].geometries[0].name")


def test_a_repeated_geometry_prefix_names_the_later_frames_after_the_geometry(tmp_path):
    # Safedrone/ManualPolygon: two polygons with prefix "ins" published the same pose frames
    zigzag = {"type": "zigzag", "use": "poses", "height": 1, "spacing": [0, 1], "sweep_angle": 0,
              "margins": [0.1, 0.1], "initial_sense": "left", "orientation": [0, 0, 0]}
    square = [[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]]
    polygons = [{"name": f"Polygon{n}", "prefix": "ins", "shape": "prism", "id": 0, "origin": [[5 * n, 0, 0],
                 [0, 0, 0]], "dimensions": [2, square], "color": [0, 0, 0], "alpha": 0.3, "poses_sets": [zigzag]}
                for n in (1, 2)]
    file = write(tmp_path, [volume(polygons, prefix="MP")])
    resolved = resolve_world(load_world(file, search_path=[]))
    warning = only_warning(resolved, "scenario.volumes[0].geometries[1].prefix", file)
    assert "MAGNA names this geometry's pose and obstacle frames MP_Polygon2_pos_... and MP_Polygon2_obs_..." in warning
    assert resolved.geometry("V", "Polygon1").poses()[0].frames[0] == "MP_ins_pos_0"
    assert resolved.geometry("V", "Polygon2").poses()[0].frames[0] == "MP_Polygon2_pos_0"
    refused_when_strict(file, "scenario.volumes[0].geometries[1].prefix")


def test_a_path_set_after_divisions_is_skipped_as_the_original_did(tmp_path):
    # SolarPlant/safety (Feb 2019): a "path" set the code of its time no longer read
    path_set = {"type": "path", "dimensions": [2, 2, 1], "orientation": [0, 0, 0]}
    file = write(tmp_path, [volume([cube(sets=[path_set, MATRIX])])])
    world = load_world(file, search_path=[])
    assert [s.type for s in world.volumes[0].geometries[0].pose_sets] == ["matrix"]
    warning = only_warning(world, "scenario.volumes[0].geometries[0].poses_sets[0].type", file)
    assert "'path': the original skipped it without a word" in warning
    refused_when_strict(file, "scenario.volumes[0].geometries[0].poses_sets[0].type")


def test_an_unknown_field_is_ignored_with_a_warning(tmp_path):
    file = write(tmp_path, [volume([cube(sets=[dict(MATRIX, colour="red")])])])
    only_warning(load_world(file, search_path=[]), "scenario.volumes[0].geometries[0].poses_sets[0].colour", file)
    refused_when_strict(file, "scenario.volumes[0].geometries[0].poses_sets[0].colour")


# --- older formats: migrated, each change listed ----------------------------------------------------------------

def test_divisions_orientation_and_no_matrix_type_are_migrated(tmp_path):
    # Jan 2019: sets in `divisions`, turned by `orientation`, matrices without matrix_type
    old = {"type": "matrix", "use": "poses", "dimensions": [2, 1, 1], "density": 1, "orientation": [0, 0.5, 0]}
    file = write(tmp_path, [volume([{**cube(), "divisions": [old]}])])
    world = load_world(file, search_path=[])
    where = "scenario.volumes[0].geometries[0]"
    assert world.changes == (f"{file}: {where}.divisions -> poses_sets",
                             f"{file}: {where}.divisions[0].orientation -> poses_orientation",
                             f"{file}: {where}.divisions[0]: matrix_type \"dimension\" added (a matrix without it "
                             "was laid by counts per axis)")
    assert world.warnings == ()
    spec = world.volumes[0].geometries[0].pose_sets[0]
    assert (spec.matrix_type, spec.orientation.ranges[1]) == ("dimension", (0.5, 0.5))
    # the migration never touches its input, and strict does not refuse an older format
    assert load_world(file, search_path=[], strict=True).changes == world.changes
    raw = json.loads(file.read_text())
    assert migrate(raw).original == raw and "divisions" in raw["scenario"]["volumes"][0]["geometries"][0]


def test_an_error_in_a_migrated_set_names_the_path_the_file_writes(tmp_path):
    old = {"type": "matrix", "use": "poses", "dimensions": [2, 1.5, 1], "density": 1, "orientation": [0, 0, 0]}
    file = write(tmp_path, [volume([{**cube(), "divisions": [old]}])])
    with pytest.raises(WorldError) as err:
        load_world(file, search_path=[])
    assert err.value.path == "scenario.volumes[0].geometries[0].divisions[0].dimensions[1]"


def test_a_path_set_in_divisions_says_magna_does_not_lay_it_out(tmp_path):
    file = write(tmp_path, [volume([{**cube(), "divisions": [{"type": "path", "dimensions": [2, 2, 1],
                                                              "orientation": [0, 0, 0]}]}])])
    warning = only_warning(load_world(file, search_path=[]),
                           "scenario.volumes[0].geometries[0].divisions[0].type", file)
    assert "the original laid a zigzag through a grid" in warning and "MAGNA has no such set and skips it" in warning


# --- crashed the original: refused --------------------------------------------------------------------------

def test_a_prism_without_vertices_is_refused(tmp_path):
    # Safedrone/volumes_from_unifly (Jun 2019): Polygon_1 [3.0, []]; the original's sweep read its first vertex
    prism = {"name": "Polygon_1", "prefix": "P1", "shape": "prism", "id": 0, "origin": [[0, 0, 0], [0, 0, 0]],
             "dimensions": [3.0, []], "color": [0, 0, 0], "alpha": 0.3}
    file = write(tmp_path, [volume([prism])])
    with pytest.raises(WorldError) as err:
        load_world(file, search_path=[])
    assert err.value.path == "scenario.volumes[0].geometries[0].dimensions[1]"
    assert "3 or more base vertices" in err.value.message


def test_a_missing_field_is_described_in_words(tmp_path):
    broken = cube()
    del broken["shape"]
    file = write(tmp_path, [volume([broken])])
    with pytest.raises(WorldError) as err:
        load_world(file, search_path=[])
    assert err.value.path == "scenario.volumes[0].geometries[0].shape"
    assert err.value.message == "missing; add it: one of cube, sphere, cylinder, prism, torus"
    assert "DESIGN" not in err.value.message


# --- the command line -----------------------------------------------------------------------------------------

def magna(*args):
    return subprocess.run([str(ROOT / "magna"), "world", *args], capture_output=True, text=True, timeout=120)


def test_check_prints_warnings_on_stderr_and_strict_refuses(tmp_path):
    old = {"type": "matrix", "use": "poses", "dimensions": [2, 1, 1], "density": 1, "orientation": [0, 0, 0]}
    file = write(tmp_path, [volume([{**cube(), "divisions": [old]}])], boundaries=None)
    done = magna("check", str(file))
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"magna world: warning: {file}: scenario.world_boundaries: ")
    assert "format      older format migrated to the current one: 3 change(s)" in done.stdout
    assert f"  {file}: scenario.volumes[0].geometries[0].divisions -> poses_sets" in done.stdout
    assert "(not in the file: the box around its geometries)" in done.stdout
    data = json.loads(magna("check", str(file), "--json").stdout)
    assert len(data["warnings"]) == 1 and len(data["changes"]) == 3 and data["boundaries_defaulted"]
    strict = magna("check", str(file), "--strict")
    assert strict.returncode == 2 and strict.stdout == ""
    assert strict.stderr.startswith(f"magna world: {file}: scenario.world_boundaries: missing")
    assert strict.stderr.rstrip().endswith("(refused with --strict)")


def test_the_old_take_off_geometry_name_migrates_to_the_one_legacy_missions_spawn_at(tmp_path):
    file = write(tmp_path, [volume([cube("UAVs_take_off", "to")], name="Ground_Station", prefix="GS")])
    world = load_world(file)
    assert [g.name for g in world.volumes[0].geometries] == ["Agents_take_off"]
    assert any("geometries[0].name: UAVs_take_off -> Agents_take_off" in c for c in world.changes)
    both = write(tmp_path, [volume([cube("UAVs_take_off", "to"), cube("Agents_take_off", "ao", origin=(5, 0, 1))],
                                   name="Ground_Station", prefix="GS")], name="both.json")
    names = [g.name for g in load_world(both).volumes[0].geometries]
    assert names == ["UAVs_take_off", "Agents_take_off"]  # a volume that has both keeps both
