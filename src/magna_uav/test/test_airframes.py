"""Airframe files: the shipped ones load, the corpus ones load, bad ones say where they are wrong."""
import json
from pathlib import Path

import pytest

from magna_uav.airframes import AirframeError, available_models, load_airframe
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
