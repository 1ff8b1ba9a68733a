"""UAV configurations: every real mission's agents load; each bad entry is named by file and JSON path."""
import copy
import json

import pytest

from magna_common.airframes import load_airframe
from magna_uav.config import ConfigError, UavConfig, configs_from_mission, configs_from_mission_file
from tests.support import CORPUS

MISSIONS = sorted((CORPUS / "Missions").glob("*/*.json"))
SOURCE = "missions/x.json"
GOOD = {"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5], "ual_use": True,
        "agent_manager_on_gs": True}


def test_the_corpus_has_missions_in_both_schemas():
    keys = {next(k for k in json.loads(p.read_text()) if k.endswith("_Config")) for p in MISSIONS}
    assert len(MISSIONS) >= 9, f"the corpus missions are missing from {CORPUS}"
    assert keys == {"Agents_Config", "UAVs_Config"}


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_corpus_mission_loads(path):
    raw = json.loads(path.read_text())
    entries = raw.get("Agents_Config", raw.get("UAVs_Config"))
    configs = configs_from_mission_file(path)
    assert [c.id for c in configs] == [e["ID"] for e in entries]
    for config, entry in zip(configs, entries, strict=True):
        assert isinstance(config, UavConfig)
        assert config.model == entry["model"] and config.mode == entry["mode"]
        assert config.marker_color == tuple(entry["marker_color"])
        assert config.ual_use is entry["ual_use"]
        assert config.manager_on_gs is entry.get("agent_manager_on_gs", entry.get("uav_manager_on_gs"))
        assert config.safety_radius == load_airframe(entry["model"]).safety_radius


def test_config_merges_the_airframe_and_the_entry():
    (config,) = configs_from_mission([dict(GOOD, ID=4, model="crazyflie", marker_color=[0, 51, 255, 1])], SOURCE)
    frame = load_airframe("crazyflie")
    assert config.airframe == frame
    assert (config.safety_radius, config.max_speed, config.accepted_target_radius, config.autopilot) == \
        (frame.safety_radius, frame.max_speed, frame.accepted_target_radius, frame.autopilot)
    assert config.name == "uav_4"
    assert config.marker_rgba == pytest.approx((0.0, 0.2, 1.0, 1.0))
    with pytest.raises(AttributeError):
        config.id = 5  # frozen


def test_optional_keys_take_their_defaults_and_legacy_names():
    entry = {k: v for k, v in GOOD.items() if k not in ("ual_use", "agent_manager_on_gs")}
    (config,) = configs_from_mission([entry], SOURCE)
    assert config.ual_use is bool(load_airframe("iris").ual_use) and config.manager_on_gs is True
    (legacy,) = configs_from_mission([dict(entry, uav_manager_on_gs=False, ual_use=False)], SOURCE, "UAVs_Config")
    assert legacy.manager_on_gs is False and legacy.ual_use is False


@pytest.mark.parametrize("change, message", [
    (lambda e: e.pop("mode"), r"^missions/x.json: Agents_Config\[1\]\.mode: missing"),
    (lambda e: e.update(mode="simulation"),
     r"^missions/x.json: Agents_Config\[1\]\.mode: 'simulation' is not one of sitl, hil, real$"),
    (lambda e: e.update(colour=[1, 2, 3, 1]),
     r"Agents_Config\[1\]\.colour: unknown key; did you mean 'marker_color'\?"),
    (lambda e: e.update(ID="2"), r"Agents_Config\[1\]\.ID: expected a whole number 0 or more, got '2'"),
    (lambda e: e.update(ID=True), r"Agents_Config\[1\]\.ID: expected a whole number"),
    (lambda e: e.update(ID=1), r"Agents_Config\[1\]\.ID: 1 is already the ID of Agents_Config\[0\]"),
    (lambda e: e.update(model="irris"),
     r"Agents_Config\[1\]\.model: 'irris' is not a known airframe; did you mean 'iris'\? "
     r"known: crazyflie, f550, iris, plane, typhoon_h480"),
    (lambda e: e.update(model=3), r"Agents_Config\[1\]\.model: expected an airframe name"),
    (lambda e: e.update(marker_color=[255, 0, 0]), r"Agents_Config\[1\]\.marker_color: expected \[r, g, b, a\]"),
    (lambda e: e.update(marker_color=[256, 0, 0, 1]), r"Agents_Config\[1\]\.marker_color\[0\]: 256 is outside 0..255"),
    (lambda e: e.update(marker_color=[255, 0, 0, 50]),
     r"Agents_Config\[1\]\.marker_color\[3\]: 50 is outside 0..1 \(alpha\)"),
    (lambda e: e.update(marker_color=[0, "0", 0, 1]), r"Agents_Config\[1\]\.marker_color\[1\]: .*'0' is not a number"),
    (lambda e: e.update(ual_use="yes"), r"Agents_Config\[1\]\.ual_use: expected true or false, got 'yes'"),
    (lambda e: e.update(uav_manager_on_gs=True),
     r"Agents_Config\[1\]\.uav_manager_on_gs: give agent_manager_on_gs or its legacy name"),
])
def test_bad_entries_are_named(change, message):
    second = dict(GOOD, ID=2)
    change(second)
    with pytest.raises(ConfigError, match=message):
        configs_from_mission([copy.deepcopy(GOOD), second], SOURCE)


def test_the_list_and_its_entries_must_have_the_right_shape():
    with pytest.raises(ConfigError, match=r"^m.json: UAVs_Config: expected a list of agent entries .*got an object"):
        configs_from_mission({"ID": 1}, "m.json", "UAVs_Config")
    with pytest.raises(ConfigError, match=r"^m.json: Agents_Config\[0\]: expected an object with ID, model"):
        configs_from_mission([3], "m.json")


def test_a_broken_airframe_file_is_named(tmp_path):
    (tmp_path / "iris.json").write_text('{"autopilot": "px4"}')
    with pytest.raises(ConfigError, match=r"Agents_Config\[0\]\.model: airframe 'iris' does not load: .*"
                                          r"iris.json: 'ual_use': missing"):
        configs_from_mission([GOOD], SOURCE, airframe_dir=tmp_path)


def test_mission_files_name_their_path(tmp_path):
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"State_Machine": []}))
    with pytest.raises(ConfigError, match=r"m.json: Agents_Config: missing; .* legacy UAVs_Config"):
        configs_from_mission_file(path)
    path.write_text(json.dumps({"Agents_Config": [GOOD], "UAVs_Config": [GOOD]}))
    with pytest.raises(ConfigError, match=r"m.json: UAVs_Config: give the agents once"):
        configs_from_mission_file(path)
    path.write_text(json.dumps({"UAVs_Config": [dict(GOOD, mode="SITL")]}))
    with pytest.raises(ConfigError, match=rf"^{path}: UAVs_Config\[0\]\.mode: 'SITL' is not one of"):
        configs_from_mission_file(path)
    path.write_text("{")
    with pytest.raises(ConfigError, match=r"m.json: not valid JSON"):
        configs_from_mission_file(path)
    with pytest.raises(ConfigError, match=r"nope.json: cannot read the mission"):
        configs_from_mission_file(tmp_path / "nope.json")
