"""The per-simulation supervisor: the Master's ROS node for one simulation.

    python -m magna_master.supervisor --result FILE --log FILE [--data-dir DIR] [--time-limit S]
        [--stop-grace S] [--settle S] [--shutdown-timeout S] [--extra JSON] [--parent-pid PID] -- COMMAND...

rospy allows one node per process and every simulation has a master of its own, so
the batch loop starts one supervisor per simulation (against that simulation's
master). The supervisor

1. serves `/magna/master/simulation_termination` (magna_msgs/SimulationTermination);
2. starts COMMAND (by default `roslaunch magna_gs simulation.launch ...`) in its own
   process group, output to the --log file;
3. waits for the termination call, the command's exit (a crash: it ended without calling),
   roslaunch's word in the log that a required node died (a crash naming the node, e.g. the
   simulator: launch_watch), the wall-clock --time-limit (then calls `/magna/gs/stop`,
   std_srvs/Trigger, when it is served, and waits --stop-grace seconds more), or SIGINT/SIGTERM
   (interrupted);
4. ends the command's process group (SIGINT, SIGTERM, SIGKILL, --shutdown-timeout apart),
   then ends any process still carrying this simulation's token (MAGNA_SIM_TOKEN in its
   environment: nodes that roslaunch put in sessions of their own): SIGINT first, so that a
   bag left recording is closed and readable, SIGKILL LEFTOVER_GRACE seconds later;
5. writes result.json atomically (also right when the termination call arrives, before it
   is acknowledged).

`SupervisorCore` holds all of this except the ROS wiring, so tests drive it directly.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from magna_common.processes import (
    TOKEN_ENV,
    ancestors,
    end_process_group,
    kill_tagged,
    pid_alive,
    set_parent_death_signal,
    tagged_processes,
)
from magna_common.records import (
    CRASHED,
    GROUND_STATION,
    INTERRUPTED,
    START_FAILED,
    TIME_LIMIT,
    SimulationResult,
)
from magna_common.ros_names import GS_STOP, MASTER_TERMINATION
from magna_common.storage_tree import LOGS_DIR, RESULT_FILE
from magna_common.warm_start import cold_start
from magna_master.launch_watch import RequiredDeath, RequiredDeathWatch

STOP_RETRY = 0.2  # wall s between calls of the stop service while it is not served yet
LEFTOVER_GRACE = 2.0  # wall s between SIGINT and SIGKILL to the processes left after the launch
NODE_NAME = "magna_master_supervisor"


def log_tail(path: Path | None, lines: int = 6, limit: int = 600) -> str:
    """The last non-empty lines of a log, on one line, for a result message."""
    if path is None:
        return ""
    try:
        with open(path, "rb") as handle:
            handle.seek(0, os.SEEK_END)
            handle.seek(max(0, handle.tell() - 16384))
            text = handle.read().decode(errors="replace")
    except OSError:
        return ""
    kept = [line.strip() for line in text.splitlines() if line.strip()][-lines:]
    joined = " | ".join(kept)
    return joined[-limit:]


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="milliseconds")


def end_tagged(token: str, exclude: set[int], grace: float = LEFTOVER_GRACE) -> list[str]:
    """End every process still carrying the token: SIGINT (a bag closes, a node shuts down), SIGKILL after
    `grace` for what is left (a frozen process). Describes each one ended."""
    interrupted = tagged_processes(TOKEN_ENV, token, exclude)
    for pid, _ in interrupted:
        try:
            os.kill(pid, signal.SIGINT)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + grace
    while interrupted and time.monotonic() < deadline and tagged_processes(TOKEN_ENV, token, exclude):
        time.sleep(0.05)
    killed = kill_tagged(token, exclude=exclude)
    killed_pids = {description.split(" ", 1)[0] for description in killed}
    return [f"{pid} {command[:200]} (SIGINT)" for pid, command in interrupted if str(pid) not in killed_pids] + killed


# --- the supervisor without ROS ------------------------------------------------------------------------------

@dataclass
class Termination:
    """What the ground station reported (the SimulationTermination request)."""

    success: bool
    outcome: str
    message: str
    sim_duration: float
    collisions: int
    wall_duration: float = 0.0  # wall s of the mission, start to end (0: not reported)
    setup_wall_duration: float = 0.0  # of those, wall s with the simulator paused for setup
    critical_events: tuple[dict, ...] = ()  # result.json's records of the ground station's critical events


class SupervisorCore:
    """Run one launch command until it reports, crashes, runs out of time or is interrupted.

    `stop_ground_station()` (injected) asks the ground station to stop and returns True when
    it was asked. `on_termination` is called by the service handler; `request_stop` by signals.
    """

    def __init__(self, command: Sequence[str], result_path: Path, log_path: Path, data_dir: Path | None = None,
                 time_limit: float | None = None, stop_grace: float = 15.0, settle: float = 5.0,
                 shutdown_timeout: float = 10.0, known: SimulationResult | None = None, token: str | None = None,
                 stop_ground_station: Callable[[], bool] | None = None, poll: float = 0.05,
                 env: dict | None = None, deaths: RequiredDeathWatch | None = None, node: str = "",
                 start: Callable[[list[str], Path, dict | None], subprocess.Popen] = cold_start):
        self.command = list(command)
        self.result_path = Path(result_path)
        self.log_path = Path(log_path)
        self.data_dir = Path(data_dir) if data_dir else None
        self.time_limit = time_limit if time_limit and time_limit > 0 else None
        self.stop_grace = stop_grace
        self.settle = settle
        self.shutdown_timeout = shutdown_timeout
        self.known = known or SimulationResult()  # what the batch knows before the run: id, seed, files...
        self.token = token
        self.stop_ground_station = stop_ground_station or (lambda: False)
        self.poll = poll
        self._lock = threading.Lock()
        self._termination: Termination | None = None
        self._termination_wall = 0.0  # wall seconds from the start to the report, once there is one
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._started: float | None = None
        self._started_at = _now()
        self.launch: subprocess.Popen | None = None
        self.env = env  # the command's environment (None: ours)
        self.start = start  # starts the command: output appended to the log, stdin empty, in its own session
        # the node the command is, when it is one node and not a launch (a persistent stack's ground station):
        # its exit before reporting is that node's death, said as roslaunch says a required node's
        self.node = node
        # where a required node's death is said: the launch's own log, or a persistent stack's
        self._deaths = deaths if deaths is not None else RequiredDeathWatch(self.log_path)
        self._death: RequiredDeath | None = None  # a required node's death, noticed before any report
        self._death_noticed: dict = {}  # when: "noticed_at" (UTC) and "noticed_after" (wall s from the start)

    # called from other threads ---------------------------------------------------------------------------------

    def on_termination(self, termination: Termination) -> bool:
        """Record the ground station's report (the first one counts); write it down, then acknowledge."""
        with self._lock:
            if self._termination is not None:
                return True
            self._termination = termination
            start = self._started if self._started is not None else time.monotonic()
            self._termination_wall = time.monotonic() - start
            result = self._result(GROUND_STATION, launch_exit_code=None, leftovers=[], gs_stop_called=False,
                                  timed_out=False)
            try:
                self._write(dataclasses.replace(result, final=False))  # rewritten once the launch is down
            except OSError as err:  # a full disk: acknowledge all the same; the final write (or the batch) says it
                print(f"supervisor: cannot write {self.result_path}: {err}", file=sys.stderr, flush=True)
        self._wake.set()
        return True

    def request_stop(self) -> None:
        self._stop.set()
        self._wake.set()

    # the main loop ------------------------------------------------------------------------------------------------

    @property
    def termination(self) -> Termination | None:
        with self._lock:
            return self._termination

    def run(self) -> SimulationResult:
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._started = time.monotonic()
        try:
            launch = self.launch = self.start(self.command, self.log_path, self.env)
        except OSError as err:
            message = f"cannot start {self.command[0]!r}: {err.strerror or err}; check the launch command"
            result = self._result(START_FAILED, None, [], False, False, message=message)
            self._write(result)
            return result

        timed_out = gs_stop_called = False
        while True:
            if self._noticed_a_death():
                break
            if self.termination is not None or self._stop.is_set():
                break
            if launch.poll() is not None:
                break
            if self.time_limit is not None and time.monotonic() - self._started >= self.time_limit:
                timed_out = True
                grace_ends = time.monotonic() + self.stop_grace

                def ended():
                    return self.termination is not None or launch.poll() is not None or self._stop.is_set()

                # a ground station still starting serves its stop service a moment later: ask again until it
                # does (within the grace), so that it still saves what it has instead of being killed
                while not gs_stop_called and not ended() and time.monotonic() < grace_ends:
                    try:
                        gs_stop_called = bool(self.stop_ground_station())
                    except Exception:  # a broken ground station must not keep the batch waiting
                        gs_stop_called = False
                    if not gs_stop_called:
                        self._wait(min(STOP_RETRY, max(0.0, grace_ends - time.monotonic())), ended)
                self._wait(max(0.0, grace_ends - time.monotonic()), ended)
                break
            self._wake.wait(self.poll)
            self._wake.clear()

        end_wall = time.monotonic() - self._started
        if not timed_out and not self._stop.is_set():
            self._noticed_a_death()  # the launch may have exited before its last words were read
        if self._death is not None and not self._stop.is_set():
            # roslaunch shuts the launch down by itself after a required node's death: give it the chance
            self._wait(self.settle, lambda: launch.poll() is not None or self._stop.is_set())
        elif self.termination is not None and not self._stop.is_set():
            # The ground station is required in simulation.launch: once it has reported and exited,
            # roslaunch ends the rest by itself. Give it that chance before forcing it.
            self._wait(self.settle, lambda: launch.poll() is not None or self._stop.is_set())
        end_process_group(launch, grace=self.shutdown_timeout)
        leftovers = end_tagged(self.token, exclude=ancestors()) if self.token else []

        if self._death is not None:
            kind = CRASHED
        elif self.termination is not None:
            kind = TIME_LIMIT if timed_out else GROUND_STATION
        elif self._stop.is_set():
            kind = INTERRUPTED
        elif timed_out:
            kind = TIME_LIMIT
        else:
            kind = CRASHED
        result = self._result(kind, launch.returncode, leftovers, gs_stop_called, timed_out, end_wall=end_wall)
        self._write(result)
        return result

    def _noticed_a_death(self) -> bool:
        """True once the launch log says a required node died before the ground station reported."""
        if self._death is None and self.termination is None:
            death = self._deaths.poll()
            launch = self.launch
            if death is None and self.node and launch is not None and launch.poll() is not None:
                death = RequiredDeath(self.node, f"process has died [pid {launch.pid}, exit code {launch.returncode}]",
                                      launch.returncode)
            if death is not None:
                start = self._started if self._started is not None else time.monotonic()
                self._death_noticed = {"noticed_at": _now(), "noticed_after": round(time.monotonic() - start, 3)}
                self._death = death
        return self._death is not None

    def _wait(self, seconds: float, done: Callable[[], bool]) -> None:
        deadline = time.monotonic() + seconds
        while not done() and time.monotonic() < deadline:
            self._wake.wait(self.poll)
            self._wake.clear()

    # the result --------------------------------------------------------------------------------------------------

    def _result(self, kind: str, launch_exit_code: int | None, leftovers: list[str], gs_stop_called: bool,
                timed_out: bool, message: str = "", end_wall: float | None = None) -> SimulationResult:
        reported = self._termination
        if reported is not None:
            wall = self._termination_wall
        elif end_wall is not None:
            wall = end_wall
        else:
            wall = time.monotonic() - self._started if self._started is not None else 0.0
        if kind == GROUND_STATION:
            assert reported is not None  # the kind of a result after the ground station's report
            success, outcome, message = reported.success, reported.outcome, reported.message
        elif kind == TIME_LIMIT:
            success = False
            outcome = reported.outcome if reported is not None else TIME_LIMIT
            note = (f"time limit of {self.time_limit:g} s (wall clock) reached; "
                    + (f"{GS_STOP} was called" if gs_stop_called else f"{GS_STOP} is not served"))
            message = note + (f"; the ground station said: {reported.message}" if reported is not None
                              else f"; it did not call {MASTER_TERMINATION}")
        elif kind == INTERRUPTED:
            success, outcome = False, INTERRUPTED
            message = "interrupted (Ctrl-C or SIGTERM) before the ground station reported"
        elif kind == CRASHED and self._death is not None:
            success, outcome = False, CRASHED
            message = (f"{self._death.describe()}; noticed {self._death_noticed['noticed_after']:.2f} s after the "
                       f"start, the simulation ended")
            if reported is not None:
                message += f"; the ground station then said: {reported.message}"
        elif kind == CRASHED:
            success, outcome = False, CRASHED
            tail = log_tail(self.log_path)
            message = (f"the launch exited with status {launch_exit_code} without calling {MASTER_TERMINATION}"
                       + (f"; last lines of {self.log_path.name}: {tail}" if tail else ""))
        else:
            success, outcome = False, kind
        return dataclasses.replace(
            self.known,
            success=bool(success),
            outcome=outcome,
            message=message,
            sim_duration=float(reported.sim_duration) if reported is not None else 0.0,
            collisions=int(reported.collisions) if reported is not None else 0,
            wall_time=round(float(wall), 3),
            mission_wall_time=round(reported.wall_duration, 3) if reported is not None else 0.0,
            setup_wall_time=round(reported.setup_wall_duration, 3) if reported is not None else 0.0,
            termination=kind,
            reported=reported is not None,
            time_limit=self.time_limit,
            timed_out=timed_out,
            gs_stop_called=gs_stop_called,
            launch_command=tuple(self.command),
            launch_pid=self.launch.pid if self.launch is not None else None,
            launch_exit_code=launch_exit_code,
            supervisor_pid=os.getpid(),
            leftover_processes_killed=tuple(leftovers),
            started_at=self._started_at,
            ended_at=_now(),
            files=self._files(),
            final=True,
            extra={**self.known.extra, **self._extra(reported)},
        )

    def _extra(self, reported: Termination | None) -> dict:
        """result.json's keys beyond SimulationResult's fields: the critical events, a required node's death."""
        extra: dict = {}
        if reported is not None:
            extra["critical_events"] = [dict(event) for event in reported.critical_events]
        if self._death is not None:
            extra["died"] = {"node": self._death.node, "component": self._death.component,
                             "detail": self._death.detail, "exit_code": self._death.exit_code, **self._death_noticed}
        return extra

    def _files(self) -> tuple[str, ...]:
        if self.data_dir is None or not self.data_dir.is_dir():
            return ()
        skip = {RESULT_FILE}
        files = []
        for path in sorted(self.data_dir.rglob("*")):
            relative = path.relative_to(self.data_dir)
            if path.is_file() and relative.parts[0] != LOGS_DIR and relative.name not in skip \
                    and not relative.name.startswith("."):
                files.append(str(relative))
        return tuple(files)

    def _write(self, result: SimulationResult) -> None:
        result.write(self.result_path)


# --- the ROS node ------------------------------------------------------------------------------------------------

def termination_of(request) -> Termination:
    """The ground station's report, from a magna_msgs/SimulationTermination request."""
    events = tuple({"uav": int(e.uav_id), "event": e.event, "sim_time": round(float(e.sim_time), 3),
                    "detail": e.detail} for e in request.critical_events)
    return Termination(
        success=bool(request.success), outcome=request.outcome, message=request.message,
        sim_duration=float(request.sim_duration), collisions=int(request.collisions),
        wall_duration=float(request.wall_duration), setup_wall_duration=float(request.setup_wall_duration),
        critical_events=events)


def ros_stop_ground_station(timeout: float = 5.0) -> Callable[[], bool]:
    def stop() -> bool:
        import rosgraph
        import rospy
        from std_srvs.srv import Trigger

        try:
            rosgraph.Master(rospy.get_name()).lookupService(GS_STOP)
        except Exception:  # not served (rosgraph.MasterError) or the master is gone
            return False
        outcome = {}

        def call():
            try:
                outcome["response"] = rospy.ServiceProxy(GS_STOP, Trigger)()
            except Exception as err:  # the ground station died meanwhile
                outcome["error"] = err

        caller = threading.Thread(target=call, daemon=True)
        caller.start()
        caller.join(timeout)
        return "response" in outcome
    return stop


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m magna_master.supervisor", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--result", required=True, type=Path, help="result.json to write")
    parser.add_argument("--log", required=True, type=Path, help="file taking the launch command's output")
    parser.add_argument("--data-dir", default="", help="the ground station's folder (its files are listed)")
    parser.add_argument("--time-limit", type=float, default=0.0, help="wall-clock seconds; 0: none")
    parser.add_argument("--stop-grace", type=float, default=15.0,
                        help=f"seconds to wait after {GS_STOP} before ending the launch")
    parser.add_argument("--settle", type=float, default=5.0,
                        help="seconds the launch gets to exit by itself after the termination call")
    parser.add_argument("--shutdown-timeout", type=float, default=10.0,
                        help="seconds between SIGINT, SIGTERM and SIGKILL when ending the launch")
    parser.add_argument("--extra", default="{}",
                        help="result.json's fields the batch knows (JSON: id, seed, hyperparameters, files)")
    parser.add_argument("--parent-pid", type=int, default=0, help="stop when this process (the batch) dies")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND ARGS...")
    args = parser.parse_args(argv)
    if args.command[:1] == ["--"]:
        args.command = args.command[1:]
    if not args.command:
        parser.error("give the launch command after --")
    try:
        args.extra = json.loads(args.extra)
    except ValueError as err:
        parser.error(f"--extra is not JSON: {err}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    core = SupervisorCore(args.command, args.result, args.log, data_dir=args.data_dir or None,
                          time_limit=args.time_limit, stop_grace=args.stop_grace, settle=args.settle,
                          shutdown_timeout=args.shutdown_timeout,
                          known=SimulationResult.from_dict(args.extra, "--extra"),
                          token=os.environ.get(TOKEN_ENV), stop_ground_station=ros_stop_ground_station())
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda *_: core.request_stop())
    if args.parent_pid:
        set_parent_death_signal(signal.SIGTERM)
        if os.getppid() != args.parent_pid:  # the batch died before prctl took effect
            core.request_stop()

    import rospy
    from magna_msgs.srv import SimulationTermination, SimulationTerminationResponse

    rospy.init_node(NODE_NAME, disable_signals=True)

    def handle(request):
        return SimulationTerminationResponse(acknowledged=core.on_termination(termination_of(request)))

    service = rospy.Service(MASTER_TERMINATION, SimulationTermination, handle)
    try:
        result = core.run()
    finally:
        service.shutdown()
    print(f"supervisor: {result.termination}: {result.outcome} ({result.message})", flush=True)
    if args.parent_pid and os.getppid() != args.parent_pid:
        # The batch died (SIGKILL, a crash) and cannot stop this simulation's master any more: do it for it.
        end_orphaned_master()
    return 0


def end_orphaned_master(timeout: float = 5.0) -> int | None:
    """Stop the master of ROS_MASTER_URI (asked for its pid); for a batch that died. Returns the pid ended."""
    import rosgraph

    try:
        pid = int(rosgraph.Master(f"/{NODE_NAME}").getPid())
    except Exception:  # already gone
        return None
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            return pid
        deadline = time.monotonic() + timeout
        while pid_alive(pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        if not pid_alive(pid):
            break
    print(f"supervisor: the batch is gone; ended its master (pid {pid})", flush=True)
    return pid


if __name__ == "__main__":
    status = main()
    # rospy.signal_shutdown() spends ~0.6 s unregistering from a master that is stopped right after us;
    # the result is on disk (atomically) and the launch is down, so leave at once.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
