"""magna port: a folder of worlds and missions is walked, each file loaded, missions paired with a world that holds
their places, and the report says what loads, migrates, warns, validates and flies. Files are written per test."""
from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from magna_master import port
from magna_master.cli import main
from tests.support import CORPUS


def _geometry(name, prefix, origin=(0.0, 0.0, 0.05), poses=True):
    g = {"name": name, "prefix": prefix, "shape": "cube", "id": 0, "origin": [list(origin), [0, 0, 0]],
         "dimensions": [6.0, 0.1, 0.1], "color": [0, 0, 0], "alpha": 0.3}
    if poses:
        g["poses_sets"] = [{"type": "matrix", "matrix_type": "dimension", "use": "poses", "dimensions": [3, 1, 1],
                            "density": 1}]
    return g


def _volume(name, prefix, x, geometries):
    return {"name": name, "prefix": prefix, "origin": [[x, 0, 0.0], [0, 0, 0]], "permits": "geofence",
            "geometries": geometries}


def _world(*volumes):
    return {"scenario": {"world_boundaries": [[-100, 100], [-100, 100], [0, 50]], "volumes": list(volumes)}}


GROUND = _volume("Ground_Station", "GS", -20, [_geometry("Agents_take_off", "takeoff")])
AREA = _volume("Area", "AR", 20, [_geometry("Line", "line", origin=(0.0, 0.0, 3.0))])


def _mission(places, ids=(1,)):
    """Spawn each agent on the take-off line, take off, fly to each (volume, geometry) cell, land."""
    agents = [{"ID": i, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]} for i in ids]
    path = [{"definition": [v, g, "matrix", [0, 0, 0]]} for v, g in places]
    states = [
        {"type": "CBState", "name": "spawn", "state_type": "spawn_agents",
         "parameters": {"initial_poses": [["Ground_Station", "Agents_take_off", "matrix", [i - 1, 0, 0]]
                                          for i in ids]},
         "outcomes": {"completed": "1_take_off", "failed": "failed"}},
        {"type": "SimpleActionState", "name": "take_off", "state_type": "take_off", "ids": ids[0],
         "parameters": {"height": 2.0}, "outcomes": {"succeeded": f"{ids[0]}_path"}},
    ]
    after_path = f"{ids[0]}_land"
    if path:
        states.append({"type": "SimpleActionState", "name": "path", "state_type": "follow_path", "ids": ids[0],
                       "parameters": {"path": path, "dynamic": "position"},
                       "outcomes": {"succeeded": after_path}})
    else:
        states[1]["outcomes"] = {"succeeded": after_path}
    states.append({"type": "SimpleActionState", "name": "land", "state_type": "land", "ids": ids[0],
                   "outcomes": {"succeeded": "completed"}})
    return {"Agents_Config": agents, "State_Machine": states}


def _write(root: Path, relative: str, data) -> Path:
    path = root / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return path


@pytest.fixture
def tree(tmp_path):
    """Worlds/Lab/{Big,Small,Inspection}, Missions/Lab/{Inspection,Home}, Missions/Other/{Home,Nowhere,Broken}."""
    _write(tmp_path, "Worlds/Lab/Big.json", _world(GROUND, AREA))
    _write(tmp_path, "Worlds/Lab/Small.json", _world(GROUND))
    _write(tmp_path, "Worlds/Lab/Inspection.json", _world(GROUND, AREA))
    _write(tmp_path, "Worlds/Far/Tiny.json", _world(GROUND))
    _write(tmp_path, "Missions/Lab/Inspection.json", _mission([("Area", "Line")]))
    _write(tmp_path, "Missions/Lab/Home.json", _mission([]))
    _write(tmp_path, "Missions/Other/Home.json", _mission([("Ground_Station", "Agents_take_off")]))
    _write(tmp_path, "Missions/Other/Nowhere.json", _mission([("Moon", "Crater")]))
    return tmp_path


def _by_label(report):
    return {r.label: r for r in [*report.worlds, *report.missions]}


def test_each_mission_is_paired_with_the_preferred_world_that_holds_its_places(tree):
    report = port.port_folder(tree)
    found = _by_label(report)
    assert [w.label for w in report.worlds] == ["Far/Tiny", "Lab/Big", "Lab/Inspection", "Lab/Small"]
    assert all(w.loads for w in report.worlds)
    # same family and same name first; then the family's smallest world; then the smallest anywhere
    assert found["Lab/Inspection"].world.label == "Lab/Inspection"
    assert found["Lab/Home"].world.label == "Lab/Small"
    assert found["Other/Home"].world.label == "Far/Tiny"
    assert all(found[m].validates for m in ("Lab/Inspection", "Lab/Home", "Other/Home"))
    # a mission no world can hold is listed but is not a pair, and is not a refusal
    assert found["Other/Nowhere"].loads and not found["Other/Nowhere"].paired
    assert len(report.pairs) == 3 and not report.refused


def test_a_mission_flying_where_only_one_world_has_room_is_paired_with_that_one(tree):
    _write(tree, "Missions/Lab/Reach.json", _mission([("Area", "Line")]))
    # Big's Line and Inspection's Line are the same; only the family's two holding worlds qualify, not Small
    found = _by_label(port.port_folder(tree))
    assert found["Lab/Reach"].world.label in ("Lab/Big", "Lab/Inspection")


def test_refused_files_are_listed_with_file_path_and_fix_and_make_the_report_refused(tree):
    _write(tree, "Worlds/Lab/Broken.json", {"scenario": {"world_boundaries": [[-1, 1], [-1, 1], [0, 1]],
                                                         "volumes": [{"name": "X"}]}})
    _write(tree, "Missions/Other/Broken.json", "{ not json")
    report = port.port_folder(tree)
    found = _by_label(report)
    assert not found["Lab/Broken"].loads and "Broken.json" in found["Lab/Broken"].problems[0]
    assert "volumes[0]" in found["Lab/Broken"].problems[0]
    assert not found["Other/Broken"].loads and "not valid JSON" in found["Other/Broken"].problems[0]
    assert report.refused
    text = port.format_report(report)
    assert "REFUSED" in text and "refused: " in text
    assert "worlds loaded 4 of 5; missions loaded 4 of 5; pairs validated 3 of 3" in text


def test_a_pair_whose_places_do_not_resolve_is_a_refusal_of_the_pair(tree):
    # cell [5, 0, 0] of a 3 x 1 x 1 matrix: the names match, the place does not exist
    mission = _mission([("Area", "Line")])
    mission["State_Machine"][2]["parameters"]["path"][0]["definition"][3] = [5, 0, 0]
    _write(tree, "Missions/Lab/Inspection.json", mission)
    report = port.port_folder(tree)
    inspection = _by_label(report)["Lab/Inspection"]
    assert inspection.paired and not inspection.validates and inspection.pair_problems
    assert "Inspection.json" in inspection.pair_problems[0]
    assert report.refused


def test_migrated_legacy_missions_say_what_changed(tree):
    legacy = _mission([("Area", "Line")])
    legacy["UAVs_Config"] = legacy.pop("Agents_Config")
    _write(tree, "Missions/Lab/Inspection.json", legacy)
    inspection = _by_label(port.port_folder(tree))["Lab/Inspection"]
    assert inspection.validates and any("UAVs_Config -> Agents_Config" in c for c in inspection.changes)


def test_fly_pairs_records_each_outcome_and_goes_on_after_a_pair_that_cannot_start(tree):
    report = port.port_folder(tree)
    flown = []

    def make_config(mission):
        return mission.label

    def run(label):
        flown.append(label)
        if label == "Lab/Home":
            raise RuntimeError("no simulator")
        ok = label == "Lab/Inspection"
        sim = SimpleNamespace(success=ok, outcome="completed" if ok else "collision", message="m")
        return SimpleNamespace(simulations=[sim], interrupted=False)

    port.fly_pairs(report, make_config, run)
    found = _by_label(report)
    assert flown == ["Lab/Home", "Lab/Inspection", "Other/Home"]  # validated pairs only, in file order
    assert found["Lab/Inspection"].flew
    assert found["Other/Home"].flight == "collision" and not found["Other/Home"].flew
    assert found["Lab/Home"].flight == "not started" and "no simulator" in found["Lab/Home"].flight_message
    assert found["Other/Nowhere"].flight is None
    assert "pairs flown to success 1 of 3" in port.totals(report)


def test_cli_exit_status_table_and_json(tree, capsys):
    out_json = tree / "port.json"
    assert main(["port", str(tree), "-o", str(out_json)]) == 0
    captured = capsys.readouterr()
    assert "Lab/Inspection" in captured.out and "pairs validated 3 of 3" in captured.out
    assert f"json:    {out_json}" in captured.out and captured.err == ""
    data = json.loads(out_json.read_text())
    assert {m["label"]: m["world"] for m in data["missions"]}["Lab/Home"] == "Lab/Small"
    # the JSON is not replaced without --force
    before = out_json.read_text()
    assert main(["port", str(tree), "--output", str(out_json)]) == 2
    assert capsys.readouterr().err == f"magna port: -o {out_json} already exists; pass --force to replace it\n"
    assert out_json.read_text() == before
    out_json.write_text("old")
    assert main(["port", str(tree), "-o", str(out_json), "--force", "--brief"]) == 0
    assert json.loads(out_json.read_text()) == data
    _write(tree, "Missions/Other/Broken.json", "{ not json")
    assert main(["port", str(tree), "--brief"]) == 2


def test_cli_old_spellings_json_and_no_data_still_work_with_one_line_each(tree, capsys):
    from magna_common.cli_vocabulary import deprecation_line
    from magna_master.cli import build_parser

    out_json = tree / "old.json"
    assert main(["port", str(tree), "--json", str(out_json), "--brief"]) == 0
    assert json.loads(out_json.read_text())["missions"]
    assert capsys.readouterr().err.splitlines() == [deprecation_line("magna port", "--json", "-o/--output")]
    args = build_parser().parse_args(["port", str(tree), "--fly", "--no-data"])
    assert args.skip_save is True
    assert capsys.readouterr().err.splitlines() == [deprecation_line("magna port", "--no-data", "--skip-save")]
    args = build_parser().parse_args(["port", str(tree), "--fly", "--skip-save", "--rtf", "2"])
    assert args.skip_save is True and args.rtf == "2" and capsys.readouterr().err == ""
    assert build_parser().parse_args(["port", str(tree)]).skip_save is False


def test_cli_help_uses_the_vocabulary(capsys):
    with pytest.raises(SystemExit):
        main(["port", "--help"])
    out = capsys.readouterr().out
    for spelling in ("-o FILE, --output FILE", "--force", "--skip-save", "--rtf max|FACTOR"):
        assert spelling in out
    assert "--json" not in out and "--no-data" not in out
    assert "./magna port ../shared/ros_magna_corpus" in out.split("examples:")[1]


def test_cli_refuses_a_folder_without_worlds_or_missions(tmp_path, capsys):
    assert main(["port", str(tmp_path / "missing")]) == 2
    assert "no such folder" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["port", str(tmp_path / "empty")]) == 2
    assert "no world or mission files" in capsys.readouterr().err


def test_a_flat_folder_is_sorted_by_content(tmp_path):
    _write(tmp_path, "a/world.json", _world(GROUND))
    _write(tmp_path, "a/mission.json", _mission([]))
    report = port.port_folder(tmp_path)
    assert [w.label for w in report.worlds] == ["a/world"]
    assert [m.label for m in report.missions] == ["a/mission"] and report.missions[0].validates


def test_the_shared_corpus_loads_and_every_pair_validates():
    report = port.port_folder(CORPUS.resolve())
    assert report.worlds and report.missions, f"no corpus at {CORPUS}; set MAGNA_CORPUS to ros_magna_corpus"
    assert all(w.loads for w in report.worlds), [w.problems for w in report.worlds if not w.loads]
    assert all(m.loads for m in report.missions), [m.problems for m in report.missions if not m.loads]
    assert len(report.pairs) == len(report.missions)
    assert all(m.validates for m in report.pairs), [(m.label, m.pair_problems) for m in report.pairs]


def test_within_a_family_the_world_named_in_the_missions_name_is_preferred(tree):
    _write(tree, "Worlds/Lab/Crop_Field.json", _world(GROUND, AREA))
    _write(tree, "Missions/Lab/1UAV_cropfield_survey.json", _mission([("Area", "Line")]))
    found = _by_label(port.port_folder(tree))
    assert found["Lab/1UAV_cropfield_survey"].world.label == "Lab/Crop_Field"


def test_what_the_original_tolerated_warns_and_strict_refuses_it(tree):
    unbounded = _world(GROUND)
    del unbounded["scenario"]["world_boundaries"]  # the original did without; MAGNA warns and bounds it itself
    _write(tree, "Worlds/Lab/Small.json", unbounded)
    small = _by_label(port.port_folder(tree))["Lab/Small"]
    assert small.loads and any("world_boundaries" in w for w in small.warnings)
    strict = port.port_folder(tree, strict=True)
    small = _by_label(strict)["Lab/Small"]
    assert not small.loads and any("world_boundaries" in p for p in small.problems) and strict.refused


def test_magna_run_strict_refuses_a_tolerated_world_before_anything_starts(tree, tmp_path, capsys):
    unbounded = _world(GROUND)
    del unbounded["scenario"]["world_boundaries"]
    world = _write(tree, "Worlds/Lab/Small.json", unbounded)
    mission = tree / "Missions/Lab/Home.json"
    data_root = tmp_path / "data"
    argv = ["run", "--world", str(world), "--mission", str(mission), "--data-root", str(data_root), "--strict"]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "Small.json" in error and "world_boundaries" in error
    assert not data_root.exists()  # nothing started, nothing written


def test_magna_run_refuses_a_mission_whose_places_the_world_does_not_have(tree, tmp_path, capsys):
    world, mission = tree / "Worlds/Lab/Small.json", tree / "Missions/Lab/Inspection.json"  # Small has no Area
    assert main(["run", "--world", str(world), "--mission", str(mission), "--data-root", str(tmp_path / "d")]) == 2
    error = capsys.readouterr().err
    assert "Inspection.json: State_Machine[2].parameters.path[0].definition" in error and "Area" in error
    assert not (tmp_path / "d").exists()


def test_magna_run_refuses_a_bad_utm_plan_before_anything_starts(tree, tmp_path, capsys):
    plan = _write(tmp_path, "plan.json", {"flight_plans": [{"ids": [1], "at": -5, "waypoints": [[0, 0, 2]]}]})
    world, mission = tree / "Worlds/Lab/Small.json", tree / "Missions/Lab/Home.json"
    argv = ["run", "--world", str(world), "--mission", str(mission), "--data-root", str(tmp_path / "d"),
            "--utm-plan", str(plan)]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "--utm-plan" in error and "plan.json: flight_plans[0].at" in error
    assert not (tmp_path / "d").exists()


def test_a_mission_place_outside_its_worlds_boundaries_warns_in_the_pair_and_strict_refuses_it(tree):
    far = _volume("Area", "AR", 20, [_geometry("Line", "line", origin=(0.0, 0.0, 80.0))])  # above z 0..50
    _write(tree, "Worlds/Lab/Inspection.json", _world(GROUND, far))
    inspection = _by_label(port.port_folder(tree))["Lab/Inspection"]
    assert inspection.validates and inspection.world.label == "Lab/Big"  # a world where it is clean comes first
    _write(tree, "Worlds/Lab/Big.json", _world(GROUND, far))
    inspection = _by_label(port.port_folder(tree))["Lab/Inspection"]
    assert inspection.validates and inspection.world.label == "Lab/Inspection"
    assert any("outside the world boundaries" in w for w in inspection.pair_warnings)
    assert "warning in Lab/Inspection: " in port.format_report(port.port_folder(tree))
    strict = port.port_folder(tree, strict=True)
    world = next(w for w in strict.worlds if w.label == "Lab/Inspection")  # its pose set lies outside too
    assert not world.loads and any("refused with --strict" in p for p in world.problems)


def test_a_fixed_wing_mission_prefers_the_roomier_of_two_worlds(tree):
    plane = _mission([])
    plane["Agents_Config"][0]["model"] = "plane"
    _write(tree, "Missions/Air/Circuit.json", plane)
    roomy = _world(GROUND)
    roomy["scenario"]["world_boundaries"] = [[-900, 900], [-900, 900], [0, 300]]
    _write(tree, "Worlds/Far/Roomy.json", roomy)
    found = _by_label(port.port_folder(tree))
    assert found["Air/Circuit"].world.label == "Far/Roomy"  # it loiters and lands over hundreds of metres
    assert found["Other/Home"].world.label == "Far/Roomy"  # equally small worlds: the roomier


@pytest.mark.parametrize("value", ["100", "-1", "half"])
def test_a_battery_floor_outside_0_to_100_is_refused(tree, value, capsys):
    with pytest.raises(SystemExit) as refused:
        main(["run", "--world", "Gym/X", "--mission", "Gym/Y", "--battery-floor", value])
    assert refused.value.code == 2 and "--battery-floor" in capsys.readouterr().err
