"""The world designer: worlds of the project and of the original open in the current schema, checks are
`magna world check`'s on the fields they name, and the scene is the geometry rviz is given."""
import copy
import json
import subprocess

import numpy as np
import pytest

from magna_studio.documents import DesignError, save_document
from magna_studio.world_design import check_world, new_world, open_world, pose_choices, resolve_world_data, world_scene
from magna_worlds.loader import world_from_data
from magna_worlds.markers import world_markers
from magna_worlds.query import PoseQueries
from tests.support import CORPUS, ROOT

DIMENSIONS = "scenario.volumes[1].geometries[0].dimensions"  # Gym/Four_Cylinders: the lateral cylinder X


def magna_world(*args):
    return subprocess.run([str(ROOT / "magna"), "world", *args], capture_output=True, text=True, timeout=120)


def errors(result):
    return [d for d in result["diagnostics"] if d["severity"] == "error"]


def test_a_project_world_opens_as_it_is_with_its_scene():
    opened = open_world("Gym/Four_Cylinders", [])
    path = ROOT / "worlds" / "Gym" / "Four_Cylinders.json"
    assert opened["path"] == str(path) and opened["name"] == "Gym/Four_Cylinders"
    assert opened["data"] == json.loads(path.read_text())
    assert opened["changes"] == [] and opened["diagnostics"] == []
    resolved = resolve_world_data(opened["data"], str(path), [])
    assert len(opened["scene"]["items"]) == len(world_markers([resolved]).markers) - 1  # all but the DELETEALL
    assert opened["scene"]["boundaries"] == [[-12, 12], [-14, 12], [0, 8]]
    json.dumps(opened)  # what the server sends as it is


@pytest.mark.parametrize("name", ["Gym/1Obs_Central_Cylinder", "Gym/Empty_4_Cylinders_1Obs", "Delivery/Delivery"])
def test_the_originals_worlds_open_from_the_corpus_with_what_the_command_says(name):
    opened = open_world(name, [CORPUS])
    assert opened["path"] == str(CORPUS / "Worlds" / f"{name}.json")
    done = magna_world("check", name, "--search-path", str(CORPUS))
    assert done.returncode == 0, done.stderr
    assert [f"magna world: {d['line']}" for d in opened["diagnostics"]] == done.stderr.splitlines()
    summary = json.loads(magna_world("check", name, "--search-path", str(CORPUS), "--json").stdout)
    kinds = [item["kind"] for item in opened["scene"]["items"]]
    assert kinds.count("geometry") == summary["totals"]["geometries"]
    assert kinds.count("obstacle") == summary["totals"]["obstacles"]
    points = sum(len(item["points"]) for item in opened["scene"]["items"] if item["kind"] == "pose_set")
    assert points == summary["totals"]["poses"]


def test_a_bad_geometry_value_is_an_error_on_its_field_with_the_commands_line_and_clearing_it_clears_it(tmp_path):
    opened = open_world("Gym/Four_Cylinders", [])
    data = copy.deepcopy(opened["data"])
    data["scenario"]["volumes"][1]["geometries"][0]["dimensions"] = [1.5, 1.5, -2.0]
    file = tmp_path / "Gym" / "Bad_Cylinder.json"
    file.parent.mkdir()
    save_document(data, file)

    found = check_world(data, str(file), [])
    assert found["scene"] is None
    [error] = found["diagnostics"]
    assert error["severity"] == "error" and error["path"] == f"{DIMENSIONS}[2]"
    assert error["message"].startswith("must be positive")
    done = magna_world("check", str(file))
    assert done.returncode == 2
    assert done.stderr.splitlines() == [f"magna world: {error['line']}"]

    data["scenario"]["volumes"][1]["geometries"][0]["dimensions"] = [1.5, 1.5, 2.0]
    cleared = check_world(data, str(file), [])
    assert cleared["diagnostics"] == [] and cleared["scene"] is not None


def test_warnings_are_placed_on_their_fields_with_the_commands_lines(tmp_path):
    data = copy.deepcopy(open_world("Gym/Four_Cylinders", [])["data"])
    data["scenario"]["volumes"][1]["geometries"][0]["colour"] = [0, 0, 255]
    data["scenario"]["volumes"][0]["note: why"] = "a key with a colon and a space"
    data["scenario"]["world_boundaries"][2] = [0, 3]  # the take-off line 4 m up is outside now
    file = save_document(data, tmp_path / "Loose.json")
    found = check_world(data, str(file), [])
    assert found["scene"] is not None and errors(found) == []
    paths = [d["path"] for d in found["diagnostics"]]
    assert "scenario.volumes[1].geometries[0].colour" in paths
    assert "scenario.volumes[0].note: why" in paths  # the loader keeps the path: no guess from the text
    assert "scenario.volumes[0].geometries[1].poses_sets[0]" in paths
    done = magna_world("check", str(file))
    assert done.returncode == 0
    assert [f"magna world: {d['line']}" for d in found["diagnostics"]] == done.stderr.splitlines()


def test_an_older_world_is_migrated_and_its_findings_placed_on_the_migrated_fields(tmp_path):
    division = {"type": "matrix", "use": "poses", "dimensions": [2, 1, 1], "orientation": [0, 0, 0], "spin": 1}
    legacy = {"scenario": {"world_boundaries": [[-5, 5], [-5, 5], [0, 5]], "volumes": [
        {"name": "Zone", "prefix": "Z", "origin": [[0, 0, 0], [0, 0, 0]], "geometries": [
            {"name": "Box", "prefix": "B", "shape": "cube", "origin": [[0, 0, 1], [0, 0, 0]],
             "dimensions": [2, 2, 2], "divisions": [division]}]}]}}
    (tmp_path / "Old").mkdir()
    file = tmp_path / "Old" / "Boxes.json"
    file.write_text(json.dumps(legacy))
    opened = open_world(str(file), [])
    geometry = opened["data"]["scenario"]["volumes"][0]["geometries"][0]
    assert "divisions" not in geometry and geometry["poses_sets"][0]["poses_orientation"] == [0, 0, 0]
    assert geometry["poses_sets"][0]["matrix_type"] == "dimension"
    assert f"{file}: scenario.volumes[0].geometries[0].divisions -> poses_sets" in opened["changes"]
    assert len(opened["changes"]) == 3
    [warning] = opened["diagnostics"]
    assert warning["path"] == "scenario.volumes[0].geometries[0].poses_sets[0].spin"
    assert warning["line"] == f"warning: {file}: scenario.volumes[0].geometries[0].divisions[0].spin: unknown field, " \
                              "ignored"  # the command's words about the file as written
    [pose_set] = [item for item in opened["scene"]["items"] if item["kind"] == "pose_set"]
    assert pose_set["path"] == "scenario.volumes[0].geometries[0].poses_sets[0]"
    assert check_world(opened["data"], str(file), [])["diagnostics"][0]["path"] == warning["path"]


def test_parts_of_an_included_world_are_drawn_but_belong_to_their_own_file():
    opened = open_world("Inspection/Complete", [])
    assert opened["diagnostics"] == []
    own = ROOT / "worlds" / "Inspection" / "Complete.json"
    files = {item["file"] for item in opened["scene"]["items"]}
    assert str(own) in files and len(files) > 1
    for item in opened["scene"]["items"]:
        assert (item["path"] != "") == (item["file"] == str(own))


def test_the_scene_is_the_geometry_magna_worlds_gives_rviz():
    path = ROOT / "worlds" / "Gym" / "Central_Obstacle_Torus.json"  # cubes, cylinders, a torus, obstacles
    resolved = resolve_world_data(json.loads(path.read_text()), str(path), [], seed=3)
    scene = world_scene(resolved)
    markers = world_markers([resolved]).markers[1:]
    shapes = {1: "cube", 2: "sphere", 3: "cylinder", 4: "line", 7: "points", 11: "triangles"}
    micrometre = {"abs": 1e-6, "rel": 0}  # the scene's precision
    for item, marker in zip(scene["items"], markers, strict=True):
        assert item["shape"] == shapes[marker.type]
        assert item["position"] == pytest.approx([marker.pose.position.x, marker.pose.position.y,
                                                  marker.pose.position.z], **micrometre)
        turn = marker.pose.orientation
        assert item["orientation"] == pytest.approx([turn.x, turn.y, turn.z, turn.w], **micrometre)
        assert item["scale"] == pytest.approx([marker.scale.x, marker.scale.y, marker.scale.z], **micrometre)
        assert item["color"] == pytest.approx([marker.color.r, marker.color.g, marker.color.b, marker.color.a],
                                              **micrometre)
        points = np.array(item.get("points", []), dtype=float).reshape(-1, 3)
        assert np.allclose(points, [[p.x, p.y, p.z] for p in marker.points] or np.empty((0, 3)), rtol=0, atol=1e-6)

    by_path = {(item["kind"], item["path"]): item for item in scene["items"]}
    take_off = by_path["geometry", "scenario.volumes[0].geometries[0]"]  # a cube 8 x 1 x 0.1 at (0, -11, 0.05)
    assert take_off["shape"] == "cube" and take_off["frame"] == "GS_Agents_take_off"
    assert take_off["position"] == [0.0, -11.0, 0.05] and take_off["scale"] == [8.0, 1.0, 0.1]
    assert take_off["color"] == pytest.approx([30 / 255, 30 / 255, 30 / 255, 0.5])
    poses = by_path["pose_set", "scenario.volumes[0].geometries[0].poses_sets[0]"]
    placed = resolved.geometry("Ground_Station", "Agents_take_off")
    assert np.allclose(poses["points"], placed.poses()[0].positions, rtol=0, atol=1e-6)
    assert poses["frames"] == placed.poses()[0].frames
    torus = next(i for i in scene["items"] if i["kind"] == "geometry" and i["name"] == "Accessible")
    assert torus["shape"] == "triangles" and len(torus["points"]) % 3 == 0 and len(torus["points"]) > 300
    obstacles = [item for item in scene["items"] if item["kind"] == "obstacle"]
    assert [o["name"] for o in obstacles] == [o.name for o in resolved.obstacles()]
    assert all(o["path"].startswith("scenario.volumes[2].geometries[1].poses_sets[") for o in obstacles)
    assert np.allclose([o["position"] for o in obstacles], [o.position for o in resolved.obstacles()], rtol=0,
                       atol=1e-6)


def test_a_new_world_loads_without_a_warning_even_strictly():
    data = new_world()
    assert check_world(data, "New/World.json", [])["diagnostics"] == []
    world_from_data(data, "New/World.json", strict=True)  # raises at what would be a warning
    assert len(pose_choices(data, "New/World.json", [])) == 4  # two volumes, a geometry each


def test_every_pose_choice_resolves_in_its_world():
    path = ROOT / "worlds" / "SolarPlant" / "Panels.json"  # matrices, zigzags, several sets of poses
    data = json.loads(path.read_text())
    resolved = resolve_world_data(data, str(path), [])
    choices = pose_choices(data, str(path), [])
    assert {(c["volume"], c["geometry"]) for c in choices} == \
        {(v.name, "volume") for v in resolved.world.volumes} | \
        {(g.volume.name, g.geometry.name) for g in resolved.geometries}
    queries = PoseQueries(0)
    for choice in choices:
        assert [example[2] for example in choice["examples"]] == choice["kinds"]
        for example in choice["examples"]:
            assert len(queries.resolve([resolved], example).positions) >= 1
        for cell in choice["matrix_cells"]:
            queries.resolve([resolved], [choice["volume"], choice["geometry"], "matrix", cell])
    assert any(c["paths"] for c in choices) and any("matrix" in c["kinds"] for c in choices)


def test_a_world_that_does_not_load_offers_no_pose_choices():
    data = new_world()
    data["scenario"]["volumes"][0]["geometries"][0]["shape"] = "cone"
    assert pose_choices(data, "New/World.json", []) == []


def test_a_world_that_cannot_be_opened_is_a_design_error_naming_the_file(tmp_path):
    with pytest.raises(DesignError, match="Gym/Nowhere: no such file, nor a world"):
        open_world("Gym/Nowhere", [])
    broken = tmp_path / "Broken.json"
    broken.write_text('{"scenario": [')
    with pytest.raises(DesignError, match=f"{broken}: not valid JSON"):
        open_world(str(broken), [])
