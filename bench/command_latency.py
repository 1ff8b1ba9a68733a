"""Command-to-motion latency, as the original thesis's Experiment III, with 1, 2, 3 and 10 UAVs.

Per fleet size N, in a process of its own (rospy allows one node per process):
  * a private ROS master (magna_common.ros_master.RosMaster) and `roslaunch magna_gs simulation.launch`
    at rtf 1.0 (real time), no bag, no data, button_timeout 0, in the world Gym/Central_Obstacle_Torus;
  * its mission (generated into a temporary folder): N UAVs spawned on two rows of pads at the ground
    station, all take off to 3 m, then a `wait` for the operator's button, forever;
  * once the mission waits: --trials times (default 30, after --warmup 2 not counted), while UAV 1
    hovers (|v| < threshold / 2 for 0.5 s, then a random 0..100 ms so the call falls anywhere in the
    control and publishing periods), call /magna/gs/command (magna_msgs/GroundStationCommand:
    basic_action move, direction up / down alternately, distance 0.5 m, agent "1" or --agent all)
    and take the wall time from the call to the arrival of the first /uav_1/ual/velocity message
    with |v| > --threshold (default 0.05 m/s);
  * then the button (/magna/gs/continue): the UAVs land and the launch ends; every process is ended.

Prints p50 / p90 / p99 per fleet size, the service's round trip, the same latency in simulated time
(stamp of that velocity message minus the /clock at the call), how fast the simulation really ran,
and the growth of p50 from 1 to 10 UAVs, against DESIGN.md section 6: p50 <= 50 ms wall, growing
<= 20% from 1 to 10 UAVs. Saves the box plot and CDF per fleet size (the figure of
magna_viz.plots.plot_latency_distribution) to -o/--output, by default bench/pictures/command_latency.png,
which it replaces only with --force (checked before measuring).
Never fails on a time. The default run takes about 8 minutes.

    python bench/command_latency.py [--fleets 1 2 3 10] [--trials 30] [--agent 1|all] [-o PATH.png] [--force]
"""
from __future__ import annotations

import argparse
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
import uuid
from pathlib import Path

if __name__ == "__main__":  # `python bench/command_latency.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "rospy", "magna_master", "magna_viz"))

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PICTURE = ROOT / "bench" / "pictures" / "command_latency.png"
WORLD, SUBWORLD = "Gym", "Central_Obstacle_Torus"
TARGET_P50_S = 0.050
TARGET_GROWTH = 0.20
WAIT_STATE = "operator_button"


# --- the mission ---------------------------------------------------------------------------------------------

def pads(n: int) -> list[list[float]]:
    """Two rows of 5 pads, 2 m apart, in the Ground_Station volume's frame (in front of the world's own 4)."""
    return [[-4.0 + 2.0 * (k % 5), -2.0 * (k // 5), 0.05] for k in range(n)]


def hover_mission(n: int) -> dict:
    """N UAVs take off to 3 m and wait for the operator's button; then they land."""
    agents = [{"ID": i, "model": "iris", "mode": "sitl", "marker_color": [255, 40 * (i % 6), 0, 0.8]}
              for i in range(1, n + 1)]
    machine = [
        {"type": "CBState", "state_type": "world_config", "name": "new_world",
         "parameters": {"action": "spawn", "id": 1}, "outcomes": {"completed": "add_world"}},
        {"type": "CBState", "state_type": "world_config", "name": "add_world",
         "parameters": {"action": "add", "world_part_def": "from_hyperparameters"},
         "outcomes": {"completed": "spawn_agents", "failed": "failed"}},
        {"type": "CBState", "state_type": "spawn_agents", "name": "spawn_agents",
         "parameters": {"initial_poses": [["Ground_Station", "volume", "coordinates", [p, [0, 0, 0]], 1.570796]
                                          for p in pads(n)]},
         "outcomes": {"completed": "1_take_off", "failed": "failed"}},
        {"type": "Concurrence", "name": "take_off", "ids": 1,
         "occurrencies": [{"type": "SimpleActionState", "state_type": "take_off", "name": "take_off", "ids": "all",
                           "ids_var": "agent", "parameters": {"height": 3.0}}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "failed": {"all": "aborted"}},
         "outcomes": {"completed": WAIT_STATE, "failed": "failed"}},
        {"type": "CBState", "state_type": "wait", "name": WAIT_STATE, "parameters": {"exit_type": "button"},
         "outcomes": {"completed": "1_land", "failed": "1_land"}},
        {"type": "Concurrence", "name": "land", "ids": 1,
         "occurrencies": [{"type": "SimpleActionState", "state_type": "land", "name": "land", "ids": "all",
                           "ids_var": "agent"}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "failed": {"all": "aborted"}},
         "outcomes": {"completed": "completed", "failed": "failed"}},
    ]
    return {"Agents_Config": agents, "State_Machine": machine}


# --- one fleet size, in its own process -----------------------------------------------------------------------

class VelocityWatch:
    """Speed of UAV 1 as it arrives: hover detection, and the first message above a threshold after a mark."""

    def __init__(self, threshold: float):
        self.threshold = threshold
        self.cond = threading.Condition()
        self.last_speed = math.inf
        self.last_wall = 0.0
        self.below_since: float | None = None  # wall time since |v| stays under threshold / 2
        self.armed_at: float | None = None
        self.hit: tuple[float, float, float] | None = None  # (wall, stamp, speed)

    def on_velocity(self, msg) -> None:
        now = time.perf_counter()
        v = msg.twist.linear
        speed = math.sqrt(v.x * v.x + v.y * v.y + v.z * v.z)
        with self.cond:
            self.last_speed, self.last_wall = speed, now
            if speed < self.threshold / 2:
                if self.below_since is None:
                    self.below_since = now
            else:
                self.below_since = None
            if self.armed_at is not None and self.hit is None and speed > self.threshold:
                self.hit = (now, msg.header.stamp.to_sec(), speed)
                self.cond.notify_all()

    def hovering_for(self) -> float:
        with self.cond:
            if self.below_since is None or time.perf_counter() - self.last_wall > 0.5:
                return 0.0
            return time.perf_counter() - self.below_since

    def arm(self) -> None:
        with self.cond:
            self.armed_at, self.hit = time.perf_counter(), None

    def wait_hit(self, timeout: float):
        with self.cond:
            self.cond.wait_for(lambda: self.hit is not None, timeout)
            hit, self.armed_at = self.hit, None
            return hit


class ClockWatch:
    def __init__(self):
        self.lock = threading.Lock()
        self.sim = math.nan
        self.samples: list[tuple[float, float]] = []  # (wall, sim), one per message

    def on_clock(self, msg) -> None:
        now, sim = time.perf_counter(), msg.clock.to_sec()
        with self.lock:
            self.sim = sim
            self.samples.append((now, sim))

    def now(self) -> float:
        with self.lock:
            return self.sim

    def factor(self, since: float) -> float:
        with self.lock:
            kept = [s for s in self.samples if s[0] >= since]
        if len(kept) < 2 or kept[-1][0] <= kept[0][0]:
            return math.nan
        return (kept[-1][1] - kept[0][1]) / (kept[-1][0] - kept[0][0])


def measure_fleet(n: int, args, folder: Path) -> dict:
    from magna_common.processes import TOKEN_ENV, kill_tagged
    from magna_common.ros_master import RosMaster

    mission_file = folder / f"{n}UAVs_Hover.json"
    mission_file.write_text(json.dumps(hover_mission(n), indent=1))
    token = uuid.uuid4().hex  # every process of this simulation carries it, the UAV managers too
    launch_log = open(folder / "launch.log", "wb")
    result = {"n": n, "latency": [], "rtt": [], "sim_latency": [], "timeouts": 0, "refused": [], "error": ""}
    started = time.monotonic()
    master = RosMaster(log_dir=folder / "ros")
    try:
        master.start()
        env = dict(os.environ)
        env[TOKEN_ENV] = token
        launch = master.spawn(
            ["roslaunch", "--sigint-timeout=5", "--sigterm-timeout=2", "magna_gs", "simulation.launch",
             f"mission_file:={mission_file}", f"world:={WORLD}", f"subworld:={SUBWORLD}",
             f"worlds_path:={ROOT / 'worlds'}", "data_dir:=", f"rtf:={args.rtf}", "seed:=1", "bag:=false",
             "save_data:=false", "button_timeout:=0", "output:=log"],
            env=env, stdout=launch_log, stderr=launch_log, stdin=subprocess.DEVNULL)
        os.environ.update(master.env())
        import rospy
        from geometry_msgs.msg import TwistStamped
        from magna_msgs.msg import NamedValue, SMStatus
        from magna_msgs.srv import GroundStationCommand
        from rosgraph_msgs.msg import Clock
        from std_srvs.srv import Trigger

        rospy.init_node("command_latency_bench", anonymous=True, disable_signals=True)
        watch, clock = VelocityWatch(args.threshold), ClockWatch()
        waiting = threading.Event()

        def on_status(msg):
            if WAIT_STATE in msg.active_states:
                waiting.set()

        rospy.Subscriber("/magna/sm/mission/status", SMStatus, on_status, queue_size=50)
        rospy.Subscriber("/uav_1/ual/velocity", TwistStamped, watch.on_velocity, queue_size=10, tcp_nodelay=True)
        rospy.Subscriber("/clock", Clock, clock.on_clock, queue_size=50, tcp_nodelay=True)
        deadline = time.monotonic() + args.start_timeout
        while not waiting.is_set():
            if launch.poll() is not None:
                raise RuntimeError(f"the launch ended (status {launch.returncode}) before the mission waited; "
                                   f"see {folder / 'launch.log'}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"the mission did not reach its wait within {args.start_timeout:g} s")
            time.sleep(0.05)
        result["ready_s"] = time.monotonic() - started
        rospy.wait_for_service("/magna/gs/command", timeout=30.0)
        command = rospy.ServiceProxy("/magna/gs/command", GroundStationCommand)
        rng = random.Random(n)
        trials_started = time.perf_counter()
        for k in range(args.warmup + args.trials):
            direction = "up" if k % 2 == 0 else "down"
            hover_deadline = time.monotonic() + 20.0
            while watch.hovering_for() < 0.5:
                if time.monotonic() > hover_deadline:
                    raise RuntimeError(f"UAV 1 did not settle (|v| {watch.last_speed:.3f} m/s) within 20 s")
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, 0.1))
            parameters = [NamedValue("direction", 0.0, direction, ""), NamedValue("distance", args.distance, "", "m")]
            watch.arm()
            sim0 = clock.now()
            t0 = time.perf_counter()
            answer = command(intent="basic_action", action="move", agent=args.agent, parameters=parameters)
            t1 = time.perf_counter()
            if not answer.accepted:
                result["refused"].append(answer.message)
                watch.wait_hit(0.0)
                continue
            hit = watch.wait_hit(args.trial_timeout)
            if k < args.warmup:
                continue
            if hit is None:
                result["timeouts"] += 1
                continue
            result["latency"].append(hit[0] - t0)
            result["rtt"].append(t1 - t0)
            result["sim_latency"].append(hit[1] - sim0)
        result["rtf"] = clock.factor(trials_started)
        result["trials_s"] = time.perf_counter() - trials_started
        result["load"] = os.getloadavg()[0]
        try:  # the button: the UAVs land and the mission ends
            rospy.ServiceProxy("/magna/gs/continue", Trigger)()
            launch.wait(timeout=60)
        except Exception:
            pass
        rospy.signal_shutdown("bench done")
    except Exception as error:  # report it; the clean-up below still runs
        result["error"] = f"{type(error).__name__}: {error}"
    finally:
        master.stop()
        leftovers = kill_tagged(token)
        if leftovers:
            result["leftovers"] = leftovers
        launch_log.close()
    result["total_s"] = time.monotonic() - started
    return result


# --- the table and the picture --------------------------------------------------------------------------------

def percentile(values, q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else math.nan


def draw(rows: list[dict], path: Path, agent: str, rtf: str = "1") -> None:
    """Box plot and CDF of the wall latency per fleet size, with the p50 target: the figure magna_viz's
    per-simulation reports also draw (magna_viz.plots.plot_latency_distribution)."""
    from magna_viz.plots import plot_latency_distribution

    samples = {f"{r['n']} UAV" + ("s" if r["n"] > 1 else ""): np.array(r["latency"]) * 1000 for r in rows
               if r["latency"]}
    plot_latency_distribution(
        samples, path,
        f"/magna/gs/command basic_action move 0.5 m (agent {agent}) -> /uav_1/ual/velocity, rtf {rtf}",
        "ms", value_label="command -> first motion of UAV 1 (ms, wall)", group_label="UAVs in the simulation",
        reference=(TARGET_P50_S * 1000, "target p50 50 ms"))


def run_worker(argv: list[str]) -> None:
    """Run one fleet's worker; on Ctrl-C pass it on and let the worker end what it started."""
    worker = subprocess.Popen(argv)
    try:
        code = worker.wait()
    except BaseException:
        worker.send_signal(signal.SIGINT)  # its clean-up stops the ROS master and every tagged process
        try:
            worker.wait(timeout=120)
        except subprocess.TimeoutExpired:
            worker.kill()
            worker.wait()
        raise
    if code != 0:
        raise subprocess.CalledProcessError(code, argv)


def build_parser() -> argparse.ArgumentParser:
    from magna_common.cli_vocabulary import add_deprecated_option, add_force, add_output, add_rtf

    parser = argparse.ArgumentParser(prog="python bench/command_latency.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--fleets", type=int, nargs="+", default=[1, 2, 3, 10], help="fleet sizes (max 10)")
    parser.add_argument("--trials", type=int, default=30, help="commands measured per fleet size (default 30)")
    parser.add_argument("--warmup", type=int, default=2, help="commands sent first and not counted (default 2)")
    parser.add_argument("--agent", default="1", help='the command\'s agent: "1" (default) or "all"')
    parser.add_argument("--distance", type=float, default=0.5, help="metres per move (default 0.5)")
    parser.add_argument("--threshold", type=float, default=0.05, help="|v| in m/s that counts as motion")
    add_rtf(parser, default="1.0", help="real-time factor of the simulator: the latency is a wall time, so 1.0")
    parser.add_argument("--trial-timeout", type=float, default=5.0, help="wall s to wait for motion")
    parser.add_argument("--start-timeout", type=float, default=180.0, help="wall s for the mission to wait")
    add_output(parser, default=PICTURE, metavar="PATH.png", old=("--picture",),
               help=f"where the plot goes (default {PICTURE.relative_to(ROOT)})")
    add_force(parser, help="replace the plot if it exists (checked before measuring)")
    parser.add_argument("--worker", type=int, help=argparse.SUPPRESS)  # one fleet size, in its own process
    parser.add_argument("--worker-output", type=Path, help=argparse.SUPPRESS)  # where that process writes its row
    add_deprecated_option(parser, "--out", "worker_output", "--worker-output", type=Path)
    return parser


def check_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Bad options end here, before anything starts (parser.error: status 2)."""
    from magna_common.cli_vocabulary import OutputExists, check_output, parse_rtf
    from magna_common.errors import UsageError

    try:
        args.rtf = parse_rtf(args.rtf)
    except UsageError as error:
        parser.error(str(error))
    if args.worker:
        return
    if any(not 1 <= n <= 10 for n in args.fleets):
        parser.error("fleet sizes go from 1 to 10 (the pads)")
    try:
        check_output(args.output, args.force, "the plot")
    except OutputExists as error:
        parser.error(str(error))


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    check_args(parser, args)
    if args.worker:
        with tempfile.TemporaryDirectory(prefix=f"command_latency_{args.worker}_") as folder:
            args.worker_output.write_text(json.dumps(measure_fleet(args.worker, args, Path(folder))))
        return 0
    rows = []
    passthrough = ["--trials", str(args.trials), "--warmup", str(args.warmup), "--agent", args.agent,
                   "--distance", str(args.distance), "--threshold", str(args.threshold), "--rtf", args.rtf,
                   "--trial-timeout", str(args.trial_timeout), "--start-timeout", str(args.start_timeout)]
    for n in args.fleets:
        print(f"{n} UAV(s): {args.warmup} + {args.trials} commands (load average {os.getloadavg()[0]:.1f}) ...",
              flush=True)
        with tempfile.NamedTemporaryFile(suffix=".json") as out:
            run_worker([sys.executable, __file__, "--worker", str(n), "--worker-output", out.name, *passthrough])
            row = json.loads(Path(out.name).read_text())
        if row["error"]:
            print(f"   failed: {row['error']}", flush=True)
        if row["refused"]:
            print(f"   refused {len(row['refused'])}: {row['refused'][0]}", flush=True)
        if row.get("leftovers"):
            print(f"   leftover processes killed: {len(row['leftovers'])}", flush=True)
        print(f"   ready after {row.get('ready_s', math.nan):.1f} s, {len(row['latency'])} measured, "
              f"{row['timeouts']} timeouts, {row['total_s']:.0f} s in all", flush=True)
        rows.append(row)

    print(f"\ncommand-to-motion latency: /magna/gs/command (basic_action move {args.distance:g} m up/down, agent "
          f"{args.agent}) -> first /uav_1/ual/velocity with |v| > {args.threshold:g} m/s; rtf {args.rtf}, "
          f"{os.cpu_count()} cores, ms of wall time")
    head = (f"{'UAVs':>4} {'n':>3} {'p50':>7} {'p90':>7} {'p99':>7} {'max':>7} {'mean':>7} {'svc p50':>8} "
            f"{'sim p50':>8} {'sim x':>6} {'miss':>4} {'load':>5}  {'p50 / 50 ms target':>19}")
    print(head)
    print("-" * len(head))
    for r in rows:
        lat = np.array(r["latency"]) * 1000
        p50 = percentile(lat, 50)
        verdict = f"{TARGET_P50_S * 1000 / p50:.2f} {'meets' if p50 <= TARGET_P50_S * 1000 else 'misses'}" \
            if lat.size else "-"
        print(f"{r['n']:>4} {lat.size:>3} {p50:>7.1f} {percentile(lat, 90):>7.1f} {percentile(lat, 99):>7.1f} "
              f"{(lat.max() if lat.size else math.nan):>7.1f} {(lat.mean() if lat.size else math.nan):>7.1f} "
              f"{percentile(np.array(r['rtt']) * 1000, 50):>8.1f} "
              f"{percentile(np.array(r['sim_latency']) * 1000, 50):>8.1f} {r.get('rtf', math.nan):>5.2f}x "
              f"{r['timeouts'] + len(r['refused']):>4} {r.get('load', math.nan):>5.1f}  {verdict:>19}")
    print("svc = the service call's round trip (the command returns once the goals are sent); sim = the same latency "
          "in simulated time (velocity stamp - /clock at the call); sim x = simulated / wall time during the trials;\n"
          "miss = no motion within --trial-timeout, or refused; load = 1-min load average after the trials "
          "(2 cores: above 2, something else competes)")
    by_n = {r["n"]: r for r in rows if r["latency"]}
    low, high = min(by_n, default=None), max(by_n, default=None)
    if low is not None and high is not None and high != low:
        a, b = percentile(by_n[low]["latency"], 50), percentile(by_n[high]["latency"], 50)
        growth = b / a - 1.0
        growth90 = percentile(by_n[high]["latency"], 90) / percentile(by_n[low]["latency"], 90) - 1.0
        print(f"growth of p50 from {low} to {high} UAVs: {100 * growth:+.0f}% (target <= {100 * TARGET_GROWTH:.0f}%: "
              f"{'meets' if growth <= TARGET_GROWTH else 'misses'}); of p90: {100 * growth90:+.0f}%")
    if by_n:
        draw(rows, args.output, args.agent, args.rtf)
        print(f"picture: {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
