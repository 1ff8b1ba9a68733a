"""/magna/sim/reset and /magna/sim/swarm_state on a live simulator, against a simulator started cold.

The simulator serves UAV 1 from ~uavs and adds sensor noise, so what UAV 1's odom carries depends on the seed
and on the rng draws since time 0: a reset that left anything of the rng or of the schedules behind shows up.
"""
import json
import math
import subprocess
import sys
from pathlib import Path

from magna_common.processes import end_process_group
from magna_sim.ros_ual import rotate_into_body

PROBE = Path(__file__).with_name("reset_probe.py")
SIM = ["rosrun", "magna_sim", "sim", "_uavs:=1", "_real_time_factor:=3", "_noise/position_std:=0.1",
       "_noise/velocity_std:=0.05"]
FIRST_TICK_NS = int(1e9 / 240)  # /clock after the first physics step (240 Hz), as rospy.Time.from_sec stamps it


def probe(master, *args):
    return master.spawn([sys.executable, str(PROBE), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                        text=True)


def probed(process):
    out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err[-3000:]
    result = json.loads(out.splitlines()[-1])
    for stream in ("odom", "swarm"):
        result[stream] = {int(stamp): value for stamp, value in result[stream].items()}
    return result


def assert_swarm_is_the_odom(result):
    """Each swarm state holds UAV 1 exactly as its odom of that stamp (odom's twist is in the body frame), and in
    the UAL state its ual/state reports (one: it stands landed)."""
    common = sorted(set(result["odom"]) & set(result["swarm"]))
    assert len(common) >= 30, len(common)
    for stamp in common:
        swarm, odom = result["swarm"][stamp], result["odom"][stamp]
        assert swarm["frame"] == "map" and swarm["ids"][0] == 1
        pose, velocity, angular = swarm["poses"][0], swarm["velocities"][0], swarm["angular_velocities"][0]
        assert pose == odom[:7]
        assert list(rotate_into_body(pose[3:], velocity)) == odom[7:10]
        assert list(rotate_into_body(pose[3:], angular)) == odom[10:]
        assert len(swarm["states"]) == len(swarm["ids"]) and [swarm["states"][0]] == result["states"]


def test_a_reset_simulator_runs_as_a_cold_one_with_the_seed(fresh_ros_master):
    fresh_ros_master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    used = fresh_ros_master.spawn([*SIM, "_seed:=1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    warm = probed(probe(fresh_ros_master, "reset", "2"))
    assert used.poll() is None, "the simulator died during the reset"
    end_process_group(used)

    assert warm["spawned"]
    assert warm["before"] and warm["after"] == [], warm["after"]  # UAV 2's topics, services, lockstep: unregistered
    assert warm["refused"] == [False, "seed: -1 must be 0 or more (as ~seed); nothing was reset"]
    assert warm["reset"] == [True, "reset with seed 2: 2 UAV(s) and 1 obstacle(s) removed, simulated time 0, "
                                   "1 UAV(s) spawned as at start"]
    assert all(message.endswith("models: uav_1") for message in warm["deleted"]), warm["deleted"]
    assert warm["ual_ids"] == [1]
    assert warm["respawned"][0], warm["respawned"]
    clock = warm["clock"]
    jumps = [i for i in range(1, len(clock)) if clock[i] < clock[i - 1]]
    assert len(jumps) == 1 and clock[jumps[0]] == FIRST_TICK_NS, (jumps, clock[:5])
    assert_swarm_is_the_odom(warm)

    listening = probe(fresh_ros_master, "cold")
    assert listening.stdout.readline().strip() == "listening"
    cold_sim = fresh_ros_master.spawn([*SIM, "_seed:=2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    cold = probed(listening)
    assert cold_sim.poll() is None
    assert_swarm_is_the_odom(cold)
    common = sorted(set(warm["odom"]) & set(cold["odom"]))
    assert len(common) >= 30 and common[0] < 2e9, (len(common), common[:1])
    assert [warm["odom"][stamp] for stamp in common] == [cold["odom"][stamp] for stamp in common]
    # The noise is there (the comparison can tell one draw from another) and the UAV stands where it started.
    noisy_x = [warm["odom"][stamp][0] for stamp in common]
    assert len(set(noisy_x)) == len(noisy_x) and abs(sum(noisy_x) / len(noisy_x)) < 0.1
    assert not math.isclose(warm["odom"][common[0]][1], 0.0, abs_tol=1e-12)
