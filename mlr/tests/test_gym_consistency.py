"""The gym and magna_sim's ROS node fly the same trajectory for the same velocity commands from the same start.

The ROS side is the whole path a UAV manager's commands take: the sim node, its UAL topics, its lockstep
with the manager's control steps (mlr/tests/sim_node_probe.py plays the manager). The gym side is
mlr.gym.fleet, with no ROS. Both start with two iris UAVs hovering where the node's take-off left them.

Stated tolerance: every position, sampled at every control step of a 5 s flight with a new command each
step, within TOLERANCE of the other side's. The residue comes from where in its control period the node
applies a command: a ROS message lands a physics step or two after the control step's simulated time,
where the gym applies it exactly on it. The node's lockstep bounds that lag at 10 ms (LOCKSTEP_LEAD less a
control period; a change of 0.3 m/s applied 10 ms late moves the UAV 3 mm). Measured: 2 mm at most.
"""
from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mlr.gym.fleet import Fleet
from mlr.gym.scenario import load_scenario
from tests.support import CORPUS, wait_until

TOLERANCE = 0.03  # m
STEPS = 50  # control steps of 0.1 s
HEIGHT = 2.0  # m, the take-off
# s the node may run ahead of the probe's last control step: just over one control period, so that it reaches
# the next step's time (and the probe sends it) but never runs past it by more than 10 ms, however loaded
LOCKSTEP_LEAD = 0.11
PROBE = Path(__file__).with_name("sim_node_probe.py")


def commands() -> np.ndarray:
    """(STEPS, 2, 3) m/s: both UAVs turning and climbing, a new command every step, drifting apart along y."""
    k = np.arange(STEPS)[:, None]
    first = np.hstack([1.2 * np.cos(0.25 * k), -0.4 + 0.7 * np.sin(0.3 * k), 0.4 * np.sin(0.2 * k)])
    second = np.hstack([-1.0 * np.sin(0.2 * k), 0.4 + 0.7 * np.cos(0.35 * k), -0.3 * np.sin(0.15 * k)])
    return np.stack([first, second], axis=1)


def fly_the_node(master, sent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(STEPS + 1, 2, 3) positions at the node's control steps, and the UAVs' hovering starts ((2, 3))."""
    import rosgraph

    master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    node = master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=2", "_model:=iris", "_real_time_factor:=1",
                         f"_lockstep_lead:={LOCKSTEP_LEAD}"],
                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ros = rosgraph.Master("/test", master_uri=master.uri)
    wait_until(lambda: ros.hasParam("/ual_ids") and len(ros.getParam("/ual_ids")) == 2, "two UAL ids", timeout=60)
    request = json.dumps({"height": HEIGHT, "commands": sent.tolist()})
    out = subprocess.run([sys.executable, str(PROBE)], input=request, capture_output=True, text=True,
                         timeout=180, env=master.env())
    assert out.returncode == 0, out.stderr
    assert node.poll() is None, "the sim node died during the flight"
    answer = json.loads(out.stdout.strip().splitlines()[-1])
    times = answer["t0"] + 0.1 * np.arange(STEPS + 1)
    positions = np.zeros((STEPS + 1, 2, 3))
    for j in range(2):
        heard = np.array(answer["poses"][str(j + 1)])
        assert heard[0, 0] < times[0] and heard[-1, 0] > times[-1], "the poses heard do not span the flight"
        for axis in range(3):
            positions[:, j, axis] = np.interp(times, heard[:, 0], heard[:, 1 + axis])
    return positions, positions[0]


def fly_the_gym(starts: np.ndarray, sent: np.ndarray) -> np.ndarray:
    scenario = load_scenario("Gym/Empty_4_Cylinders", "Gym/2UAVs_2paths_4_Cylinders", [CORPUS])
    assert [uav.airframe.model for uav in scenario.uavs] == ["iris", "iris"]
    empty = dataclasses.replace(scenario, solids=(), obstacles=())  # the node's world holds nothing else either
    fleet = Fleet(empty, copies=1)
    try:
        fleet.place(0, starts)
        positions = [fleet.positions()[0]]
        for step in sent:
            fleet.control_step(step[None])
            positions.append(fleet.positions()[0])
        return np.array(positions)
    finally:
        fleet.close()


@pytest.mark.timeout(300)
def test_the_gym_flies_the_trajectory_the_sim_node_flies(fresh_ros_master):
    sent = commands()
    node, starts = fly_the_node(fresh_ros_master, sent)
    gym = fly_the_gym(starts, sent)
    assert np.all(np.abs(starts[:, 2] - HEIGHT) < 0.2), starts  # both took off and hover
    travelled = [float(np.sum(np.linalg.norm(np.diff(node[:, j], axis=0), axis=1))) for j in range(2)]
    assert min(travelled) > 3.0, travelled  # the flight goes somewhere: not two UAVs at rest agreeing
    worst = float(np.max(np.linalg.norm(node - gym, axis=2)))
    assert worst <= TOLERANCE, f"worst deviation {worst:.3f} m over {STEPS} control steps"
    # and the comparison can tell trajectories apart: the same commands one control step late are far off
    late = fly_the_gym(starts, np.vstack([np.zeros((1, 2, 3)), sent[:-1]]))
    assert float(np.max(np.linalg.norm(node - late, axis=2))) > 3 * TOLERANCE
    assert math.isfinite(worst)
