"""The persistent stack's decisions and its wire format, without ROS (magna_master.stack)."""
import dataclasses
from pathlib import Path

import pytest

from magna_common.records import CRASHED, GROUND_STATION, INTERRUPTED, TIME_LIMIT, SimulationResult
from magna_master.batch_config import DEFAULT_LAUNCH_COMMAND
from magna_master.stack import (
    SimulationReply,
    SimulationRequest,
    StackPolicy,
    cold_reasons,
    ground_station_params,
)


def test_only_a_default_batch_keeps_a_stack(make_config, tmp_path):
    default = make_config(launch_command=DEFAULT_LAUNCH_COMMAND)
    assert cold_reasons(default) == []
    assert cold_reasons(dataclasses.replace(default, cold_start=True)) == ["--cold-start"]
    assert cold_reasons(dataclasses.replace(default, rviz=True)) == ["--rviz"]
    assert cold_reasons(dataclasses.replace(default, fleet=tmp_path / "fleet.yaml")) == ["--fleet"]
    assert cold_reasons(make_config()) == ["--launch-command"]  # the stand-in ground station


def _result(termination=GROUND_STATION, leftovers=()):
    return SimulationResult(id=1, termination=termination, leftover_processes_killed=tuple(leftovers))


@pytest.mark.parametrize(("result", "reply", "restart"), [
    (_result(), SimulationReply(ran=True, healthy=True, reset_s=0.2), ""),
    (_result(), SimulationReply(ran=True, healthy=False, reason="REQUIRED process [magna_sim-1] has died"),
     "REQUIRED process [magna_sim-1] has died"),
    (_result(CRASHED), SimulationReply(ran=True, healthy=True), "the simulation ended crashed"),
    (_result(TIME_LIMIT), SimulationReply(ran=True, healthy=True), "the simulation ended time_limit"),
    (_result(INTERRUPTED), SimulationReply(ran=True, healthy=True), "the simulation ended interrupted"),
    (_result(leftovers=["123 python x (SIGINT)"]), SimulationReply(ran=True, healthy=True),
     "processes were left over and killed"),
    (_result(), SimulationReply(ran=True, healthy=True, reset_s=12.5), "the reset took 12.5 s"),
])
def test_the_stack_stays_only_after_a_clean_report(result, reply, restart):
    assert StackPolicy(reset_limit=10.0).why_restart(result, reply) == restart


def test_requests_and_replies_survive_the_wire():
    request = SimulationRequest(result="/d/result.json", log="/d/logs/launch.log", data_dir="/d",
                                ros_log_dir="/d/logs/ros", seed=7, world_record="/d/world.json",
                                hyperparameters={"seed": 7, "world": "Gym"}, ground_station={"teardown": False},
                                known={"id": 3}, token="abc", time_limit=600.0)
    line = request.to_line()
    assert line.endswith("\n") and line.count("\n") == 1  # one request per line
    assert SimulationRequest.from_line(line) == request
    reply = SimulationReply(ran=True, healthy=False, reason="a\nb", reset_s=0.3, timeline={"reset": 0.3})
    assert reply.to_line().count("\n") == 1
    assert SimulationReply.from_line(reply.to_line()) == reply


def test_the_ground_station_of_a_warm_stack_leaves_the_reset_to_it(make_config, tmp_path):
    from magna_master.storage import plan_storage

    config = make_config(launch_command=DEFAULT_LAUNCH_COMMAND, bag=False)
    plan = plan_storage(config.dataset_dir, 1, None, True, None)
    params = ground_station_params(config, tmp_path / "simulation_1", plan)
    assert params["teardown"] is False
    assert params["bag"] is False and params["save_data"] is True
    assert Path(params["mission_file"]) == config.inputs.mission_file
    assert params["data_dir"] == str(tmp_path / "simulation_1")
    assert params["button_timeout"] == config.button_timeout
