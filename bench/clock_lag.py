"""How far a node's simulated clock trails magna_sim's topics: the margin a test's wait on fresh data needs.

A node with /use_sim_time takes its time from /clock messages, so a pose the simulator stamped can arrive
ahead of that clock. Tests wait for fresh data on that basis instead of sleeping: ual_api_rostest.py's
settle() waits for a pose stamped CAUGHT_UP (simulated seconds) past its clock at a call's return,
and test_sim_node.py allows for `fly`'s clock running behind while it streams velocities. This measures
that lead: for each pose of UAV 1, its stamp minus this node's clock when it arrives (simulated seconds),
for --seconds of wall time with the machine as it is, then as long again with one busy process per core
(this script's own children, ended when it finishes). Prints the two side by side with their ratio;
never fails on a time.

    python bench/clock_lag.py [--rtf max|FACTOR] [--seconds 10]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/clock_lag.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("rospy", "magna_sim", "magna_master"))

ROOT = Path(__file__).resolve().parent.parent
_DEVEL = ROOT / "devel" / "lib" / "python3" / "dist-packages"
if _DEVEL.is_dir() and str(_DEVEL) not in sys.path:
    sys.path.insert(0, str(_DEVEL))

UAL_API_CASES = ROOT / "src" / "magna_sim" / "test" / "ual_api_rostest.py"
BUSY = "import signal\nsignal.signal(signal.SIGINT, signal.SIG_DFL)\nwhile True:\n    pass\n"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python bench/clock_lag.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--rtf", default="4", metavar="max|FACTOR",
                        help="the simulator's real-time factor (default 4, as three_uavs.test)")
    parser.add_argument("--seconds", type=float, default=10.0, help="wall seconds of each of the two phases")
    return parser


def settle_margin() -> float:
    """CAUGHT_UP of ual_api_rostest.py, read from the file the rostest runs."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from tests.support import load_module

    return float(load_module(UAL_API_CASES, "ual_api_cases").CAUGHT_UP)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


class Phase:
    """The leads of the poses, and the simulated time /clock covered, during one phase."""

    def __init__(self, name: str):
        self.name, self.leads, self.clock = name, [], []

    @property
    def rtf(self) -> float:
        (sim0, wall0), (sim1, wall1) = self.clock[0], self.clock[-1]
        return (sim1 - sim0) / (wall1 - wall0) if wall1 > wall0 else 0.0


def measure(rtf: str, seconds: float) -> list[Phase]:
    import rospy
    from geometry_msgs.msg import PoseStamped
    from rosgraph_msgs.msg import Clock

    from magna_common.ros_master import RosMaster

    phases: list[Phase] = []
    lock = threading.Lock()

    def on_pose(msg):
        lead = msg.header.stamp.to_sec() - rospy.get_time()
        with lock:
            if phases:
                phases[-1].leads.append(lead)

    def on_clock(msg):
        with lock:
            if phases:
                phases[-1].clock.append((msg.clock.to_sec(), time.monotonic()))

    with tempfile.TemporaryDirectory() as logs, RosMaster(log_dir=Path(logs)) as master:
        os.environ.update(master.env())
        master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
        master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=1", f"_real_time_factor:={rtf}"],
                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        rospy.init_node("bench_clock_lag", anonymous=True, disable_signals=True)  # on simulated time
        rospy.Subscriber("/uav_1/ual/pose", PoseStamped, on_pose, queue_size=100)
        rospy.Subscriber("/clock", Clock, on_clock, queue_size=100)
        deadline = time.monotonic() + 60
        while rospy.get_time() == 0.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        if rospy.get_time() == 0.0:
            raise SystemExit("magna_sim published no /clock within 60 s")
        for name, busy in (("as it is", 0), (f"{os.cpu_count()} cores busy", os.cpu_count() or 1)):
            burners = [master.spawn([sys.executable, "-c", BUSY], stdin=subprocess.DEVNULL,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(busy)]
            try:
                with lock:
                    phases.append(Phase(name))
                time.sleep(seconds)  # the measuring window itself
            finally:
                from magna_common.processes import end_process_group

                for burner in burners:
                    end_process_group(burner, grace=2.0)
        with lock:
            phases.append(Phase("done"))  # later messages land here
        rospy.signal_shutdown("bench done")
    return phases[:-1]


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    phases = measure(args.rtf, args.seconds)
    print(f"magna_sim with 1 UAV at --rtf {args.rtf}; poses at 30 Hz of simulated time; {args.seconds:g} wall s each")
    idle, busy = phases
    print(f"{'':36} {idle.name:>14} {busy.name:>16} {'busy / idle':>12}")
    print(f"{'real-time factor reached':36} {idle.rtf:13.1f}x {busy.rtf:15.1f}x {busy.rtf / max(idle.rtf, 1e-9):12.2f}")
    print(f"{'poses heard':36} {len(idle.leads):14d} {len(busy.leads):16d}")
    for label, q in (("pose lead over our clock, p50", 0.5), ("pose lead over our clock, p95", 0.95),
                     ("pose lead over our clock, max", 1.0)):
        a, b = percentile(idle.leads, q), percentile(busy.leads, q)
        ratio = f"{b / a:12.2f}" if a > 0.0005 else f"{'-':>12}"
        print(f"{label:36} {a:12.3f} s {b:14.3f} s {ratio}")
    worst, margin = max(busy.leads + idle.leads), settle_margin()
    print(f"{'settle() margin (CAUGHT_UP)':36} {margin:12.3f} s   ({margin / worst:.1f} x the largest lead measured)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
