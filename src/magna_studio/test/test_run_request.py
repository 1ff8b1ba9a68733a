"""What the page may ask `magna run` for: the request is checked before anything is written or started."""
import pytest

from magna_studio.run_control import RunError, RunRequest, StudioRun

WORLD = {"data": {"scenario": {}}, "name": "Gym/My_World"}
MISSION = {"data": {"States": []}, "name": "Gym/My_Mission"}


def test_a_whole_request_is_read_with_its_defaults():
    request = RunRequest.from_json({"world": WORLD, "mission": MISSION, "n_iter": 3, "rtf": "max", "seed": 7})
    assert (request.n_iter, request.rtf, request.seed, request.name) == (3, "max", 7, "studio")


@pytest.mark.parametrize(("change", "message"), [
    ({"world": None}, "world: give"),
    ({"mission": {"data": [], "name": "Gym/M"}}, "mission: give"),
    ({"n_iter": 0}, "n_iter is 0"),
    ({"n_iter": True}, "n_iter is True"),
    ({"seed": 1.5}, "seed is 1.5"),
    ({"rtf": "fast"}, "rtf is 'fast'"),
    ({"rtf": "-1"}, "rtf is '-1'"),
    ({"name": "../up"}, "name"),
])
def test_a_bad_request_names_the_field_and_the_fix(change, message):
    with pytest.raises(RunError, match=message.replace("(", r"\(")):
        RunRequest.from_json({"world": WORLD, "mission": MISSION, **change})


@pytest.mark.parametrize("name", ["My_World", "Gym/Sub/World", "Gym/..", "/World"])
def test_a_name_must_be_family_and_name_before_anything_is_written(tmp_path, name):
    run = StudioRun(tmp_path / "magna", tmp_path / "runs", tmp_path / "data", [], origin="http://127.0.0.1:1")
    with pytest.raises(RunError, match="world name"):
        run.start(RunRequest.from_json({"world": {**WORLD, "name": name}, "mission": MISSION}))
    assert not (tmp_path / "runs").exists()
    assert run.status() == {"state": "idle"}
