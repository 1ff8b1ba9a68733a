"""Airframe files: the shipped ones load, the corpus ones load, bad ones say where they are wrong."""
import json
from pathlib import Path

import pytest

from magna_common.airframes import AirframeError, available_models, load_airframe
from tests.support import CORPUS as CORPUS_ROOT

CORPUS = CORPUS_ROOT / "Agent_Configurations"


def test_every_shipped_airframe_has_physics():
    models = available_models()
    assert {"iris", "typhoon_h480", "f550", "crazyflie", "plane"} <= set(models)
    for model in models:
        frame = load_airframe(model)
        frame.require_physics()
        assert frame.body.mass > 0 and len(frame.body.inertia) == 3


def test_shipped_airframes_keep_the_original_fields_of_the_corpus():
    paths = sorted(CORPUS.glob("*.json"))
    assert len(paths) == 5, f"the corpus airframes are missing from {CORPUS}"
    for path in paths:
        original = json.loads(path.read_text())
        ours = json.loads((Path(load_airframe(path.stem).source)).read_text())
        assert {k: ours[k] for k in original} == original, path.name


def test_a_corpus_file_loads_without_physics_and_is_refused_for_simulation():
    frame = load_airframe("f550", CORPUS)
    assert frame.extra == {"laser_altimeter": False, "self_arming": True}
    with pytest.raises(AirframeError, match=r"f550.json: 'body': missing"):
        frame.require_physics()


@pytest.mark.parametrize("change, message", [
    (lambda d: d.pop("safety_radius"), r"'safety_radius': missing"),
    (lambda d: d["body"].update(mass=-1), r"'body.mass': must be positive"),
    (lambda d: d["body"].update(inertia=[1, 2]), r"'body.inertia': expected 3 numbers"),
    (lambda d: d["limits"].update(max_tilt=float("nan")), r"'limits.max_tilt': expected a finite number"),
    (lambda d: d["battery"].update(volts=3), r"'battery.volts': unknown key"),
    (lambda d: d["body"].update(rotors=2), r"'body.rotors': expected 0 \(fixed wing\) or 3 or more"),
])
def test_bad_fields_are_named(tmp_path, change, message):
    data = json.loads(Path(load_airframe("iris").source).read_text())
    change(data)
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(AirframeError, match=message):
        load_airframe("bad", tmp_path)


def test_unknown_model_lists_the_known_ones():
    with pytest.raises(AirframeError, match="no such airframe; known models: .*iris"):
        load_airframe("zeppelin")


@pytest.mark.parametrize("change, message", [
    (lambda d: d["fixed_wing"].update(min_speed=7.0), r"'fixed_wing.min_speed': 7 m/s must be above fixed_wing.stall"),
    (lambda d: d["fixed_wing"].update(cruise_speed=25.0), r"'fixed_wing.max_speed': 20 m/s must be above"),
    (lambda d: d["fixed_wing"].update(loiter_radius=15.0), r"'fixed_wing.loiter_radius': 15 m is tighter than the "
                                                           r"23.0 m turn"),
    (lambda d: d.update(accepted_target_radius=40), r"'accepted_target_radius': 40 m is not beyond the 40 m loiter"),
    (lambda d: d["fixed_wing"].pop("landing_slope"), r"'fixed_wing.landing_slope': missing"),
    (lambda d: d["fixed_wing"].update(max_climb_rate=12.0), r"'fixed_wing.max_climb_rate': 12 m/s; give a positive"),
    (lambda d: d["battery"].update(hover_power_w=90.0), r"'battery.hover_power_w': a fixed wing cannot hover"),
    (lambda d: d["battery"].pop("cruise_power_w"), r"'battery.cruise_power_w': missing"),
    (lambda d: d["body"].update(rotors=4), r"'body.rotors': 4, but the file has a fixed_wing block"),
    (lambda d: d.pop("fixed_wing"), r"'fixed_wing': missing; body.rotors = 0 makes a fixed wing"),
])
def test_bad_fixed_wing_fields_are_named(tmp_path, change, message):
    data = json.loads(Path(load_airframe("plane").source).read_text())
    change(data)
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(AirframeError, match=message) as refused:
        load_airframe("bad", tmp_path)
    assert "bad.json" in str(refused.value)


def test_the_plane_is_a_fixed_wing_that_cannot_stop_on_a_waypoint():
    plane = load_airframe("plane")
    assert plane.is_fixed_wing and not load_airframe("iris").is_fixed_wing
    fw = plane.fixed_wing
    assert fw.stall_speed < fw.min_speed <= fw.cruise_speed <= fw.max_speed
    assert fw.min_turn_radius() <= fw.loiter_radius < plane.accepted_target_radius
