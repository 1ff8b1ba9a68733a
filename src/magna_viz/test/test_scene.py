"""The UAV scene (magna_viz.scene): colours from the mission, trails, paths and goals, without a master."""
from __future__ import annotations

import json

import pytest
from visualization_msgs.msg import Marker, MarkerArray

from magna_viz.scene import (
    NAMESPACES,
    Scene,
    UavStyle,
    is_clear_only,
    rgba_from_marker_color,
    styles_from_mission,
)
from tests.support import ROOT

MISSION = ROOT / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json"
RED = UavStyle(1, (1.0, 0.0, 0.0, 0.5), body_radius=0.3, safety_radius=0.4)
GREEN = UavStyle(2, (0.0, 1.0, 0.0, 0.5))


def by_key(array: MarkerArray) -> dict[tuple[str, int], Marker]:
    return {(m.ns, m.id): m for m in array.markers}


def rgb(marker: Marker) -> tuple[float, float, float]:
    return (round(marker.color.r, 3), round(marker.color.g, 3), round(marker.color.b, 3))


def test_marker_colour_converts_0_255_channels_and_keeps_alpha():
    assert rgba_from_marker_color([255, 0, 0, 0.5]) == (1.0, 0.0, 0.0, 0.5)
    assert rgba_from_marker_color([51, 102, 255, 1]) == pytest.approx((0.2, 0.4, 1.0, 1.0))
    with pytest.raises(ValueError, match=r"\[r, g, b, a\]"):
        rgba_from_marker_color([255, 0, 0])


def test_styles_come_from_the_mission_and_its_airframes():
    mission = json.loads(MISSION.read_text())["Agents_Config"]
    styles = styles_from_mission(MISSION)
    assert [s.id for s in styles] == [a["ID"] for a in mission]
    for style, agent in zip(styles, mission, strict=True):
        r, g, b, a = agent["marker_color"]
        assert style.rgba == pytest.approx((r / 255, g / 255, b / 255, a))
        assert style.safety_radius == 0.3 and style.body_radius == 0.3  # iris.json


def test_bad_mission_entries_are_refused_with_the_file_named(tmp_path):
    bad = tmp_path / "m.json"
    bad.write_text(json.dumps({"Agents_Config": [{"ID": 1, "model": "iris", "mode": "sitl",
                                                  "marker_color": [300, 0, 0, 1]}], "State_Machine": []}))
    with pytest.raises(ValueError, match=r"m.json.*marker_color\[0\]"):
        styles_from_mission(bad)


def test_a_uav_is_drawn_in_its_colour_once_it_has_a_pose():
    scene = Scene([RED, GREEN])
    before = by_key(scene.markers())
    assert before[("body", 1)].action == Marker.DELETE and before[("trail", 1)].action == Marker.DELETE

    scene.update_pose(1, (1.0, 2.0, 3.0), (0, 0, 0.7071, 0.7071), stamp=1.0)
    markers = by_key(scene.markers())
    body = markers[("body", 1)]
    assert body.action == Marker.ADD and body.type == Marker.CYLINDER and body.header.frame_id == "map"
    assert (body.pose.position.x, body.pose.position.y, body.pose.position.z) == (1.0, 2.0, 3.0)
    assert body.pose.orientation.z == pytest.approx(0.7071)
    assert rgb(body) == (1.0, 0.0, 0.0) and body.color.a == 1.0  # opaque, whatever the mission's alpha
    safety = markers[("safety", 1)]
    assert safety.type == Marker.SPHERE and safety.scale.x == pytest.approx(0.8)  # true size: 2 x safety radius
    assert rgb(safety) == (1.0, 0.0, 0.0) and 0 < safety.color.a < 1
    assert markers[("label", 1)].text == "uav_1"
    assert markers[("label", 1)].pose.position.z > 3.0
    assert markers[("body", 2)].action == Marker.DELETE  # uav 2 has not been seen
    assert {ns for ns, _ in markers} <= set(NAMESPACES)


def test_the_trail_grows_by_steps_and_is_a_line_in_the_uav_colour():
    scene = Scene([GREEN], trail_step=0.5)
    for i in range(11):  # every 0.3 m: one in two becomes a trail point
        scene.update_pose(2, (0.3 * i, 0.0, 2.0), stamp=float(i))
    trail = by_key(scene.markers())[("trail", 2)]
    assert trail.type == Marker.LINE_STRIP and trail.action == Marker.ADD
    assert [round(p.x, 3) for p in trail.points] == [0.0, 0.6, 1.2, 1.8, 2.4, 3.0]
    assert rgb(trail) == (0.0, 1.0, 0.0) and trail.color.a == 1.0 and trail.scale.x > 0


def test_the_trail_keeps_the_last_points_when_capped():
    scene = Scene([GREEN], trail_step=0.0, max_trail=3)
    for i in range(6):
        scene.update_pose(2, (float(i), 0.0, 1.0), stamp=float(i))
    assert [p.x for p in by_key(scene.markers())[("trail", 2)].points] == [3.0, 4.0, 5.0]


def test_time_going_back_restarts_the_trails_and_clears_rviz():
    scene = Scene([RED])
    scene.update_pose(1, (0, 0, 1), stamp=10.0)
    scene.update_pose(1, (5, 0, 1), stamp=20.0)
    scene.update_path(1, [(0, 0, 1), (5, 0, 1)], smoothed=True)
    scene.markers()
    scene.update_pose(1, (0, 0, 0), stamp=1.0)  # the bag started again
    array = scene.markers()
    assert array.markers[0].action == Marker.DELETEALL
    markers = by_key(array)
    assert markers[("trail", 1)].action == Marker.DELETE  # one point only, so far
    assert markers[("path_smoothed", 1)].action == Marker.DELETE
    assert markers[("body", 1)].pose.position.x == 0.0
    assert scene.markers().markers[0].action != Marker.DELETEALL  # cleared once


def test_paths_and_goal_are_drawn_in_the_uav_colour():
    scene = Scene([RED, GREEN])
    raw = [(0, 0, 2), (4, 0, 2), (4, 4, 2)]
    smooth = [(0, 0, 2), (3.5, 0.2, 2), (4, 0.5, 2), (4, 4, 2)]
    scene.update_path(1, raw, smoothed=False)
    scene.update_path(1, smooth, smoothed=True)
    scene.update_pose(1, (1, 0, 2), stamp=1.0)
    scene.update_goal(1, (4, 0, 2))
    markers = by_key(scene.markers())
    raw_line, smooth_line = markers[("path_raw", 1)], markers[("path_smoothed", 1)]
    assert raw_line.type == smooth_line.type == Marker.LINE_STRIP
    assert [(p.x, p.y, p.z) for p in raw_line.points] == [tuple(map(float, p)) for p in raw]
    assert [(p.x, p.y) for p in smooth_line.points] == [(p[0], p[1]) for p in smooth]
    waypoints = [m for (ns, _), m in markers.items() if ns == "path_raw" and m.type == Marker.SPHERE_LIST]
    assert len(waypoints) == 1 and len(waypoints[0].points) == 3
    assert rgb(raw_line) == rgb(smooth_line) == (1.0, 0.0, 0.0)
    goal = markers[("goal", 1)]
    assert goal.type == Marker.SPHERE and (goal.pose.position.x, goal.pose.position.y) == (4.0, 0.0)
    assert goal.color.r == 1.0 and goal.color.g == goal.color.b  # a lighter red
    to_goal = [m for (ns, _), m in markers.items() if ns == "goal" and m.type == Marker.LINE_STRIP]
    assert [(p.x, p.y) for p in to_goal[0].points] == [(1.0, 0.0), (4.0, 0.0)]
    # uav 2 has none of them
    assert markers[("path_raw", 2)].action == markers[("goal", 2)].action == Marker.DELETE
    # ids are unique per namespace
    assert len(markers) == len(scene.markers().markers)


def test_updates_set_changed_and_drawing_clears_it():
    scene = Scene([RED])
    scene.markers()
    assert not scene.changed
    scene.update_goal(7, (0, 0, 0))  # not a UAV of the mission: ignored
    scene.update_pose(7, (0, 0, 0))
    assert not scene.changed and scene.ids == [1]
    scene.update_goal(1, (0, 0, 1))
    assert scene.changed


def test_scale_grows_the_drawing_but_not_the_safety_sphere():
    small, big = Scene([RED]), Scene([RED], scale=4.0)
    for scene in (small, big):
        scene.update_pose(1, (0, 0, 1), stamp=0.0)
        scene.update_pose(1, (1, 0, 1), stamp=1.0)
    s, b = by_key(small.markers()), by_key(big.markers())
    assert b[("body", 1)].scale.x == pytest.approx(4 * s[("body", 1)].scale.x)
    assert b[("trail", 1)].scale.x == pytest.approx(4 * s[("trail", 1)].scale.x)
    assert b[("safety", 1)].scale.x == s[("safety", 1)].scale.x
    with pytest.raises(ValueError):
        Scene([RED], scale=0)


def test_a_world_message_that_only_deletes_is_recognised():
    clear = MarkerArray(markers=[Marker(action=Marker.DELETEALL)])
    world = MarkerArray(markers=[Marker(action=Marker.DELETEALL), Marker(action=Marker.ADD, type=Marker.CUBE)])
    assert is_clear_only(clear) and not is_clear_only(world)
