"""How fast the gym steps: agent-steps per second for a 2-UAV scenario on one core (target: >= 2,000).

It pins itself to one CPU (os.sched_setaffinity) and torch to one thread, then steps, side by side in one
run: the single-agent MagnaNavEnv (with the other UAV on ORCA-3D), the PettingZoo parallel environment,
and the stable-baselines3 vector environment with 1, 4, 8 and 16 copies of the scenario in one magna_sim
world. Actions are random, seeded. Prints a table with the ratio to the target; never fails on a time.

    python bench/gym_speed.py [--search-path ../shared/ros_magna_corpus] [--steps 400]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/gym_speed.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "gymnasium", "pettingzoo", "stable_baselines3", "magna_sim"))

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mlr.gym.env import MagnaNavEnv  # noqa: E402
from mlr.gym.parallel import MagnaNavParallelEnv  # noqa: E402
from mlr.gym.scenario import load_scenario  # noqa: E402
from mlr.gym.vector import SwarmVecEnv  # noqa: E402

TARGET = 2000.0  # agent-steps per second, 2 UAVs, one core
CORPUS = ROOT.parent / "shared" / "ros_magna_corpus"
WORLD, MISSION = "Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder"


def timed(step, agents_per_step: int, steps: int) -> float:
    step()  # warm up: first calls build caches
    started = time.perf_counter()
    for _ in range(steps):
        step()
    return agents_per_step * steps / (time.perf_counter() - started)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--search-path", type=Path, action="append",
                        help=f"where the ROS-MAGNA files are (default {CORPUS} when it exists)")
    parser.add_argument("--steps", type=int, default=400, help="control steps per measurement (default 400)")
    args = parser.parse_args()
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    import torch

    torch.set_num_threads(1)
    scenario = load_scenario(WORLD, MISSION, args.search_path or [CORPUS])
    rng = np.random.default_rng(0)
    rows = []

    single = MagnaNavEnv(scenario=scenario, max_steps=10 ** 9)
    single.reset(seed=0)
    rows.append(("MagnaNavEnv (1 learner, 1 ORCA-3D)", 1, timed(lambda: single.step(rng.uniform(-2, 2, 3)), 1,
                                                               args.steps)))
    single.close()

    parallel = MagnaNavParallelEnv(scenario=scenario, max_steps=10 ** 9)
    parallel.reset(seed=0)

    def parallel_step():
        if not parallel.agents:
            parallel.reset()
        parallel.step({name: rng.uniform(-2, 2, 3) for name in parallel.agents})

    rows.append(("MagnaNavParallelEnv (2 agents)", 2, timed(parallel_step, 2, args.steps)))
    parallel.close()

    for copies in (1, 4, 8, 16):
        venv = SwarmVecEnv(scenario, copies=copies, max_steps=10 ** 9)
        venv.reset()
        rate = timed(lambda v=venv: v.step(rng.uniform(-2, 2, (v.num_envs, 3))), venv.num_envs,
                     max(20, args.steps // copies))
        rows.append((f"SwarmVecEnv, {copies} copies", 2 * copies, rate))
        venv.close()

    print(f"gym speed on one core ({WORLD}, 2 UAVs per copy, 10 Hz control, 240 Hz physics)\n")
    print("| environment | UAVs stepped | agent-steps/s | target | ratio (measured / target) |")
    print("|---|---|---|---|---|")
    for name, uavs, rate in rows:
        print(f"| {name} | {uavs} | {rate:,.0f} | >= {TARGET:,.0f} | {rate / TARGET:.2f} "
              f"({'met' if rate >= TARGET else 'missed'}) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
