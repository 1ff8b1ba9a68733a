"""A persistent stack for a batch: one ROS master, simulator, world node and ORCA-3D for many simulations.

A cold simulation starts everything (a master, then `roslaunch magna_gs simulation.launch`) and ends it
all. Most of that is the same every time, so a batch keeps a *stack* up between its simulations:

- `Stack.start()` starts a master and the stack server (`python -m magna_master.stack_server`), which
  runs `roslaunch magna_gs stack.launch` (magna_sim, magna_world, orca3d_server) once;
- `Stack.simulate(request)` has the server reset the simulator and the world to a cold start's state
  for the simulation's seed (/magna/sim/reset, /magna/world/reset), start only the ground station, and
  supervise it as the cold supervisor does (the same SupervisorCore, the same result.json);
- `Stack.stop()` ends the server, the stack and the master.

`StackPolicy` decides when a batch may keep its stack and when the next simulation must start cold:
after anything but a clean report (a crash, the time limit, an interruption, leftovers killed), or when
the stack's health is in doubt. The server and this module speak JSON lines over the server's stdin and
stdout (`SimulationRequest`, `SimulationReply`).
"""
from __future__ import annotations

import dataclasses
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.processes import TOKEN_ENV, end_process_group, kill_tagged
from magna_common.records import GROUND_STATION, SimulationResult
from magna_common.ros_master import RosMaster, RosMasterError

READY_TIMEOUT = 60.0  # wall s for the stack's nodes to serve what a simulation needs, on a loaded machine
STOP_TIMEOUT = 20.0  # wall s for the server to end the stack when asked


def cold_reasons(config) -> list[str]:
    """Why a batch with this BatchConfig cannot keep a stack (empty: it can)."""
    reasons = []
    if config.cold_start:
        reasons.append("--cold-start")
    if not config.uses_default_launch():
        reasons.append("--launch-command")
    if config.rviz:
        reasons.append("--rviz")  # rviz holds sim-time timers that a reset's clock jump would kill
    if config.fleet:
        reasons.append("--fleet")  # real autopilots' bridges are started per mission by the launch
    return reasons


@dataclass
class StackPolicy:
    """Whether the stack stays up after a simulation, and why not."""

    reset_limit: float = 10.0  # wall s a reset may take before the stack counts as unwell

    def why_restart(self, result: SimulationResult, reply: SimulationReply) -> str:
        """Empty when the next simulation may reuse the stack; else why it starts cold."""
        if not reply.healthy:
            return reply.reason or "the stack is not healthy"
        if result.termination != GROUND_STATION:
            return f"the simulation ended {result.termination}"
        if result.leftover_processes_killed:
            return "processes were left over and killed"
        if reply.reset_s > self.reset_limit:
            return f"the reset took {reply.reset_s:.1f} s"
        return ""


@dataclass
class SimulationRequest:
    """One simulation for the stack server: what the cold supervisor gets on its command line, plus the
    reset and the ground station's parameters."""

    result: str
    log: str
    data_dir: str
    ros_log_dir: str
    seed: int
    world_record: str  # world.json of the simulation; "" for none
    hyperparameters: dict
    ground_station: dict  # the ground station's private parameters
    known: dict  # result.json's fields the batch knows now
    token: str  # carried by the ground station and its managers; what is left with it is ended
    time_limit: float = 0.0
    stop_grace: float = 15.0
    settle: float = 5.0
    shutdown_timeout: float = 10.0

    def to_line(self) -> str:
        return json.dumps(dataclasses.asdict(self)) + "\n"

    @classmethod
    def from_line(cls, line: str) -> SimulationRequest:
        return cls(**json.loads(line))


@dataclass
class SimulationReply:
    """What the server says after a simulation: whether it ran, and whether the stack is still sound."""

    ran: bool  # false: the reset failed, nothing started; the batch runs the simulation cold instead
    healthy: bool
    reason: str = ""  # why it did not run, or why the stack is unwell
    reset_s: float = 0.0  # wall s of the reset
    timeline: dict = field(default_factory=dict)  # wall s from the request to each step

    def to_line(self) -> str:
        return json.dumps(dataclasses.asdict(self)) + "\n"

    @classmethod
    def from_line(cls, line: str) -> SimulationReply:
        return cls(**json.loads(line))


class StackError(RuntimeError):
    """The stack could not be started; the batch goes on cold."""


class Stack:
    """The batch's side of a persistent stack: its master and its server process."""

    def __init__(self, server_argv: list[str], logs: Path, token: str):
        self.server_argv = server_argv
        self.logs = Path(logs)
        self.token = token  # carried by the server and the stack's nodes
        self.master: RosMaster | None = None
        self.server: subprocess.Popen | None = None
        self.simulations = 0  # run on this stack so far
        self._lines: queue.Queue[str | None] = queue.Queue()

    @property
    def master_uri(self) -> str:
        if self.master is None:
            raise StackError("the stack is not started")
        return self.master.uri

    def start(self) -> Stack:
        self.logs.mkdir(parents=True, exist_ok=True)
        self.master = RosMaster(log_dir=self.logs / "ros")
        try:
            self.master.start()
        except (RosMasterError, OSError) as err:
            raise StackError(f"cannot start a ROS master: {err}") from None
        env = dict(os.environ)
        env[TOKEN_ENV] = self.token
        package_parent = str(Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH", "")) if p)
        with open(self.logs / "stack_server.log", "ab") as log:
            self.server = self.master.spawn(self.server_argv, env=env, stdin=subprocess.PIPE,
                                            stdout=subprocess.PIPE, stderr=log, text=True, bufsize=1)
        threading.Thread(target=self._read, args=(self.server.stdout,), daemon=True).start()
        line = self._next_line(READY_TIMEOUT + 10.0, lambda: False)
        ready = json.loads(line) if line else {"ready": False, "reason": "the stack server exited"}
        if not ready.get("ready"):
            self.stop()
            raise StackError(f"the stack did not start: {ready.get('reason', 'no answer')}; "
                             f"see {self.logs / 'stack_server.log'}")
        return self

    def _read(self, stream) -> None:
        for line in stream:
            self._lines.put(line)
        self._lines.put(None)  # the server's stdout closed: it exited

    def _next_line(self, timeout: float, give_up: Callable[[], bool]) -> str | None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not give_up():
            try:
                return self._lines.get(timeout=0.05)
            except queue.Empty:
                continue
        return None

    def simulate(self, request: SimulationRequest, budget: float, interrupt: Callable[[], bool]) -> SimulationReply:
        """Run one simulation on the stack. `interrupt()` is polled: once it says True the server gets a
        SIGINT (the simulation ends interrupted) and a shorter budget. A server silent past the budget is
        taken as hung: the reply says unhealthy and the batch stops the stack."""
        assert self.server is not None and self.server.stdin is not None
        self.simulations += 1
        try:
            self.server.stdin.write(request.to_line())
            self.server.stdin.flush()
        except OSError as err:
            return SimulationReply(ran=False, healthy=False, reason=f"the stack server is gone: {err}")
        deadline = time.monotonic() + budget
        interrupted_at = None
        while True:
            line = self._next_line(0.05, lambda: False)
            if line is not None:
                try:
                    return SimulationReply.from_line(line)
                except (ValueError, TypeError) as err:
                    return SimulationReply(ran=True, healthy=False, reason=f"the stack server said {line!r}: {err}")
            if self.server.poll() is not None and self._lines.empty():
                return SimulationReply(ran=True, healthy=False,
                                       reason=f"the stack server exited with status {self.server.returncode}")
            now = time.monotonic()
            if interrupted_at is None and interrupt():
                interrupted_at = now
                deadline = min(deadline, now + 45.0)
                try:
                    os.kill(self.server.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
            if now > deadline:
                return SimulationReply(ran=True, healthy=False, reason="the stack server hung and was stopped")

    def stop(self) -> list[str]:
        """End the server (it ends the stack), then anything left with the stack's token, then the master."""
        leftovers: list[str] = []
        server = self.server
        if server is not None:
            if server.poll() is None:
                try:
                    assert server.stdin is not None
                    server.stdin.close()  # end of requests: the server ends the stack and exits
                except OSError:
                    pass
                try:
                    server.wait(STOP_TIMEOUT)
                except subprocess.TimeoutExpired:
                    end_process_group(server, grace=2.0)
            self.server = None
        leftovers = kill_tagged(self.token)
        if self.master is not None:
            self.master.stop()
            self.master = None
        return leftovers


def server_argv(config) -> list[str]:
    """The stack server's command line for a BatchConfig."""
    i = config.inputs
    return [sys.executable, "-m", "magna_master.stack_server", "--rtf", config.rtf,
            "--worlds-path", str(i.worlds_path), "--output", config.output,
            "--battery-floor", f"{config.battery_floor:g}", "--parent-pid", str(os.getpid())]


def ground_station_params(config, data_dir: Path | None, plan) -> dict:
    """The ground station's private parameters, as simulation.launch gives them, and no teardown:
    the stack's reset clears the UAVs and the world at once."""
    i = config.inputs
    return {"mission_file": str(i.mission_file), "data_dir": str(data_dir) if data_dir is not None else "",
            "bag": bool(plan.save and config.bag), "save_data": bool(plan.save), "control_rate": 10.0,
            "manager_output": config.output, "button_timeout": float(config.button_timeout),
            "utm_plan": str(config.utm_plan) if config.utm_plan else "", "fleet_file": "", "teardown": False,
            "managers": config.managers}
