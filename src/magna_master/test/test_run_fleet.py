"""`magna run --fleet`: a mission with hil or real UAVs needs a fitting fleet file, and runs at real time when
one is an autopilot outside the simulator; anything that does not fit stops the batch before it starts, with
one line naming the file and the fix."""
from pathlib import Path

import pytest

from magna_master import cli
from magna_master.batch_config import BatchError, launch_command
from magna_master.run_cli import check_fleet

ROOT = Path(__file__).resolve().parents[3]
WORLD = "Gym/Central_Obstacle_Torus"
MISSION = "Gym/Experiment_II_SITL_HIL"  # UAVs 1 and 2 sitl, 3 hil
MISSION_FILE = ROOT / "missions" / "Gym" / "Experiment_II_SITL_HIL.json"
SITL_MISSION_FILE = ROOT / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json"
STAND_IN = ROOT / "fleets" / "stand_in_hil.yaml"


def run(tmp_path, capsys, *more):
    status = cli.main(["run", "--world", WORLD, "--mission", MISSION, "--data-root", str(tmp_path / "data"), *more])
    return status, capsys.readouterr()


def test_an_autopilot_outside_the_simulator_makes_the_run_real_time(tmp_path, capsys):
    real = tmp_path / "fleet.yaml"
    real.write_text("uavs: {3: {url: 'udpin:0.0.0.0:14542'}}")
    fleet, rtf = check_fleet(MISSION_FILE, real, "max")
    assert fleet == real.resolve() and rtf == "1"
    assert "UAVs [3] fly over MAVLink outside the simulator: the simulation runs at real time" in \
        capsys.readouterr().out
    assert check_fleet(MISSION_FILE, real, "1.0") == (real.resolve(), "1")
    with pytest.raises(BatchError, match=r"--rtf 4: UAVs \[3\] are autopilots outside the simulator"):
        check_fleet(MISSION_FILE, real, "4")


def test_stand_ins_fly_in_simulated_time_at_any_factor(capsys):
    assert check_fleet(MISSION_FILE, STAND_IN, "max") == (STAND_IN.resolve(), "max")
    assert check_fleet(MISSION_FILE, STAND_IN, "4") == (STAND_IN.resolve(), "4")
    assert "real time" not in capsys.readouterr().out


def test_the_fleet_file_goes_to_the_simulation_launch():
    from magna_gs.inputs import resolve_inputs
    from magna_master.batch_config import BatchConfig
    from magna_master.storage import StoragePlan

    config = BatchConfig(inputs=resolve_inputs(WORLD, MISSION), fleet=STAND_IN.resolve(), rtf="1")
    argv = launch_command(config, 1, None, StoragePlan(dataset_dir=None, ids=[1]))
    assert f"fleet:={STAND_IN.resolve()}" in argv and "rtf:=1" in argv


@pytest.mark.parametrize("fleet, rtf, message", [
    (None, "max", "UAVs [3] are hil or real; give --fleet FILE"),
    (Path("no_such_fleet.yaml"), "max", "no_such_fleet.yaml: no such file"),
])
def test_a_missing_or_unfitting_fleet_stops_the_batch(fleet, rtf, message):
    with pytest.raises(BatchError, match=message.replace("[", r"\[").replace("]", r"\]")):
        check_fleet(MISSION_FILE, fleet, rtf)


def test_a_fleet_that_does_not_fit_the_mission_is_named(tmp_path):
    wrong = tmp_path / "fleet.yaml"
    wrong.write_text("uavs: {1: {url: 'udpin:0.0.0.0:14540'}, 3: {stand_in: true}}")
    with pytest.raises(BatchError, match=r"--fleet: .*fleet.yaml: uavs.1: UAV 1 is sitl in the mission"):
        check_fleet(MISSION_FILE, wrong, "max")
    with pytest.raises(BatchError, match="every UAV of 2UAVs_Crossing_ORCA.json is sitl"):
        check_fleet(SITL_MISSION_FILE, STAND_IN, "max")


def test_magna_run_refuses_before_anything_starts(tmp_path, capsys):
    status, out = run(tmp_path, capsys)
    assert status == 2
    assert out.err.startswith("magna run: ") and "give --fleet FILE" in out.err
    assert len(out.err.strip().splitlines()) == 1
    assert not (tmp_path / "data").exists()
    status, out = run(tmp_path, capsys, "--fleet", str(STAND_IN), "--rtf", "fast")
    assert status == 2 and "--rtf 'fast'" in out.err and not (tmp_path / "data").exists()
