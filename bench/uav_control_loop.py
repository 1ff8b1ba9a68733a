"""UAV managers' control loop with 2 and 10 UAVs: the rate each loop reaches on this machine.

For each fleet size: magna_sim (as fast as it can go, rtf max), orca3d_server and one
UAV manager per UAV on a private ROS master. Every UAV takes off, then all fly ORCA-3D
paths that cross near the middle. From the recorders' CSVs (one row per control step):
  * steps per simulated second (the loop asks for 10: fewer means it fell behind),
  * steps per wall second, per UAV (the loop rate times the simulation's speed) and for the fleet,
  * how much faster than real time the simulation ran while they flew.
Prints figures; never fails on a time.

    python bench/uav_control_loop.py [--fleets 2 10] [--rate 10]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/uav_control_loop.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "rospy", "magna_master", "magna_uav"))

import numpy as np  # noqa: E402


def wait_all(clients, limit: float) -> list:
    import rospy

    deadline = time.monotonic() + limit
    for client in clients:
        while not client.wait_for_result(rospy.Duration(0.5)):
            if time.monotonic() > deadline:
                raise RuntimeError(f"no result within {limit:g} s of wall time")
    return [c.get_result() for c in clients]


def fly_fleet(n: int, rate: float, folder: Path) -> dict:
    from magna_common.ros_master import RosMaster

    ids = list(range(1, n + 1))
    with RosMaster(log_dir=folder / "ros_log") as master:
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
        master.spawn(["roslaunch", "magna_sim", "sim.launch", f"uavs:={n}", "rtf:=max", "seed:=3", "output:=log"],
                     **quiet)
        master.spawn(["rosrun", "magna_orca_cpp", "orca3d_server"], **quiet)
        for i in ids:
            master.spawn(["rosrun", "magna_uav", "uav_manager", f"__name:=uav_{i}_manager", f"_id:={i}",
                          f"_uav_ids:={ids}", f"_control_rate:={rate}", "_algorithm:=orca3",
                          f"_data_dir:={folder}"], **quiet)
        os.environ.update(master.env())
        import rospy
        from magna_msgs.msg import (
            FollowPathAction,
            FollowPathGoal,
            SaveCSVAction,
            SaveCSVGoal,
            TakeOffAction,
            TakeOffGoal,
        )

        from magna_sm.simple_action import SimpleActionClient
        from magna_uav.commanders import pose_stamped

        rospy.init_node("uav_control_loop_bench", anonymous=True, disable_signals=True)
        try:
            def clients(action, spec):
                made = [SimpleActionClient(f"/magna/uav_{i}/{action}", spec) for i in ids]
                for c in made:
                    if not c.wait_for_server(rospy.Duration(120.0)):
                        raise RuntimeError(f"UAV managers not up ({action})")
                return made

            take_off, paths, save = (clients("take_off", TakeOffAction), clients("follow_path", FollowPathAction),
                                     clients("save_csv", SaveCSVAction))
            for c in take_off:
                c.send_goal(TakeOffGoal(height=3.0))
            wait_all(take_off, 300)
            # Side by side along y, 2 m apart: each crosses to the mirrored place 10 m ahead.
            ys = [(i - (n + 1) / 2) * 2.0 for i in ids]
            wall0 = time.monotonic()
            for c, y in zip(paths, ys, strict=True):
                c.send_goal(FollowPathGoal(path=[pose_stamped((10.0, -y, 3.0))], dynamic="velocity"))
            results = wait_all(paths, 600)
            wall = time.monotonic() - wall0
            for i, c in zip(ids, save, strict=True):
                c.send_goal(SaveCSVGoal(path=str(folder / f"uav_{i}.csv")))
            wait_all(save, 60)
        finally:
            rospy.signal_shutdown("bench done")
    from magna_uav.recorder import read_csv

    per_uav_sim, steps_total, first, last = [], 0, np.inf, -np.inf
    for i in ids:
        _, rows = read_csv(folder / f"uav_{i}.csv")
        flown = [r["time"] for r in rows if r["role"] == "path"]  # sim time of each control step
        span = flown[-1] - flown[0]
        per_uav_sim.append((len(flown) - 1) / span if span > 0 else float("nan"))
        steps_total += len(flown)
        first, last = min(first, flown[0]), max(last, flown[-1])
    sim = last - first  # simulated seconds the paths took
    return {"n": n, "outcomes": [r.outcome for r in results], "wall": wall, "sim": sim,
            "sim_rate": float(np.median(per_uav_sim)), "sim_rate_min": float(np.min(per_uav_sim)),
            "wall_rate": float(np.median(per_uav_sim)) * sim / wall, "fleet_wall_rate": steps_total / wall}


def build_parser() -> argparse.ArgumentParser:
    from magna_common.cli_vocabulary import add_deprecated_option

    parser = argparse.ArgumentParser(prog="python bench/uav_control_loop.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--fleets", type=int, nargs="+", default=[2, 10], help="fleet sizes (default 2 10)")
    parser.add_argument("--rate", type=float, default=10.0, help="control steps per simulated second (default 10)")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)  # one fleet, in its own process
    parser.add_argument("--worker-output", type=Path, help=argparse.SUPPRESS)  # where that process writes its row
    add_deprecated_option(parser, "--out", "worker_output", "--worker-output", type=Path)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.worker:
        with tempfile.TemporaryDirectory(prefix=f"uav_loop_{args.worker}_") as folder:
            args.worker_output.write_text(json.dumps(fly_fleet(args.worker, args.rate, Path(folder))))
        return 0
    rows = []
    for n in args.fleets:
        # rospy allows one node per process: each fleet is flown by a process of its own.
        print(f"flying {n} UAVs ...", flush=True)
        with tempfile.NamedTemporaryFile(suffix=".json") as out:
            subprocess.run([sys.executable, __file__, "--worker", str(n), "--rate", str(args.rate),
                            "--worker-output", out.name],
                           check=True)
            rows.append(json.loads(Path(out.name).read_text()))
    print(f"\nUAV manager control loop (asked: {args.rate:g} steps per simulated second), magna_sim rtf max, "
          f"ORCA-3D service, {os.cpu_count()} cores")
    print(f"{'UAVs':>5} {'steps/sim s (median, min)':>27} {'steps/wall s per UAV':>21} {'fleet steps/wall s':>19} "
          f"{'sim/wall':>9}  outcomes")
    for r in rows:
        done = sum(o == "succeeded" for o in r["outcomes"])
        print(f"{r['n']:>5} {r['sim_rate']:>17.2f}, {r['sim_rate_min']:>7.2f} {r['wall_rate']:>21.1f} "
              f"{r['fleet_wall_rate']:>19.1f} {r['sim'] / r['wall']:>8.1f}x  {done}/{r['n']} succeeded")
    return 0


if __name__ == "__main__":
    sys.exit(main())
