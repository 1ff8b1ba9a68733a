"""The UAL over MAVLink (issue 24): its set-point stream and its command-to-motion latency, in one run.

One private ROS master, magna_sim at real time (rtf 1.0) with two UAVs on the same physics:
  * UAV 1 is flown directly through magna_sim's own UAL server (as every sitl UAV);
  * UAV 2 is a MAVLink-only UAV (magna_sim's PX4-like vehicle, SpawnModel interface "mavlink") flown by
    `rosrun magna_mavlink ual_mavlink --id 2 --url udpout:127.0.0.1:TAP`, where TAP is a udp_proxy without
    faults in a process of its own (it stands for the vehicle's receiver: it notes the arrival time,
    on the monotonic clock, of every SET_POSITION_TARGET_LOCAL_NED before passing it on).
Both take off to 3 m. Then:
  1. command-to-motion latency, as bench/command_latency.py measures it (its VelocityWatch): --trials
     times per UAV, alternately, while the UAV hovers (|v| < threshold / 2 for 0.5 s, then a random
     0..100 ms), call /uav_N/ual/go_to_waypoint (blocking false) 0.5 m up or down from where it hovers and
     take the wall time to the first /uav_N/ual/velocity with |v| > --threshold (0.05 m/s). The same UAL
     call for both, so the difference is the MAVLink path: ual_mavlink, the link, the vehicle's OFFBOARD
     set-point handling and its telemetry back. Target (DESIGN.md section 6): MAVLink p50 within 2x of
     direct.
  2. the set-point stream's gaps (ual_mavlink streams at 30 Hz: 33.3 ms) as the vehicle side receives
     them: while the latency is measured (no burners), then for --seconds (60) with both cores busy (two
     CPU burners this bench starts and ends): p50, p99 and max in ms, side by side, with ratios to the
     nominal period. PX4 leaves OFFBOARD when set-points stop for its offboard-loss timeout (1 s in
     magna_sim's vehicle): the max gap is the figure to watch.
Every process is started through the ROS master and ended with it. Never fails on a time.

    python bench/mavlink_link.py [--seconds 60] [--trials 20]
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/mavlink_link.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "rospy", "magna_master", "magna_mavlink"))

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
STREAM_PERIOD_MS = 1000.0 / 30.0  # ual_mavlink's set-point rate (magna_mavlink.setpoints.STREAM_RATE)
OFFBOARD_LOSS_MS = 1000.0  # a gap this long makes the vehicle leave OFFBOARD
TARGET_RATIO = 2.0  # MAVLink command-to-motion p50 within 2x of direct
SET_POSITION_TARGET_LOCAL_NED = 84
HEIGHT = 3.0
DIRECT, MAVLINK = 1, 2  # UAV ids


# --- what the vehicle side receives ----------------------------------------------------------------------------

def message_ids(data: bytes) -> list[int]:
    """The message ids of the MAVLink 1 and 2 frames in one datagram (pymavlink sends one per datagram)."""
    ids, i = [], 0
    while i < len(data):
        if data[i] == 0xFD and i + 10 <= len(data):  # v2: STX len incompat compat seq sys comp msgid(3)
            ids.append(int.from_bytes(data[i + 7:i + 10], "little"))
            i += 12 + data[i + 1] + (13 if data[i + 2] & 0x01 else 0)  # + crc, + signature when signed
        elif data[i] == 0xFE and i + 6 <= len(data):  # v1: STX len seq sys comp msgid
            ids.append(data[i + 5])
            i += 8 + data[i + 1]
        else:
            break
    return ids


def run_tap(listen: int, vehicle: int, output: Path) -> int:
    """The tap process: forward between ual_mavlink and the vehicle; note when set-points arrive; write the
    times (monotonic s) to `output` when told to stop (SIGTERM or SIGINT)."""
    from magna_mavlink.udp_proxy import TO_VEHICLE, UdpProxy

    arrivals: list[float] = []

    def observe(direction: str, at: float, data: bytes) -> None:
        if direction == TO_VEHICLE and SET_POSITION_TARGET_LOCAL_NED in message_ids(data):
            arrivals.append(at)

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    with UdpProxy(("127.0.0.1", listen), ("127.0.0.1", vehicle), observe=observe):
        print("tap ready", flush=True)
        stop.wait()
    output.write_text(json.dumps(arrivals))
    return 0


def gap_figures(arrivals: list[float], start: float, end: float) -> dict:
    """Gaps (ms) between set-points that arrived in [start, end]."""
    times = np.array([t for t in arrivals if start <= t <= end])
    gaps = np.diff(times) * 1000.0
    if gaps.size == 0:
        return {"n": int(times.size), "p50": math.nan, "p99": math.nan, "max": math.nan, "rate": math.nan,
                "over_loss": 0}
    return {"n": int(times.size), "p50": float(np.percentile(gaps, 50)), "p99": float(np.percentile(gaps, 99)),
            "max": float(gaps.max()), "rate": (times.size - 1) / (times[-1] - times[0]),
            "over_loss": int((gaps >= OFFBOARD_LOSS_MS).sum())}


# --- load --------------------------------------------------------------------------------------------------

BURN = "import signal\nsignal.signal(signal.SIGINT, signal.SIG_DFL)\nwhile True:\n    pass\n"  # Ctrl-C ends it quietly


def start_burners(master, count: int) -> list[subprocess.Popen]:
    """`count` processes that keep one core busy each, ended by end_burners (or with the master)."""
    return [master.spawn([sys.executable, "-c", BURN], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL) for _ in range(count)]


def end_burners(burners: list[subprocess.Popen]) -> None:
    from magna_common.processes import end_process_group

    for burner in burners:
        end_process_group(burner, grace=2.0)


# --- the command-to-motion trials --------------------------------------------------------------------------

def load_bench(name: str):
    """Another bench script as a module (its measuring parts), as tests/test_bench_cli.py loads them."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from tests.support import load_module

    return load_module(ROOT / "bench" / f"{name}.py", f"bench_{name}")


class Uav:
    """One UAV's UAL as a client sees it: velocity (for motion), pose (for the hover point), state."""

    def __init__(self, uav_id: int, threshold: float, watch_class):
        import rospy
        from geometry_msgs.msg import PoseStamped, TwistStamped
        from uav_abstraction_layer.msg import State

        self.id = uav_id
        self.watch = watch_class(threshold)
        self.pose: PoseStamped | None = None
        self.state = State.UNINITIALIZED
        prefix = f"/uav_{uav_id}/ual"
        self._subscribers = [
            rospy.Subscriber(f"{prefix}/velocity", TwistStamped, self.watch.on_velocity, queue_size=10,
                             tcp_nodelay=True),
            rospy.Subscriber(f"{prefix}/pose", PoseStamped, self._on_pose, queue_size=1),
            rospy.Subscriber(f"{prefix}/state", State, self._on_state, queue_size=10),
        ]
        self.prefix = prefix

    def _on_pose(self, msg) -> None:
        self.pose = msg

    def _on_state(self, msg) -> None:
        self.state = msg.state

    def service(self, name: str, kind):
        import rospy

        rospy.wait_for_service(f"{self.prefix}/{name}", timeout=60.0)
        return rospy.ServiceProxy(f"{self.prefix}/{name}", kind)

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


def wait_for(condition, what: str, timeout: float, alive=None) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if alive is not None:
            alive()
        if time.monotonic() > deadline:
            raise RuntimeError(f"{what} did not happen within {timeout:g} s")
        time.sleep(0.02)


def take_off(uav: Uav) -> None:
    from uav_abstraction_layer.srv import TakeOff

    uav.service("take_off", TakeOff)(height=HEIGHT, blocking=True)
    wait_for(lambda: uav.pose is not None and uav.pose.pose.position.z > HEIGHT - 0.5,
             f"UAV {uav.id} reaching {HEIGHT:g} m", 60.0)


def latency_trials(uavs: list[Uav], args, rng: random.Random) -> dict[int, dict]:
    from geometry_msgs.msg import PoseStamped
    from uav_abstraction_layer.srv import GoToWaypoint

    results = {uav.id: {"latency": [], "timeouts": 0} for uav in uavs}
    go_to = {uav.id: uav.service("go_to_waypoint", GoToWaypoint) for uav in uavs}
    hover = {uav.id: uav.pose for uav in uavs}
    for k in range(args.warmup + args.trials):
        for uav in uavs:
            deadline = time.monotonic() + 20.0
            while uav.watch.hovering_for() < 0.5:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"UAV {uav.id} did not settle (|v| {uav.watch.last_speed:.3f} m/s) "
                                       "within 20 s")
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, 0.1))
            target = PoseStamped()
            target.header.frame_id = hover[uav.id].header.frame_id
            target.pose = copy.deepcopy(hover[uav.id].pose)
            target.pose.position.z = HEIGHT + (args.distance if k % 2 == 0 else 0.0)
            uav.watch.arm()
            t0 = time.perf_counter()
            go_to[uav.id](waypoint=target, blocking=False)
            hit = uav.watch.wait_hit(args.trial_timeout)
            if k < args.warmup:
                continue
            if hit is None:
                results[uav.id]["timeouts"] += 1
            else:
                results[uav.id]["latency"].append(hit[0] - t0)
    return results


# --- the whole run ----------------------------------------------------------------------------------------

def measure(args, folder: Path) -> dict:
    from magna_common.ports import free_udp_ports
    from magna_common.ros_master import RosMaster

    log = open(folder / "processes.log", "wb")
    quiet = {"stdout": log, "stderr": log, "stdin": subprocess.DEVNULL}
    result: dict = {"error": ""}
    master = RosMaster(log_dir=folder / "ros")
    try:
        master.start()
        master.spawn(["rosparam", "set", "/use_sim_time", "true"], **quiet).wait(timeout=30)
        sim = master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=1", "_real_time_factor:=1.0", "_seed:=1"],
                           **quiet)
        os.environ.update(master.env())
        import rosgraph
        import rospy
        from geometry_msgs.msg import Pose
        from magna_msgs.srv import SpawnModel, SpawnModelRequest
        from uav_abstraction_layer.msg import State

        def sim_alive():
            if sim.poll() is not None:
                raise RuntimeError(f"magna_sim ended (status {sim.returncode}); see {folder / 'processes.log'}")

        ros = rosgraph.Master("/mavlink_link_bench", master_uri=master.uri)
        wait_for(lambda: ros.hasParam("/ual_ids") and DIRECT in ros.getParam("/ual_ids"), "magna_sim's UAV 1",
                 60.0, sim_alive)
        rospy.init_node("mavlink_link_bench", anonymous=True, disable_signals=True)
        local, remote, tap_port = free_udp_ports(3)
        rospy.wait_for_service("/magna/sim/spawn_model", timeout=30.0)
        pose = Pose()
        pose.position.y, pose.position.z, pose.orientation.w = 2.0, 0.05, 1.0  # 2 m beside UAV 1
        answer = rospy.ServiceProxy("/magna/sim/spawn_model", SpawnModel)(SpawnModelRequest(
            name=f"uav_{MAVLINK}", kind="uav", pose=pose, uav_id=MAVLINK, interface="mavlink",
            mavlink_local_port=local, mavlink_remote_port=remote))
        if not answer.success:
            raise RuntimeError(f"magna_sim refused the MAVLink UAV: {answer.message}")
        tap_file = folder / "setpoints.json"
        tap = master.spawn([sys.executable, __file__, "--tap-worker", "--tap-listen", str(tap_port),
                            "--tap-to", str(local), "--worker-output", str(tap_file)],
                           stdout=subprocess.PIPE, stderr=log, stdin=subprocess.DEVNULL, text=True)
        if tap.stdout.readline().strip() != "tap ready":
            raise RuntimeError(f"the tap did not start; see {folder / 'processes.log'}")
        bridge = master.spawn(["rosrun", "magna_mavlink", "ual_mavlink", "--id", str(MAVLINK), "--url",
                               f"udpout:127.0.0.1:{tap_port}", "--arming", "auto"], **quiet)
        watch_class = load_bench("command_latency").VelocityWatch
        uavs = [Uav(DIRECT, args.threshold, watch_class), Uav(MAVLINK, args.threshold, watch_class)]

        def bridge_alive():
            sim_alive()
            if bridge.poll() is not None:
                raise RuntimeError(f"ual_mavlink ended (status {bridge.returncode}); see {folder / 'processes.log'}")

        for uav in uavs:
            wait_for(lambda u=uav: u.state in (State.LANDED_ARMED, State.LANDED_DISARMED) and u.pose is not None,
                     f"UAV {uav.id}'s UAL to report it landed", 90.0, bridge_alive)
        for uav in uavs:
            take_off(uav)
        print(f"both UAVs hover at {HEIGHT:g} m; {args.warmup} + {args.trials} commands each ...", flush=True)
        idle_start = time.monotonic()
        result["latency"] = latency_trials(uavs, args, random.Random(args.seed))
        idle_end = time.monotonic()
        bridge_alive()
        print(f"set-point stream with both cores busy for {args.seconds:g} s ...", flush=True)
        burners = start_burners(master, os.cpu_count() or 2)
        time.sleep(1.0)  # let the scheduler settle on the new load
        busy_start = time.monotonic()
        time.sleep(args.seconds)
        busy_end = time.monotonic()
        load = os.getloadavg()[0]
        end_burners(burners)
        bridge_alive()
        result["states_after"] = {uav.id: uav.state for uav in uavs}
        tap.send_signal(signal.SIGTERM)
        tap.wait(timeout=30)
        arrivals = json.loads(tap_file.read_text())
        result["gaps_idle"] = gap_figures(arrivals, idle_start, idle_end)
        result["gaps_busy"] = gap_figures(arrivals, busy_start, busy_end)
        result["load"] = load
        result["burners"] = len(burners)
        for uav in uavs:
            uav.close()
        rospy.signal_shutdown("bench done")
    except Exception as error:  # reported; the clean-up below still runs
        result["error"] = f"{type(error).__name__}: {error}"
    finally:
        master.stop()
        log.close()
    return result


# --- the figures ------------------------------------------------------------------------------------------

def percentile(values, q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else math.nan


def print_figures(result: dict, args) -> None:
    names = {DIRECT: "direct (magna_sim UAL)", MAVLINK: "MAVLink (ual_mavlink)"}
    latency = result.get("latency", {})
    if latency:
        print(f"\ncommand-to-motion latency: /uav_N/ual/go_to_waypoint {args.distance:g} m up/down (blocking "
              f"false) -> first /uav_N/ual/velocity with |v| > {args.threshold:g} m/s; rtf 1.0, ms of wall time")
        head = f"{'UAV':<24} {'n':>3} {'p50':>7} {'p90':>7} {'max':>7} {'miss':>4}"
        print(head)
        print("-" * len(head))
        p50 = {}
        for uav_id in (DIRECT, MAVLINK):
            row = latency.get(uav_id) or latency.get(str(uav_id)) or {"latency": [], "timeouts": 0}
            ms = np.array(row["latency"]) * 1000
            p50[uav_id] = percentile(ms, 50)
            print(f"{names[uav_id]:<24} {ms.size:>3} {p50[uav_id]:>7.1f} {percentile(ms, 90):>7.1f} "
                  f"{(ms.max() if ms.size else math.nan):>7.1f} {row['timeouts']:>4}")
        ratio = p50[MAVLINK] / p50[DIRECT] if p50[DIRECT] > 0 else math.nan
        verdict = "meets" if ratio <= TARGET_RATIO else "misses"
        print(f"MAVLink / direct p50: {ratio:.2f}x (target <= {TARGET_RATIO:g}x: {verdict})")
    idle, busy = result.get("gaps_idle"), result.get("gaps_busy")
    if idle and busy:
        print(f"\nset-point stream (SET_POSITION_TARGET_LOCAL_NED as the vehicle side receives them; nominal "
              f"{STREAM_PERIOD_MS:.1f} ms), gaps in ms")
        head = (f"{'':<20} {'n':>6} {'Hz':>6} {'p50':>7} {'p99':>7} {'max':>7} {'>=1 s':>6} "
                f"{'p99 / period':>13} {'max / period':>13}")
        print(head)
        print("-" * len(head))
        for label, g in (("no burners (trials)", idle), (f"{result.get('burners', 2)} burners busy", busy)):
            print(f"{label:<20} {g['n']:>6} {g['rate']:>6.1f} {g['p50']:>7.1f} {g['p99']:>7.1f} {g['max']:>7.1f} "
                  f"{g['over_loss']:>6} {g['p99'] / STREAM_PERIOD_MS:>12.2f}x {g['max'] / STREAM_PERIOD_MS:>12.2f}x")
        print(f"busy / no burners: p99 {busy['p99'] / idle['p99']:.2f}x, max {busy['max'] / idle['max']:.2f}x; "
              f">=1 s = gaps at or over the vehicle's offboard-loss timeout (it would leave OFFBOARD); "
              f"load average {result.get('load', math.nan):.1f} on {os.cpu_count()} cores")
    states = result.get("states_after")
    if states:
        from magna_mavlink.ual_state import NAMES

        print("UAL states after the busy span: " + ", ".join(f"UAV {k} {NAMES[v]}" for k, v in states.items()))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python bench/mavlink_link.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="wall s of the set-point stream with both "
                        "cores busy (default 60)")
    parser.add_argument("--trials", type=int, default=20, help="commands measured per UAV (default 20)")
    parser.add_argument("--warmup", type=int, default=2, help="commands sent first and not counted (default 2)")
    parser.add_argument("--distance", type=float, default=0.5, help="metres per move (default 0.5)")
    parser.add_argument("--threshold", type=float, default=0.05, help="|v| in m/s that counts as motion")
    parser.add_argument("--trial-timeout", type=float, default=5.0, help="wall s to wait for motion")
    parser.add_argument("--seed", type=int, default=1, help="seed of the random waits before commands")
    parser.add_argument("--tap-worker", action="store_true", help=argparse.SUPPRESS)  # the tap's own process
    parser.add_argument("--tap-listen", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--tap-to", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--worker-output", type=Path, help=argparse.SUPPRESS)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.tap_worker:
        return run_tap(args.tap_listen, args.tap_to, args.worker_output)
    if args.seconds <= 0 or args.trials < 1:
        parser.error("--seconds must be positive and --trials at least 1")
    print(f"MAVLink bench: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="mavlink_link_") as folder:
        result = measure(args, Path(folder))
        if result["error"]:
            log = Path(folder) / "processes.log"
            tail = log.read_text(errors="replace")[-3000:] if log.exists() else ""
            print(f"failed: {result['error']}\n--- last lines of the processes' output ---\n{tail}", flush=True)
    print_figures(result, args)
    print(f"\n{time.monotonic() - started:.0f} s in all")
    return 1 if result["error"] else 0


if __name__ == "__main__":
    sys.exit(main())
