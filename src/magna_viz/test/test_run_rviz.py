"""`magna run --rviz`: the hyperparameter, the launch argument, and the early refusal without a display."""
from __future__ import annotations

from pathlib import Path

import pytest

from magna_common.ros_master import RosMaster
from magna_gs.inputs import resolve_inputs
from magna_master import cli, storage
from magna_master.batch import preflight
from magna_master.batch_config import BatchConfig, BatchError, hyperparameters, launch_command
from magna_viz.rviz_launcher import fitted_config
from magna_viz.rviz_launcher import main as rviz_world_main

WORLD, MISSION = "Gym/Central_Obstacle_Torus", "Gym/2UAVs_Crossing_ORCA"


@pytest.fixture
def inputs():
    return resolve_inputs(WORLD, MISSION)


def test_rviz_reaches_the_hyperparameters_and_the_launch(inputs):
    plan = storage.StoragePlan(Path("/data/dataset_1"), [1])
    on, off = BatchConfig(inputs=inputs, rviz=True), BatchConfig(inputs=inputs)
    assert hyperparameters(on, 1, plan).rviz is True and hyperparameters(off, 1, plan).rviz is False
    assert launch_command(on, 1, Path("/data/dataset_1/simulation_1"), plan)[-1] == "rviz:=true"
    assert not any(a.startswith("rviz:=") for a in launch_command(off, 1, None, plan))
    custom = BatchConfig(inputs=inputs, rviz=True, launch_command=("my_launch", "show:={rviz}"))
    assert launch_command(custom, 1, None, plan) == ["my_launch", "show:=true"]


def test_without_a_display_run_rviz_stops_before_anything_and_points_to_replay(inputs, monkeypatch, tmp_path,
                                                                                  capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(BatchError, match="DISPLAY is not set"):
        preflight(BatchConfig(inputs=inputs, rviz=True))

    def refuse(self):
        raise AssertionError("a master was started")

    monkeypatch.setattr(RosMaster, "start", refuse)
    code = cli.main(["run", "--world", WORLD, "--mission", MISSION, "--rviz", "--data-root", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert err.startswith("magna run: --rviz needs a display") and "magna replay --headless" in err
    assert not (tmp_path / "d").exists()


def test_the_live_configuration_is_fitted_to_the_world_file(tmp_path, monkeypatch):
    from magna_common.records import WorldRecord
    from magna_viz import rviz_config as rc
    from magna_worlds.generate import resolve_world, world_record
    from magna_worlds.loader import load_world

    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    record = WorldRecord.from_dict({"parts": {"main": world_record(resolve_world(load_world(inputs_world_file()), 0))}},
                                   "Gym")
    path, note = fitted_config("Gym", record, None, None, "live_Gym_Central_Obstacle_Torus")
    assert path == tmp_path / "magna_viz" / "live_Gym_Central_Obstacle_Torus.rviz" and "fitted" in note
    config = rc.load_config(path)
    focal = config["Visualization Manager"]["Views"]["Current"]["Focal Point"]
    assert -12 < focal["X"] < 12 and -14 < focal["Y"] < 12  # inside the gym's boundaries
    assert config["Panels"] == rc.load_config(rc.RVIZ_DIR / "gym.rviz")["Panels"]  # on a display: panels stay


def inputs_world_file() -> Path:
    return resolve_inputs(WORLD, MISSION).world_file


def test_rviz_world_refuses_a_missing_config(tmp_path, capsys):
    assert rviz_world_main(["--world=Gym", f"--config={tmp_path / 'nope.rviz'}", "__name:=rviz"]) == 2
    assert "nope.rviz: no such file" in capsys.readouterr().err
