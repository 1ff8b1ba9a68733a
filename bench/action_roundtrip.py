"""Goal round trip of MAGNA's SimpleAction protocol against Debian's actionlib.

One goal round trip: the client sends a goal, the server's execute callback sets
it succeeded, the client has the result (`wait_for_result` returns). Measured
for our server+client, actionlib's server+client and the two cross pairs, on a
private ROS master, server and client in this one process (one rospy node).
Prints figures; never fails on a time.

    python bench/action_roundtrip.py [--goals N]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/action_roundtrip.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("rospy", "actionlib", "magna_sm", "magna_master"))

ROOT = Path(__file__).resolve().parent.parent
_DEVEL = ROOT / "devel" / "lib" / "python3" / "dist-packages"
if _DEVEL.is_dir() and str(_DEVEL) not in sys.path:
    sys.path.insert(0, str(_DEVEL))

PAIRS = {
    "ours": ("ours", "ours"),
    "actionlib": ("actionlib", "actionlib"),
    "ours-server": ("ours", "actionlib"),
    "ours-client": ("actionlib", "ours"),
}


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    rank = q / 100.0 * (len(ordered) - 1)
    low = int(rank)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (rank - low)


def make_server(kind: str, ns: str):
    import actionlib
    from magna_msgs.msg import TakeOffAction, TakeOffResult

    from magna_sm.simple_action import SimpleActionServer

    holder = {}

    def execute(goal):
        holder["server"].set_succeeded(TakeOffResult(outcome="ok"))

    cls = SimpleActionServer if kind == "ours" else actionlib.SimpleActionServer
    server = cls(ns, TakeOffAction, execute_cb=execute, auto_start=False)
    holder["server"] = server
    server.start()
    return server


def stop_server(kind: str, server) -> None:
    if kind == "ours":
        server.shutdown()
        return
    with server.terminate_mutex:
        server.need_to_terminate = True
    server.action_server.stop()
    server.execute_thread.join(5.0)


def make_client(kind: str, ns: str):
    import actionlib
    from magna_msgs.msg import TakeOffAction

    from magna_sm.simple_action import SimpleActionClient

    cls = SimpleActionClient if kind == "ours" else actionlib.SimpleActionClient
    return cls(ns, TakeOffAction)


def stop_client(kind: str, client) -> None:
    if kind == "ours":
        client.stop()
    else:
        client.action_client.stop()


def measure(server_kind: str, client_kind: str, goals: int, warmup: int, ns: str) -> dict:
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffGoal

    server = make_server(server_kind, ns)
    client = make_client(client_kind, ns)
    try:
        if not client.wait_for_server(rospy.Duration(30.0)):
            return {"error": "the client never saw the server"}
        samples, failures = [], 0
        for index in range(warmup + goals):
            start = time.perf_counter()
            client.send_goal(TakeOffGoal(height=1.0))
            finished = client.wait_for_result(rospy.Duration(10.0))
            elapsed = (time.perf_counter() - start) * 1e3
            if not finished or client.get_state() != GoalStatus.SUCCEEDED:
                failures += 1
                continue
            if index >= warmup:
                samples.append(elapsed)
        return {"samples": samples, "failures": failures}
    finally:
        stop_client(client_kind, client)
        stop_server(server_kind, server)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--goals", type=int, default=200, help="measured goals per pair (default 200)")
    parser.add_argument("--warmup", type=int, default=20, help="goals sent first and not measured (default 20)")
    parser.add_argument("--pairs", nargs="+", choices=sorted(PAIRS), default=list(PAIRS),
                        help="pairs to measure: ours (our server+client), actionlib (stock server+client), "
                             "ours-server (our server, stock client), ours-client (stock server, our client)")
    args = parser.parse_args(argv)

    from magna_common.ros_master import RosMaster

    with tempfile.TemporaryDirectory(prefix="action_bench_") as log_dir, RosMaster(log_dir=Path(log_dir)) as master:
        os.environ.update(master.env())
        import rospy

        rospy.init_node("action_roundtrip_bench", anonymous=True, disable_signals=True)
        rows = {}
        try:
            for name in args.pairs:
                server_kind, client_kind = PAIRS[name]
                ns = "/bench/" + name.replace("-", "_")
                rows[name] = measure(server_kind, client_kind, args.goals, args.warmup, ns)
        finally:
            rospy.signal_shutdown("benchmark done")

    print(f"Goal round trip (send_goal -> execute_cb set_succeeded -> wait_for_result), {args.goals} goals per pair "
          f"after {args.warmup} warm-up goals; server and client in one process, private master.")
    header = (f"{'pair':<12} {'server':<10} {'client':<10} {'p50 ms':>8} {'p90 ms':>8} {'mean ms':>8} "
              f"{'max ms':>8} {'fail':>5}")
    print(header)
    print("-" * len(header))
    stats = {}
    for name, row in rows.items():
        server_kind, client_kind = PAIRS[name]
        if "error" in row or not row["samples"]:
            print(f"{name:<12} {server_kind:<10} {client_kind:<10} {row.get('error', 'no samples')}")
            continue
        samples = row["samples"]
        stats[name] = (percentile(samples, 50), percentile(samples, 90))
        print(f"{name:<12} {server_kind:<10} {client_kind:<10} {stats[name][0]:>8.2f} {stats[name][1]:>8.2f} "
              f"{statistics.fmean(samples):>8.2f} {max(samples):>8.2f} {row['failures']:>5}")
    if "ours" in stats and "actionlib" in stats:
        (o50, o90), (a50, a90) = stats["ours"], stats["actionlib"]
        print(f"ratio ours/actionlib: p50 {o50 / a50:.2f}, p90 {o90 / a90:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
