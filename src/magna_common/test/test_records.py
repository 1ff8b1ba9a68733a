"""The typed records: round trips, files of earlier MAGNA versions, and bad files named in the error."""
import json
from pathlib import Path

import pytest

from magna_common.records import (
    INTERRUPTED,
    SUPERVISOR_FAILED,
    Hyperparameters,
    RecordError,
    SimulationResult,
    SummaryRow,
    WorldRecord,
)

HYPER = {"world": "Gym", "subworld": "1Obs_Central_Cylinder", "mission": "Gym",
         "submission": "2UAVs_2paths_Central_Cylinder", "n_dataset": 1, "n_simulation": 3, "N_iter": 4,
         "sm_view": False, "save_data": True, "save_bag": False, "rviz": False, "seed": 13}


# --- hyperparameters ---------------------------------------------------------------------------------------------

def test_hyperparameters_round_trip_through_the_parameter():
    hyper = Hyperparameters.from_param(HYPER)
    assert (hyper.world, hyper.n_iter, hyper.n_simulation, hyper.save_bag, hyper.seed) == ("Gym", 4, 3, False, 13)
    assert hyper.to_param() == HYPER
    assert Hyperparameters.from_param(hyper.to_param()) == hyper


def test_hyperparameters_not_set_take_the_defaults_and_unknown_keys_stay():
    assert Hyperparameters.from_param(None) == Hyperparameters()
    partial = Hyperparameters.from_param({"world": "SolarPlant", "note": "by hand"})
    assert partial.world == "SolarPlant" and partial.seed is None and partial.save_data is True
    assert partial.to_param()["note"] == "by hand" and "seed" not in partial.to_param()  # XML-RPC has no null


def test_a_hyperparameter_of_the_wrong_type_is_named():
    with pytest.raises(RecordError, match=r"/magna/hyperparameters: field 'N_iter': expected a whole number"):
        Hyperparameters.from_param({**HYPER, "N_iter": "four"})


# --- result.json -------------------------------------------------------------------------------------------------

def supervisor_result(**changes) -> dict:
    """result.json as the supervisor writes it today."""
    return {"id": 3, "seed": 13, "hyperparameters": HYPER, "world_file": "/w/Gym/1Obs.json",
            "mission_file": "/m/Gym/2UAVs.json", "data_dir": "/data/dataset_1/simulation_3",
            "success": True, "outcome": "succeeded", "message": "all good", "sim_duration": 42.5, "collisions": 0,
            "wall_time": 3.2, "mission_wall_time": 3.0, "setup_wall_time": 0.4, "termination": "ground_station",
            "reported": True, "time_limit": 600.0, "timed_out": False, "gs_stop_called": False,
            "launch_command": ["roslaunch", "magna_gs", "simulation.launch"], "launch_pid": 100,
            "launch_exit_code": 0, "supervisor_pid": 99, "leftover_processes_killed": [],
            "started_at": "2024-01-01T00:00:00.000+00:00", "ended_at": "2024-01-01T00:00:03.200+00:00",
            "files": ["mission.json", "simulation.bag"], "final": True, **changes}


def test_a_result_round_trips_and_keeps_every_field(tmp_path):
    path = tmp_path / "result.json"
    path.write_text(json.dumps(supervisor_result()))
    result = SimulationResult.read(path)
    assert (result.id, result.seed, result.success, result.outcome, result.sim_duration) == (3, 13, True,
                                                                                             "succeeded", 42.5)
    assert result.hyperparameters.mission == "Gym" and result.world_file == Path("/w/Gym/1Obs.json")
    assert result.launch_command == ("roslaunch", "magna_gs", "simulation.launch") and result.directory == tmp_path
    assert not result.interrupted and not result.failed_to_run
    copy = tmp_path / "copy" / "result.json"
    result.write(copy)
    assert json.loads(copy.read_text()) == supervisor_result()
    assert SimulationResult.read(copy) == result


def test_an_older_result_reads_with_defaults_and_keeps_unknown_keys(tmp_path):
    """Before the ground station reported its wall times, and with a key this version does not know."""
    older = supervisor_result(note="kept")
    for key in ("mission_wall_time", "setup_wall_time", "files"):
        del older[key]
    path = tmp_path / "result.json"
    path.write_text(json.dumps(older))
    result = SimulationResult.read(path)
    assert (result.mission_wall_time, result.setup_wall_time, result.files) == (0.0, 0.0, ())
    assert result.extra == {"note": "kept"}
    result.write(path)
    assert json.loads(path.read_text())["note"] == "kept"


def test_a_hand_made_result_takes_the_defaults(tmp_path):
    path = tmp_path / "result.json"
    path.write_text(json.dumps({"hyperparameters": {"world": "Gym"}}))
    result = SimulationResult.read(path)
    assert result.id is None and result.collisions is None and result.success is False
    assert result.hyperparameters.world == "Gym" and result.hyperparameters.n_simulation is None


def test_fields_not_known_yet_round_trip_as_null():
    """What the batch hands its supervisor before the run: most fields still None."""
    known = SimulationResult(id=2, seed=7, hyperparameters=Hyperparameters.from_param(HYPER))
    assert json.loads(json.dumps(known.to_dict()))["collisions"] is None
    assert SimulationResult.from_dict(json.loads(json.dumps(known.to_dict())), "--extra") == known
    assert SimulationResult.from_dict(SimulationResult().to_dict(), "empty") == SimulationResult()


def test_how_a_result_ended():
    assert SimulationResult(termination=INTERRUPTED).interrupted
    assert SimulationResult(termination=SUPERVISOR_FAILED).failed_to_run


@pytest.mark.parametrize("text, problem", [
    ("{not json", "not JSON"),
    ("[1, 2]", "expected a JSON object"),
    (json.dumps(supervisor_result(success="yes")), "field 'success': expected true or false"),
    (json.dumps(supervisor_result(collisions=1.5)), "field 'collisions': expected a whole number"),
    (json.dumps(supervisor_result(hyperparameters={"seed": "x"})), "hyperparameters: field 'seed'"),
])
def test_a_bad_result_names_the_file_and_the_field(tmp_path, text, problem):
    path = tmp_path / "result.json"
    path.write_text(text)
    with pytest.raises(RecordError, match=problem) as caught:
        SimulationResult.read(path)
    assert str(path) in str(caught.value) and not caught.value.missing


def test_a_missing_result_says_so(tmp_path):
    with pytest.raises(RecordError, match="no such file") as caught:
        SimulationResult.read(tmp_path / "result.json")
    assert caught.value.missing


# --- summary.csv -------------------------------------------------------------------------------------------------

def test_summary_rows_round_trip_sorted_by_id_with_unknown_columns_kept(tmp_path):
    path = tmp_path / "summary.csv"
    rows = [SummaryRow(10, True, "succeeded", "ok", 12.5, 1.25, 0, {"note": "x"}),
            SummaryRow(2, False, "collision", "collision\nbetween 1 and 2", 14.5, 1.25, 2)]
    SummaryRow.write(path, rows)
    assert path.read_text().splitlines() == [
        "id,success,outcome,message,duration,wall_time,collisions,note",
        "2,False,collision,collision between 1 and 2,14.500,1.250,2,",
        "10,True,succeeded,ok,12.500,1.250,0,x"]
    again = SummaryRow.read(path)
    assert [r.id for r in again] == [2, 10] and again[1] == rows[0] and again[1].extra == {"note": "x"}
    assert again[0].message == "collision between 1 and 2" and again[0].extra == {"note": ""}


def test_a_summary_row_of_a_result():
    row = SummaryRow.of(SimulationResult(id=4, success=True, outcome="succeeded", message="a\nb", sim_duration=3.0,
                                         wall_time=1.0))
    assert row == SummaryRow(4, True, "succeeded", "a b", 3.0, 1.0, 0)
    with pytest.raises(ValueError, match="id"):
        SummaryRow.of(SimulationResult())


def test_an_older_summary_without_some_columns_reads(tmp_path):
    path = tmp_path / "summary.csv"
    path.write_text("id,success,outcome\n1,True,succeeded\n")
    assert SummaryRow.read(path) == [SummaryRow(1, True, "succeeded")]


def test_a_bad_summary_names_the_file_the_line_and_the_column(tmp_path):
    path = tmp_path / "summary.csv"
    path.write_text("id,success,outcome\n1,True,succeeded\n2,maybe,collision\n")
    with pytest.raises(RecordError, match=rf"{path}: line 3, column 'success': expected True or False"):
        SummaryRow.read(path)
    with pytest.raises(RecordError, match="no such file") as caught:
        SummaryRow.read(tmp_path / "none.csv")
    assert caught.value.missing


# --- world.json --------------------------------------------------------------------------------------------------

PART = {"source": "/w/Gym/1Obs.json", "included": [], "seed": 3,
        "world_boundaries": [[-5.0, 5.0], [-5.0, 5.0], [0.0, 4.0]], "origin_geo": None,
        "geometries": [{"volume": "gym", "geometry": "floor", "frame": "gym_floor", "shape": "box",
                        "dimensions": [10.0, 10.0, 0.1], "polygon": [], "position": [0.0, 0.0, 0.0],
                        "orientation": [0.0, 0.0, 0.0, 1.0],
                        "pose_sets": [{"type": "grid", "path": "gym/floor", "frames": ["p0"], "cells": None,
                                       "positions": [[1.0, 2.0, 3.0]], "orientations": [[0.0, 0.0, 0.0, 1.0]]}]}],
        "obstacles": [{"name": "cylinder", "shape": "cylinder", "dimensions": [1.0, 1.0, 3.0], "polygon": [],
                       "position": [0.0, 0.0, 1.5], "orientation": [0.0, 0.0, 0.0, 1.0]}],
        "deleted": True}


def test_a_world_record_round_trips(tmp_path):
    path = tmp_path / "world.json"
    path.write_text(json.dumps({"seed": 3, "parts": {"1": PART}}))
    world = WorldRecord.read(path)
    part = world.parts["1"]
    assert part.deleted and part.world_boundaries == ((-5.0, 5.0), (-5.0, 5.0), (0.0, 4.0))
    assert part.obstacles[0].name == "cylinder" and part.obstacles[0].position == (0.0, 0.0, 1.5)
    assert part.geometries[0].pose_sets[0].positions == ((1.0, 2.0, 3.0),)
    world.write(tmp_path / "copy.json")
    assert json.loads((tmp_path / "copy.json").read_text()) == {"seed": 3, "parts": {"1": PART}}


def test_an_older_world_record_without_deleted_parts_reads(tmp_path):
    older = {k: v for k, v in PART.items() if k not in ("deleted", "origin_geo", "included")}
    path = tmp_path / "world.json"
    path.write_text(json.dumps({"seed": 3, "parts": {"main": older}}))
    part = WorldRecord.read(path).parts["main"]
    assert not part.deleted and part.origin_geo is None and part.included == ()


def test_a_bad_world_record_names_the_file(tmp_path):
    path = tmp_path / "world.json"
    path.write_text(json.dumps({"scenario": {}}))
    with pytest.raises(RecordError, match=rf"{path}: not a world record"):
        WorldRecord.read(path)
    path.write_text(json.dumps({"seed": 3, "parts": {"1": {**PART, "world_boundaries": [[0, 1]]}}}))
    with pytest.raises(RecordError, match=rf"{path}: part '1': field 'world_boundaries'"):
        WorldRecord.read(path)
