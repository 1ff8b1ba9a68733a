"""The rviz configurations: the shipped files, the choice by world family, the fitted camera, the headless copy."""
from __future__ import annotations

import copy
import json
import math

import pytest

from magna_common.records import WorldRecord
from magna_common.ros_names import VIZ_SCENE
from magna_viz import rviz_config as rc
from magna_viz.replay.plan import view_box
from magna_viz.scene import NAMESPACES

CONFIGS = sorted(rc.RVIZ_DIR.glob("*.rviz"))


def displays(config: dict) -> list[dict]:
    return config["Visualization Manager"]["Displays"]


def test_every_family_has_its_configuration():
    assert {p.name for p in CONFIGS} == {f.config for f in rc.FAMILIES.values()}


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_a_configuration_shows_the_world_the_uavs_and_tf_in_map(path):
    config = rc.load_config(path)
    manager = config["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    by_class = {}
    for display in displays(config):
        by_class.setdefault(display["Class"], []).append(display)
    assert {"rviz/Grid", "rviz/TF", "rviz/MarkerArray"} <= set(by_class)
    topics = {d["Marker Topic"]: d for d in by_class["rviz/MarkerArray"]}
    assert set(topics) == {"/magna/world/markers", VIZ_SCENE}
    assert set(topics[VIZ_SCENE]["Namespaces"]) == set(NAMESPACES)
    assert all(d["Enabled"] for d in displays(config))
    assert manager["Views"]["Current"]["Class"] == "rviz/Orbit"


@pytest.mark.parametrize("world, expected", [
    ("Gym", "gym.rviz"), ("gym", "gym.rviz"), ("Delivery", "delivery.rviz"), ("SolarPlant", "solar_plant.rviz"),
    ("Solar_Plant", "solar_plant.rviz"), ("Inspection", "inspection.rviz"),
])
def test_the_world_family_picks_the_configuration(world, expected):
    choice = rc.choose_config(world)
    assert choice.path == rc.RVIZ_DIR / expected and choice.path.is_file() and choice.note == ""


def test_an_unknown_world_falls_back_to_the_gym_and_says_so(tmp_path):
    choice = rc.choose_config("Tube")
    assert choice.path.name == "gym.rviz" and "Tube" in choice.note and "gym.rviz" in choice.note
    assert "not known" in rc.choose_config("").note
    mine = tmp_path / "mine.rviz"
    assert rc.choose_config("Gym", override=mine).path == mine


def test_the_world_of_a_simulation_folder(tmp_path):
    sim = tmp_path / "Simulations" / "Delivery" / "Delivery" / "M" / "S" / "default" / "dataset_1" / "simulation_1"
    sim.mkdir(parents=True)
    assert rc.world_of_sim_dir(sim) == "Delivery"  # from the storage path
    (sim / "result.json").write_text(json.dumps({"hyperparameters": {"world": "SolarPlant"}}))
    assert rc.world_of_sim_dir(sim) == "SolarPlant"  # result.json says better
    assert rc.world_of_sim_dir(tmp_path) == ""


def test_the_headless_copy_has_no_panels_and_fills_the_screen():
    original = rc.load_config(rc.RVIZ_DIR / "gym.rviz")
    pristine = copy.deepcopy(original)
    view = rc.OrbitView((1.0, 2.0, 3.0), 42.0, -2.0, 0.75)
    headless = rc.adapt(original, view=view, headless=(960, 540))
    assert headless["Panels"] == []
    assert headless["Window Geometry"] == {"Height": 540, "Width": 960, "X": 0, "Y": 0, "Hide Left Dock": True,
                                       "Hide Right Dock": True}
    current = headless["Visualization Manager"]["Views"]["Current"]
    assert current["Focal Point"] == {"X": 1.0, "Y": 2.0, "Z": 3.0} and current["Distance"] == 42.0
    assert (current["Yaw"], current["Pitch"]) == (-2.0, 0.75)
    assert original == pristine and original["Panels"]  # the original is untouched
    assert rc.adapt(original, view=view)["Panels"] == original["Panels"]  # on a display: panels stay


def test_a_written_configuration_reads_back(tmp_path):
    config = rc.adapt(rc.load_config(rc.RVIZ_DIR / "delivery.rviz"), headless=(640, 480),
                      grid_box=((0, 100), (-10, 10), (0, 5)))
    path = rc.write_config(config, tmp_path / "x.rviz")
    assert rc.load_config(path) == config
    grid = next(d for d in displays(config) if d["Class"] == "rviz/Grid")
    assert grid["Cell Size"] == 5.0 and grid["Plane Cell Count"] * grid["Cell Size"] >= 100
    assert grid["Offset"] == {"X": 50.0, "Y": 0.0, "Z": 0.0}
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_not_an_rviz_file_is_refused(tmp_path):
    bad = tmp_path / "bad.rviz"
    bad.write_text("just: [a, list")
    with pytest.raises(rc.ConfigError, match="bad.rviz"):
        rc.load_config(bad)
    bad.write_text("Panels: []\n")
    with pytest.raises(rc.ConfigError, match="Visualization Manager"):
        rc.load_config(bad)


def project(view: rc.OrbitView, point, aspect: float):
    """Where a look-at camera at rviz's orbit position puts a point: (x, y), -1..1 across the picture."""
    yaw, pitch = view.yaw, view.pitch
    back = (math.cos(yaw) * math.cos(pitch), math.sin(yaw) * math.cos(pitch), math.sin(pitch))
    eye = [f + view.distance * b for f, b in zip(view.focal, back, strict=True)]
    forward = [-b for b in back]

    def cross(a, b):
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    def dot(a, b):
        return sum(x * y for x, y in zip(a, b, strict=True))

    right = cross(forward, [0.0, 0.0, 1.0])
    right = [r / math.sqrt(dot(right, right)) for r in right]
    up = cross(right, forward)
    rel = [p - e for p, e in zip(point, eye, strict=True)]
    depth = dot(rel, forward)
    tan_y = math.tan(rc.FOV_Y / 2)
    return dot(rel, right) / (depth * tan_y * aspect), dot(rel, up) / (depth * tan_y)


@pytest.mark.parametrize("box, yaw, pitch, aspect", [
    (((-12, 12), (-14, 12), (0, 8)), -2.0, 0.75, 16 / 9),
    (((-90, 80), (-70, 50), (0, 30)), -2.0, 0.7, 4 / 3),
    (((0, 2), (0, 50), (0, 1)), 0.3, 1.2, 1.0),
])
def test_the_fitted_camera_sees_the_whole_box_and_no_more_than_it_must(box, yaw, pitch, aspect):
    view = rc.fit_orbit(box, yaw, pitch, aspect)
    assert (view.yaw, view.pitch) == (yaw, pitch)
    corners = [(x, y, z) for x in box[0] for y in box[1] for z in box[2]]
    xy = [project(view, c, aspect) for c in corners]
    assert all(abs(x) <= 1.0 + 1e-6 and abs(y) <= 1.0 + 1e-6 for x, y in xy)  # everything in the picture
    # tight: the box reaches an edge of the picture, and it is centred
    assert max(max(abs(x), abs(y)) for x, y in xy) > 0.97
    xs, ys = [x for x, _ in xy], [y for _, y in xy]
    assert abs(max(xs) + min(xs)) < 0.05 and abs(max(ys) + min(ys)) < 0.05


def test_the_view_box_is_the_world_inside_its_boundaries_and_the_flights():
    world = WorldRecord.from_dict({"parts": {"main": {
        "world_boundaries": [[-20, 20], [-20, 20], [0, 10]],
        "geometries": [{"position": [0, 0, 1], "dimensions": [4, 4, 2]},
                       {"position": [0, 0, 0], "dimensions": [1000, 1000, 0.1]}],  # a huge ground, clipped
        "obstacles": []}}}, "world.json")
    flights = ((-1.0, 30.0), (0.0, 1.0), (0.0, 3.0))  # a flight beyond the boundaries still shows
    box = view_box(world, flights, "world")
    assert box[0][0] < -19 and box[0][1] > 30 and box[1][0] < -19 and box[1][1] > 19
    assert view_box(world, flights, "uavs")[1][1] < 5
    assert view_box(world, flights, "none") is None
    assert view_box(None, None, "world") is None
    bounds_only = WorldRecord.from_dict({"parts": {"main": {"world_boundaries": [[0, 10], [0, 10], [0, 5]]}}}, "w")
    only_bounds = view_box(bounds_only, None, "world")
    assert only_bounds[0][0] < 0 and only_bounds[0][1] > 10
