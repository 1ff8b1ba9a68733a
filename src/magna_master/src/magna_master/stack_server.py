"""The stack server: the Master's ROS node for a batch's persistent stack (see magna_master.stack).

    python -m magna_master.stack_server [--rtf max] [--worlds-path DIR] [--output log] [--battery-floor 0]
        [--parent-pid PID]

It starts `roslaunch magna_gs stack.launch` (magna_sim, magna_world, orca3d_server) in its own process
group, waits until the stack serves what a simulation needs, and prints {"ready": true} (or false and
why) on stdout. Then it reads one SimulationRequest per stdin line, and for each:

1. resets the simulator (/magna/sim/reset) and the world node (/magna/world/reset) for the seed, and
   sets /magna/hyperparameters and the ground station's private parameters afresh;
2. starts the ground station alone (on a warm process that imported its modules during the previous
   simulation, magna_common.warm_start) and supervises it as the cold supervisor supervises a launch
   (SupervisorCore: the termination service, the time limit, /magna/gs/stop, interruption; a death of
   a stack node, read from the stack's roslaunch log, ends it as a crash), and writes result.json;
3. ends what is left with the simulation's token, and prints a SimulationReply saying whether the
   stack is still sound.

SIGINT or SIGTERM interrupt the running simulation. At the end of stdin (or when the batch dies) it
ends the stack's launch and exits.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from magna_common.processes import TOKEN_ENV, end_process_group, set_parent_death_signal
from magna_common.records import SimulationResult
from magna_common.ros_names import (
    HYPERPARAMETERS,
    MASTER_TERMINATION,
    ORCA_COMPUTE_VELOCITY,
    SIM_RESET,
    UAL_IDS,
    WORLD_RESET,
)
from magna_common.warm_start import WarmStarter, cold_start
from magna_common.workspace import node_script
from magna_master.launch_watch import RequiredDeathWatch
from magna_master.stack import READY_TIMEOUT, SimulationReply, SimulationRequest
from magna_master.supervisor import SupervisorCore, ros_stop_ground_station, termination_of

NODE_NAME = "magna_master_stack"
GROUND_STATION_NODE = "/ground_station"
RESET_TIMEOUT = 20.0  # wall s for one reset call
GROUND_STATION_MODULES = ("magna_gs.ros_node",)  # what a warm ground station has imported before it is wanted
FIRST_FLIGHT_AFTER = 2.0  # wall s from a ground station's start to its flight, until a simulation has said


def parse_args(argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m magna_master.stack_server",
                                     description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rtf", default="max", help="the simulator's real-time factor (1.0, any factor, or max)")
    parser.add_argument("--worlds-path", default="", help="an extra folder to look for worlds in")
    parser.add_argument("--output", default="log", choices=("log", "screen"), help="where the nodes' output goes")
    parser.add_argument("--battery-floor", default="0", help="%% of charge the simulated batteries keep")
    parser.add_argument("--log", type=Path, default=None,
                        help="file taking the stack launch's output (default: stack_launch.log beside ROS_LOG_DIR)")
    parser.add_argument("--parent-pid", type=int, default=0, help="stop when this process (the batch) dies")
    return parser.parse_args(argv)


def _say(line: str) -> None:
    sys.stdout.write(line)
    sys.stdout.flush()


class StackServer:
    """The stack's launch and the simulations run on it; ROS calls are made from here only."""

    def __init__(self, args: argparse.Namespace):
        self.args = args
        log_dir = Path(os.environ.get("ROS_LOG_DIR", ".")).parent
        self.log_path = args.log or log_dir / "stack_launch.log"
        self.launch: subprocess.Popen | None = None
        self.deaths = RequiredDeathWatch(self.log_path)
        self.core: SupervisorCore | None = None
        self.stopping = threading.Event()
        self.ground_stations: WarmStarter | None = None  # made once the stack is up
        self.flight_after = FIRST_FLIGHT_AFTER  # the latest simulation's wall s from its start to its flight

    # the stack ---------------------------------------------------------------------------------------------------
    def start(self) -> str:
        """Start the stack's launch; empty when it serves what a simulation needs, else why not."""
        import rospy

        argv = ["roslaunch", "--sigint-timeout=5", "--sigterm-timeout=2", "magna_gs", "stack.launch",
                f"rtf:={self.args.rtf}", f"worlds_path:={self.args.worlds_path}", f"output:={self.args.output}",
                f"battery_floor:={self.args.battery_floor}"]
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log_path, "ab") as log:
            self.launch = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                           start_new_session=True)
        deadline = time.monotonic() + READY_TIMEOUT
        for service in (SIM_RESET, WORLD_RESET, ORCA_COMPUTE_VELOCITY):
            while True:
                problem = self.health()
                if problem:
                    return problem
                if self.stopping.is_set():
                    return "interrupted"
                try:
                    rospy.wait_for_service(service, timeout=0.5)
                    break
                except rospy.ROSException:
                    if time.monotonic() > deadline:
                        return f"{service} was not served within {READY_TIMEOUT:g} s"
        self.ground_stations = WarmStarter(node_script("magna_gs", "ground_station"), GROUND_STATION_MODULES)
        self.ground_stations.prepare()
        return ""

    def health(self) -> str:
        """Empty while the stack's launch runs and no required node of it died; else what went wrong."""
        death = self.deaths.poll()
        if death is not None:
            return f"{death.describe()} (stack)"
        if self.launch is None or self.launch.poll() is not None:
            return f"the stack's launch exited with status {self.launch.returncode if self.launch else None}"
        return ""

    def stop(self) -> None:
        if self.ground_stations is not None:
            self.ground_stations.close()
        if self.launch is not None:
            end_process_group(self.launch, grace=5.0)

    # one simulation ---------------------------------------------------------------------------------------------
    def simulate(self, request: SimulationRequest) -> SimulationReply:
        import rospy
        from magna_msgs.srv import ResetSimulation, ResetWorld

        started = time.monotonic()
        timeline: dict = {}
        problem = self.health()
        if problem:
            return SimulationReply(ran=False, healthy=False, reason=problem)
        try:
            rospy.wait_for_service(SIM_RESET, timeout=RESET_TIMEOUT)
            answer = rospy.ServiceProxy(SIM_RESET, ResetSimulation)(seed=request.seed)
            if not answer.success:
                raise RuntimeError(f"{SIM_RESET}: {answer.message}")
            rospy.wait_for_service(WORLD_RESET, timeout=RESET_TIMEOUT)
            answer = rospy.ServiceProxy(WORLD_RESET, ResetWorld)(seed=request.seed, record=request.world_record)
            if not answer.success:
                raise RuntimeError(f"{WORLD_RESET}: {answer.message}")
            for name in (HYPERPARAMETERS, GROUND_STATION_NODE, UAL_IDS):
                if rospy.has_param(name):
                    rospy.delete_param(name)
            rospy.set_param(HYPERPARAMETERS, request.hyperparameters)
            for key, value in request.ground_station.items():
                rospy.set_param(f"{GROUND_STATION_NODE}/{key}", value)
        except (rospy.ROSException, rospy.ServiceException, RuntimeError) as err:
            return SimulationReply(ran=False, healthy=False, reason=f"the reset failed: {err}")
        reset_s = time.monotonic() - started
        timeline["reset"] = round(reset_s, 3)

        env = dict(os.environ)
        env[TOKEN_ENV] = request.token
        env["ROS_LOG_DIR"] = request.ros_log_dir
        script = self.ground_stations.script if self.ground_stations else node_script("magna_gs", "ground_station")
        command = [sys.executable, script, f"__name:={GROUND_STATION_NODE[1:]}"]
        core = self.core = SupervisorCore(
            command, Path(request.result), Path(request.log),
            data_dir=Path(request.data_dir) if request.data_dir else None,
            time_limit=request.time_limit, stop_grace=request.stop_grace, settle=request.settle,
            shutdown_timeout=request.shutdown_timeout,
            known=SimulationResult.from_dict(request.known, "the stack request"), token=request.token,
            stop_ground_station=ros_stop_ground_station(), env=env, deaths=self.deaths,
            node=GROUND_STATION_NODE[1:], start=self.ground_stations.start if self.ground_stations else cold_start)
        if self.stopping.is_set():
            core.request_stop()
        if self.ground_stations is not None:
            # The next ground station imports while this one flies: in its set-up every core is busy.
            self.ground_stations.prepare_in(self.flight_after)
        result = core.run()
        self.core = None
        if result.mission_wall_time > 0:
            self.flight_after = result.wall_time - result.mission_wall_time + result.setup_wall_time
        if self.ground_stations is not None:
            self.ground_stations.prepare_in(0.0)  # now, if the flight was too short for it
        timeline["ended"] = round(time.monotonic() - started, 3)
        problem = self.health()
        return SimulationReply(ran=True, healthy=not problem, reason=problem, reset_s=reset_s, timeline=timeline)

    def interrupt(self) -> None:
        self.stopping.set()
        core = self.core
        if core is not None:
            core.request_stop()


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    server = StackServer(args)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda *_: server.interrupt())
    if args.parent_pid:
        set_parent_death_signal(signal.SIGTERM)
        if os.getppid() != args.parent_pid:
            server.interrupt()

    import rospy
    from magna_msgs.srv import SimulationTermination, SimulationTerminationResponse

    rospy.init_node(NODE_NAME, disable_signals=True)

    def handle(request):
        core = server.core
        if core is None:  # a ground station of no simulation of ours
            return SimulationTerminationResponse(acknowledged=False)
        return SimulationTerminationResponse(acknowledged=core.on_termination(termination_of(request)))

    service = rospy.Service(MASTER_TERMINATION, SimulationTermination, handle)
    try:
        problem = server.start()
        _say(json.dumps({"ready": not problem, "reason": problem}) + "\n")
        if problem:
            return 1
        for line in sys.stdin:
            if server.stopping.is_set() and server.core is None and not line.strip():
                break
            if not line.strip():
                continue
            reply = server.simulate(SimulationRequest.from_line(line))
            _say(reply.to_line())
            if server.stopping.is_set():
                break
    finally:
        service.shutdown()
        server.stop()
        if args.parent_pid and os.getppid() != args.parent_pid:
            from magna_master.supervisor import end_orphaned_master

            end_orphaned_master()
    return 0


if __name__ == "__main__":
    status = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)  # as the cold supervisor: skip rospy's unregistering from a master about to stop
