"""How fast magna_sim runs: physics alone, then the whole node with the UAL API.

1. Physics only (SimWorld, no ROS): steps per second with 1, 10 and 50 flying
   UAVs in each flight model, at the default 240 Hz (real-time factor = steps/s / 240).
2. The node: `rosrun magna_sim sim` with 10 light UAVs, real_time_factor max,
   UAL topics at 30 Hz, on a private master; the real-time factor is simulated
   time over wall time read from /clock, without subscribers and with one
   subscriber to every UAV's pose, velocity and state.
Prints one table with the ratios to the 10x target; never fails on a time.

    python bench/sim_speed.py [--seconds 10]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/sim_speed.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("rospy", "magna_sim", "magna_master"))

ROOT = Path(__file__).resolve().parent.parent
_DEVEL = ROOT / "devel" / "lib" / "python3" / "dist-packages"
if _DEVEL.is_dir() and str(_DEVEL) not in sys.path:
    sys.path.insert(0, str(_DEVEL))

TARGET_RTF = 10.0  # issue 4: the node with 10 light UAVs
GYM_PYBULLET_DRONES_RTF = 2.0  # their reported figure for 10 drones, physics and control only


def physics_steps_per_second(flight_model: str, uavs: int, seconds: float) -> float:
    from magna_sim.ual_logic import UalState
    from magna_sim.world import SimWorld

    world = SimWorld(seed=1)
    try:
        side = int(uavs ** 0.5 + 0.999)
        for i in range(uavs):
            world.spawn_uav(f"uav_{i + 1}", i + 1, "iris", flight_model, [2.0 * (i % side), 2.0 * (i // side), 0.0])
        world.step()
        for logic in world.ual.values():
            logic.take_off(2.0)
        while any(logic.state != UalState.FLYING_AUTO for logic in world.ual.values()):
            world.step()
        for i, logic in world.ual.items():  # keep every UAV manoeuvring, not just hovering
            logic.go_to([2.0 * (i % side) + 5.0, 2.0 * (i // side), 3.0], 1.0)
        steps, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            for _ in range(50):
                world.step()
            steps += 50
        return steps / (time.perf_counter() - start)
    finally:
        world.close()


def node_real_time_factor(uavs: int, seconds: float, subscribe: bool) -> float:
    import rospy
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from rosgraph_msgs.msg import Clock
    from uav_abstraction_layer.msg import State

    from magna_common.ros_master import RosMaster

    with tempfile.TemporaryDirectory() as logs, RosMaster(log_dir=Path(logs)) as master:
        os.environ.update(master.env())
        master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
        master.spawn(["rosrun", "magna_sim", "sim", f"_uavs:={uavs}", "_real_time_factor:=max"],
                     stdout=open(os.devnull, "w"), stderr=open(os.devnull, "w"))
        latest = {}
        lock = threading.Lock()

        def on_clock(msg):
            with lock:
                latest["sim"], latest["wall"] = msg.clock.to_sec(), time.perf_counter()

        # A plain subscriber, not a rospy node's sim clock: this process keeps wall time.
        rospy.init_node("bench_sim_speed", anonymous=True, disable_signals=True)
        rospy.Subscriber("/clock", Clock, on_clock, queue_size=100)
        received = [0]
        if subscribe:
            def count(_msg):
                received[0] += 1

            for uav_id in range(1, uavs + 1):
                for name, kind in (("pose", PoseStamped), ("velocity", TwistStamped), ("state", State)):
                    rospy.Subscriber(f"/uav_{uav_id}/ual/{name}", kind, count, queue_size=10)
        deadline = time.monotonic() + 60
        while "sim" not in latest and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(2.0)  # let subscriptions connect and the loop reach its pace
        with lock:
            sim0, wall0 = latest["sim"], latest["wall"]
        time.sleep(seconds)
        with lock:
            sim1, wall1 = latest["sim"], latest["wall"]
        rospy.signal_shutdown("bench done")
        return (sim1 - sim0) / (wall1 - wall0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="wall seconds per node measurement")
    parser.add_argument("--physics-seconds", type=float, default=3.0, help="wall seconds per physics measurement")
    args = parser.parse_args()

    rows = []
    for model in ("light", "dynamic"):
        for uavs in (1, 10, 50):
            rate = physics_steps_per_second(model, uavs, args.physics_seconds)
            rows.append((f"physics only, {model}, {uavs} UAVs", rate, rate / 240.0))
    print(f"{'measurement':50} {'steps/s':>10} {'real-time factor':>17}")
    for name, rate, rtf in rows:
        print(f"{name:50} {rate:10.0f} {rtf:16.1f}x")
    light10 = next(r for r in rows if r[0] == "physics only, light, 10 UAVs")[2]
    dynamic10 = next(r for r in rows if r[0] == "physics only, dynamic, 10 UAVs")[2]
    print(f"{'light / dynamic, 10 UAVs':50} {'':>10} {light10 / dynamic10:16.2f}")
    print(f"{'dynamic 10 UAVs / gym-pybullet-drones (2x)':50} {'':>10} "
          f"{dynamic10 / GYM_PYBULLET_DRONES_RTF:16.2f}")
    sys.stdout.flush()
    for subscribe in (False, True):  # each in its own process: rospy allows one init_node per process
        rtf = _in_child(args.seconds, subscribe)
        label = "node, 10 light UAVs, 30 Hz UAL" + (", all subscribed" if subscribe else "")
        print(f"{label:50} {'':>10} {rtf:16.1f}x   ({rtf / TARGET_RTF:.2f} of the 10x target)")
    return 0


def _in_child(seconds: float, subscribe: bool) -> float:
    import subprocess

    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import sim_speed; "
            f"print(sim_speed.node_real_time_factor(10, {seconds!r}, {subscribe!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    if out.returncode != 0:
        raise SystemExit(f"node measurement failed:\n{out.stderr[-2000:]}")
    return float(out.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    sys.exit(main())
