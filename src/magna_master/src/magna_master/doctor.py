"""`magna doctor`: check that this machine can run MAGNA, and prove it on a live ROS graph.

Each check returns a `CheckResult`; the live check starts a private master on a
free port, serves the UAL take_off service and publishes UAL states against it,
and measures the round trips. Nothing outside this process and its master is
touched. `--mavlink URL` checks a MAVLink link instead (magna_mavlink.link_check):
heartbeat, autopilot, system id, flight mode, armed, position valid, home.
"""
from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from magna_common.errors import UsageError
from magna_common.workspace import Workspace

HELP = ("check the installation (packages, venv, build, message API) and run a live ROS round trip; "
        "or, with --mavlink URL, a MAVLink vehicle's link; or, with --cluster ADDRESS, a Dask cluster's workers")
MAVLINK_TIMEOUT = 5.0  # s for the heartbeat, then as long again for the position and the home
EXAMPLES = """\
examples:
  magna doctor --no-live
  magna doctor --mavlink udpin:0.0.0.0:14540        # [hardware] PX4 SITL instance 0, or a vehicle sending there
  magna doctor --mavlink udpout:127.0.0.1:14580 --timeout 10    # [hardware] a vehicle that waits to be spoken to
  magna doctor --mavlink /dev/ttyACM0,57600          # [hardware] an autopilot on USB or a telemetry radio
  magna doctor --cluster tcp://10.0.0.5:8786          # the workers of a Dask scheduler [synopsis]

With --mavlink only the link is checked: exit status 0 when every line is ok, 1 when one fails,
2 when the URL is not one (forms: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, DEVICE[,BAUD]).

With --cluster each worker of the scheduler is listed: its host, cores, threads (simulations at once), MAGNA
version and readiness (ROS on PATH, the workspace built, room in its temporary folder, the client's
version). Exit status 0 when every worker is ready, 1 when one is not, 2 when no scheduler answers.
"""

# The checksums of GRVC UAL v3: real UAL servers and clients accept only these.
GRVC_UAL_MD5 = {
    "msg/State": "533576484916e98b63315c3434a12ab9",
    "srv/TakeOff": "92f7691c5527d6fb3cc35d20a69e7778",
    "srv/Land": "c37d0c321494079f6ac6aae0680a10e1",
    "srv/GoToWaypoint": "1b4a030ed9ba0e5a2761567aa99a96b7",
    "srv/GoToWaypointGeo": "a636a108541a3b824065d8407258fbe8",
    "srv/SetHome": "27f767d7f04b6ba462fa116e03c0b202",
}


@dataclass
class CheckResult:
    name: str
    ok: bool
    detail: str
    fix: str = ""


def add_arguments(parser) -> None:
    import argparse

    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EXAMPLES
    parser.add_argument("--no-live", action="store_true",
                        help="skip the live ROS round trip (no master is started)")
    parser.add_argument("--round-trips", type=int, default=200, metavar="N",
                        help="service calls and messages in the live check (default: %(default)s)")
    parser.add_argument("--mavlink", metavar="URL",
                        help="check only this MAVLink link (pymavlink URL: udpin:0.0.0.0:14540, "
                             "udpout:127.0.0.1:14580, tcp:HOST:PORT, /dev/ttyACM0,57600): heartbeat, autopilot, "
                             "system id, flight mode, armed, position valid, home")
    parser.add_argument("--cluster", metavar="ADDRESS",
                        help="check only the workers of this Dask scheduler (e.g. tcp://10.0.0.5:8786): host, cores, "
                             "MAGNA version, readiness")
    parser.add_argument("--timeout", type=float, metavar="S",
                        help=f"with --mavlink: seconds to wait for the heartbeat, then again for the position and the "
                             f"home (default {MAVLINK_TIMEOUT:g}); with --cluster: for a first worker (default 10)")


def check_apt(workspace: Workspace) -> CheckResult:
    wanted = workspace.apt_packages()
    out = subprocess.run(["dpkg-query", "-W", "-f=${Package} ${db:Status-Abbrev}\n", *wanted],
                         capture_output=True, text=True)
    installed = {line.split()[0] for line in out.stdout.splitlines() if line.split()[1:2] == ["ii"]}
    missing = [name for name in wanted if name not in installed]
    if missing:
        return CheckResult("Debian packages", False, f"missing: {' '.join(missing)}", "make setup")
    return CheckResult("Debian packages", True, f"{len(wanted)} installed")


def _pinned_requirements(path: Path) -> dict[str, str]:
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            pins[name.strip()] = version.strip()
    return pins


def check_venv(workspace: Workspace) -> CheckResult:
    if Path(sys.prefix).resolve() != (workspace.root / ".venv").resolve():
        return CheckResult("Python venv", False, f"running {sys.executable}, not the workspace venv",
                           "use ./magna (or make setup)")
    wrong = []
    pins = _pinned_requirements(workspace.root / "requirements.txt")
    for name, version in pins.items():
        try:
            found = metadata.version(name)
        except metadata.PackageNotFoundError:
            wrong.append(f"{name} missing")
            continue
        if found.split("+", 1)[0] != version.split("+", 1)[0]:
            wrong.append(f"{name} {found} != {version}")
    if wrong:
        return CheckResult("Python venv", False, "; ".join(wrong), "make setup")
    return CheckResult("Python venv", True, f"{len(pins)} pinned packages, torch {metadata.version('torch')}")


def check_build(workspace: Workspace) -> CheckResult:
    if not workspace.devel_setup.exists():
        return CheckResult("catkin build", False, "devel/setup.bash is missing", "make setup")
    try:
        import magna_msgs.msg  # noqa: F401
        import magna_msgs.srv  # noqa: F401
        import uav_abstraction_layer.msg  # noqa: F401
    except ImportError as error:
        return CheckResult("catkin build", False, f"generated messages not importable ({error})",
                           "make setup, then run through ./magna")
    return CheckResult("catkin build", True, "messages of uav_abstraction_layer and magna_msgs import")


def check_ual_checksums() -> CheckResult:
    import importlib
    mismatched = []
    for kind_and_name, expected in GRVC_UAL_MD5.items():
        kind, name = kind_and_name.split("/")
        module = importlib.import_module(f"uav_abstraction_layer.{kind}")
        actual = getattr(module, name)._md5sum
        if actual != expected:
            mismatched.append(f"{name} {actual}")
    if mismatched:
        return CheckResult("UAL v3 checksums", False, "differ from GRVC's: " + ", ".join(mismatched),
                           "restore src/uav_abstraction_layer/{msg,srv} to the UAL v3 definitions")
    return CheckResult("UAL v3 checksums", True, f"{len(GRVC_UAL_MD5)} types match GRVC UAL v3")


def check_live_graph(round_trips: int) -> CheckResult:
    """A private master, a UAL take_off service and a UAL state topic, timed."""
    from magna_common.ros_master import RosMaster
    from magna_common.ros_names import ual

    with RosMaster() as master:
        os.environ.update(master.env())
        import rospy
        from uav_abstraction_layer.msg import State
        from uav_abstraction_layer.srv import TakeOff, TakeOffResponse

        rospy.init_node("magna_doctor", anonymous=True, disable_signals=True)
        try:
            heights = []

            def serve_take_off(req):
                heights.append(req.height)
                return TakeOffResponse()

            service = rospy.Service(ual(1, "take_off"), TakeOff, serve_take_off)
            received = []
            got_all = threading.Event()

            def on_state(msg):
                received.append((time.perf_counter(), msg.state))
                if len(received) >= round_trips:
                    got_all.set()

            subscriber = rospy.Subscriber(ual(1, "state"), State, on_state, queue_size=round_trips)
            publisher = rospy.Publisher(ual(1, "state"), State, queue_size=round_trips)
            rospy.wait_for_service(ual(1, "take_off"), timeout=10)
            take_off = rospy.ServiceProxy(ual(1, "take_off"), TakeOff, persistent=True)
            call_ms = []
            for i in range(round_trips):
                start = time.perf_counter()
                take_off(height=float(i), blocking=True)
                call_ms.append((time.perf_counter() - start) * 1e3)
            take_off.close()

            deadline = time.monotonic() + 10
            while publisher.get_num_connections() == 0 and time.monotonic() < deadline:
                time.sleep(0.01)
            sent = []
            for _ in range(round_trips):
                sent.append(time.perf_counter())
                publisher.publish(State(state=State.FLYING_AUTO))
                time.sleep(0.001)
            got_all.wait(timeout=10)
            service.shutdown()
            subscriber.unregister()
            publisher.unregister()
        finally:
            rospy.signal_shutdown("magna doctor done")

    if heights != [float(i) for i in range(round_trips)]:
        return CheckResult("live ROS graph", False, f"take_off served {len(heights)}/{round_trips} calls in order",
                           "see ~/.ros/log for the node's log")
    if len(received) < round_trips or any(state != State.FLYING_AUTO for _, state in received):
        return CheckResult("live ROS graph", False, f"state topic delivered {len(received)}/{round_trips}",
                           "see ~/.ros/log for the node's log")
    latencies = [(got - put) * 1e3 for (got, _), put in zip(received[:round_trips], sent, strict=True)]
    return CheckResult(
        "live ROS graph", True,
        f"master :{master.port}, take_off p50 {statistics.median(call_ms):.2f} ms, "
        f"state topic p50 {statistics.median(latencies):.2f} ms ({round_trips} each)")


def check_mavlink(url: str, timeout: float) -> list[CheckResult]:
    """The lines of magna_mavlink.link_check as doctor results; BadUrl for a URL that is not one."""
    from magna_mavlink.link_check import check_link

    return [CheckResult(c.name, c.ok, c.detail, c.fix) for c in check_link(url, timeout)]


def run_mavlink(args) -> int:
    from magna_mavlink.link_check import BadUrl, parse_url

    timeout = MAVLINK_TIMEOUT if args.timeout is None else args.timeout
    if not timeout > 0:
        raise UsageError(f"--timeout {timeout:g}: give a positive number of seconds")
    try:
        parse_url(args.mavlink)
    except BadUrl as error:
        raise UsageError(f"--mavlink {error}") from None
    print(f"MAVLink link {args.mavlink} (waiting up to {timeout:g} s for the heartbeat, then for the rest)",
          flush=True)
    results = check_mavlink(args.mavlink, timeout)
    for result in results:
        _print(result)
        if result.fix:
            print(f"       fix: {result.fix}", flush=True)
    return _summary(results, fixes_shown=True)


def check_cluster(address: str, wait: float = 10.0) -> list[CheckResult]:
    """One line per worker of the scheduler at `address` (waiting up to `wait` s for a first one to join); a
    ClusterError when no scheduler answers."""
    from magna_master.cluster import connect
    from magna_master.cluster_task import LOADED_VERSION, worker_report

    client = connect(address)
    try:
        try:
            client.wait_for_workers(1, timeout=wait)
        except TimeoutError:
            pass  # said below: no worker
        threads = client.nthreads()
        reports = client.run(worker_report, on_error="return") if threads else {}
    finally:
        client.close()
    mine = LOADED_VERSION
    results = []
    for worker, report in sorted(reports.items()):
        if isinstance(report, BaseException):  # e.g. no magna_master there
            results.append(CheckResult(worker, False, f"not ready: the check failed there ({type(report).__name__}: "
                                                      f"{report}); start it with scripts/with_env.sh dask worker ..."))
            continue
        problems = list(report["problems"])
        if report["version"] != mine:
            problems.append(f"MAGNA {report['version']} there, {mine} here: check out this commit on its host, "
                            "`make setup`, and restart the worker")
        detail = (f"host {report['host']}, cores {report['cores']}, threads {threads.get(worker, '?')}, "
                  f"MAGNA {report['version']}, " + ("ready" if not problems else "not ready: " + "; ".join(problems)))
        results.append(CheckResult(worker, not problems, detail))
    if not results:
        results.append(CheckResult("workers", False, f"none is connected to {address}",
                                   f"start one: scripts/with_env.sh dask worker {address} --nthreads 1"))
    return results


def run_cluster(args) -> int:
    wait = 10.0 if args.timeout is None else args.timeout
    print(f"Dask scheduler {args.cluster} (waiting up to {wait:g} s for a worker)", flush=True)
    results = check_cluster(args.cluster, wait)
    for result in results:
        mark = "ok  " if result.ok else "FAIL"
        print(f"[{mark}] {result.name}  {result.detail}", flush=True)
    print(f"\n{sum(r.ok for r in results)} of {len(results)} worker(s) ready"
          + ("" if results[0].fix == "" else f"; fix: {results[0].fix}"), flush=True)
    return 0 if all(r.ok for r in results) else 1


def run(args) -> int:
    if getattr(args, "cluster", None) is not None:
        return run_cluster(args)
    if getattr(args, "mavlink", None) is not None:
        return run_mavlink(args)
    if getattr(args, "timeout", None) is not None:

        raise UsageError("--timeout goes with --mavlink URL or --cluster ADDRESS (the wait for a vehicle or a worker)")
    workspace = Workspace.locate()
    checks = [lambda: check_apt(workspace), lambda: check_venv(workspace), lambda: check_build(workspace)]
    results: list[CheckResult] = []
    for check in checks:
        results.append(check())
        _print(results[-1])
    if results[-1].ok:
        results.append(check_ual_checksums())
        _print(results[-1])
        if not args.no_live:
            if shutil.which("rosmaster") is None:
                results.append(CheckResult("live ROS graph", False, "rosmaster is not on PATH", "make setup"))
            else:
                results.append(check_live_graph(args.round_trips))
            _print(results[-1])
    return _summary(results)


def _summary(results: list[CheckResult], fixes_shown: bool = False) -> int:
    """The last line; the fixes of the failures too, unless each line already showed its own."""
    failed = [r for r in results if not r.ok]
    print(f"\n{len(results) - len(failed)} of {len(results)} checks passed"
          + ("" if not failed or fixes_shown else "; fix: " + ", ".join(sorted({r.fix for r in failed if r.fix}))))
    return 1 if failed else 0


def _print(result: CheckResult) -> None:
    mark = "ok  " if result.ok else "FAIL"
    print(f"[{mark}] {result.name:<18} {result.detail}", flush=True)
