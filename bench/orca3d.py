"""ORCA-3D speed: the C++ library, the numpy reference on the same inputs, and the service.

Prints, in one run:
  * microseconds per agent with 1, 5, 10 and 50 neighbours (C++ one-shot solves, input
    reading excluded), the numpy reference on the same scenarios, and their ratio;
  * one step of 1000 agents (k-d tree neighbour search + 1000 programs), C++ and numpy;
  * the service round trip on loopback (p50/p99), one agent with 10 neighbours and a
    1000-agent batch, against orca3d_server on a private ROS master.
Targets (DESIGN.md section 6): <= 5 us per agent with 10 neighbours, >= 50x the numpy
reference, 1000 agents in < 5 ms. Never fails on a time.

    python bench/orca3d.py [--scenarios N] [--calls N] [--no-service]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/orca3d.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "magna_orca_cpp"))

import numpy as np  # noqa: E402

from magna_orca_cpp import native, reference  # noqa: E402
from magna_orca_cpp.model import Params, agent_rows  # noqa: E402
from magna_orca_cpp.scenarios import crowd, random_scenario  # noqa: E402

NEIGHBOR_COUNTS = (1, 5, 10, 50)
TARGET_US_PER_AGENT = 5.0
TARGET_RATIO = 50.0
TARGET_STEP_MS = 5.0


def same_params_scenarios(n_neighbors: int, count: int, seed: int):
    """`count` scenarios with exactly `n_neighbors` neighbours, all seen (shared params)."""
    rng = np.random.default_rng(seed)
    params = Params(max_neighbors=n_neighbors, neighbor_dist=100.0, time_horizon=3.0, time_step=0.1)
    return [random_scenario(rng, n_neighbors, params) for _ in range(count)], params


def time_cpp_one_shot(scenarios, params, repeats: int = 5) -> float:
    """Best-of-`repeats` microseconds per agent."""
    agents = agent_rows([s.agent for s in scenarios])
    others = np.concatenate([agent_rows(s.neighbors) for s in scenarios])
    offsets = np.concatenate([[0], np.cumsum([len(s.neighbors) for s in scenarios])])
    best = min(native.new_velocity_many(agents, others, offsets, params)[2] for _ in range(repeats))
    return best / len(scenarios) * 1e6


def time_python_one_shot(scenarios, params) -> float:
    start = time.perf_counter()
    for s in scenarios:
        reference.new_velocity(s.agent, s.neighbors, params)
    return (time.perf_counter() - start) / len(scenarios) * 1e6


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    rank = q / 100 * (len(ordered) - 1)
    low = int(rank)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (rank - low)


def service_round_trips(calls: int) -> dict[str, list[float]]:
    """Wall-clock round trips (s) of both services against orca3d_server on a private master."""
    from magna_common.ros_master import RosMaster

    with tempfile.TemporaryDirectory(prefix="orca_bench_") as log_dir, RosMaster(log_dir=Path(log_dir)) as master:
        master.spawn(["rosrun", "magna_orca_cpp", "orca3d_server"], stdout=subprocess.DEVNULL)
        import os

        os.environ.update(master.env())
        import rospy

        from magna_orca_cpp.service_client import OrcaServiceClient

        rospy.init_node("orca3d_bench", anonymous=True, disable_signals=True)
        try:
            client = OrcaServiceClient()
            if not client.wait(30.0):
                raise RuntimeError("orca3d_server did not come up within 30 s")
            scenarios, params = same_params_scenarios(10, calls, seed=11)
            swarm_params = Params(max_neighbors=10, neighbor_dist=3.0, time_horizon=2.0, time_step=0.1)
            swarm = crowd(seed=5, n_agents=1000, spacing=1.6, params=swarm_params)
            samples: dict[str, list[float]] = {"one agent, 10 neighbours": [], "1000-agent batch": []}
            for k in range(calls + 10):  # the first ten warm the connection up
                s = scenarios[k % calls]
                start = time.perf_counter()
                client.new_velocity(s.agent, s.neighbors, params)
                if k >= 10:
                    samples["one agent, 10 neighbours"].append(time.perf_counter() - start)
            for k in range(max(calls // 20, 5) + 2):
                start = time.perf_counter()
                client.new_velocities(swarm, swarm_params)
                if k >= 2:
                    samples["1000-agent batch"].append(time.perf_counter() - start)
            client.close()
            return samples
        finally:
            rospy.signal_shutdown("benchmark done")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", type=int, default=2000, help="C++ scenarios per neighbour count (default 2000)")
    parser.add_argument("--python-scenarios", type=int, default=200,
                        help="of those, how many the numpy reference solves (default 200)")
    parser.add_argument("--calls", type=int, default=1000, help="service calls for the round-trip figure")
    parser.add_argument("--no-service", action="store_true", help="skip the ROS service round trip")
    args = parser.parse_args(argv)
    if not native.available():
        print("bench/orca3d.py: the C++ library is not built; run `make setup` first", file=sys.stderr)
        return 2

    print("ORCA-3D, one agent against n neighbours (microseconds per agent)")
    print(f"{'neighbours':>10} {'C++ us':>9} {'numpy us':>10} {'ratio':>8} {'infeasible':>11}")
    for n in NEIGHBOR_COUNTS:
        scenarios, params = same_params_scenarios(n, args.scenarios, seed=n)
        cpp = time_cpp_one_shot(scenarios, params)
        py = time_python_one_shot(scenarios[:args.python_scenarios], params)
        infeasible = np.mean([not native.new_velocity(s.agent, s.neighbors, params).feasible for s in scenarios[:500]])
        print(f"{n:>10} {cpp:>9.2f} {py:>10.1f} {py / cpp:>7.0f}x {infeasible:>10.0%}")
        if n == 10:
            ten = (cpp, py / cpp)

    params = Params(max_neighbors=10, neighbor_dist=3.0, time_horizon=2.0, time_step=0.1)
    agents = crowd(seed=1000, n_agents=1000, spacing=1.6, params=params)
    rows = agent_rows(agents)
    step_ms = min(native.new_velocities_array(rows, params)[2] for _ in range(20)) * 1e3
    start = time.perf_counter()
    reference.new_velocities(agents, params)
    py_step_ms = (time.perf_counter() - start) * 1e3
    print("\nOne step of 1000 agents (10 neighbours each, k-d tree search included)")
    print(f"  C++ {step_ms:.2f} ms   numpy {py_step_ms:.0f} ms   ratio {py_step_ms / step_ms:.0f}x")

    if not args.no_service:
        print(f"\nService round trip on loopback, wall clock ({args.calls} calls, persistent connection)")
        for name, samples in service_round_trips(args.calls).items():
            ms = [s * 1e3 for s in samples]
            print(f"  {name:<26} p50 {percentile(ms, 50):7.3f} ms   p99 {percentile(ms, 99):7.3f} ms   "
                  f"mean {statistics.fmean(ms):7.3f} ms   ({len(ms)} calls)")

    print("\nTargets (DESIGN.md section 6)")
    print(f"  per agent with 10 neighbours  {ten[0]:.2f} us   (target <= {TARGET_US_PER_AGENT} us: "
          f"{ten[0] / TARGET_US_PER_AGENT:.0%} of it)")
    print(f"  C++ over numpy                {ten[1]:.0f}x     (target >= {TARGET_RATIO:.0f}x)")
    print(f"  1000-agent step               {step_ms:.2f} ms   (target < {TARGET_STEP_MS} ms: "
          f"{step_ms / TARGET_STEP_MS:.0%} of it)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
