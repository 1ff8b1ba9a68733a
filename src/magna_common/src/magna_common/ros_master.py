"""A private ROS master on a free port, and the processes started against it.

Tests, `magna doctor` and the simulation batches each need a ROS graph of their
own that cannot collide with a user's roscore on 11311 nor with another run on
the same machine. `RosMaster` owns one: it starts `rosmaster` on a free port,
starts nodes bound to it, and on `stop()` ends exactly those processes, by
process group, and nothing else.
"""
from __future__ import annotations

import os
import subprocess
import tempfile
import time
import uuid
import xmlrpc.client
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

from magna_common.ports import free_port
from magna_common.processes import TimeoutTransport, end_process_group


class RosMasterError(RuntimeError):
    pass


def _master_pid(uri: str, timeout: float) -> int | None:
    """The pid of the master answering at `uri`, or None when nothing answers."""
    transport = TimeoutTransport(timeout)
    try:
        answer: Any = xmlrpc.client.ServerProxy(uri, transport=transport).getPid("/magna_probe")
    except (OSError, xmlrpc.client.Error):
        return None
    code, _msg, pid = answer  # the ROS master API answers [code, status message, value]
    return int(pid) if code == 1 else None


class RosMaster:
    """A rosmaster on a free port and the processes started against it.

    Use as a context manager; every process it started is ended on exit.
    """

    def __init__(self, port: int | None = None, host: str = "127.0.0.1", start_timeout: float = 15.0,
                 log_dir: Path | None = None):
        self._requested_port = port
        self.host = host
        self.start_timeout = start_timeout
        self.log_dir = Path(log_dir) if log_dir else None
        self.port: int | None = None
        self._master: subprocess.Popen | None = None
        self._children: list[subprocess.Popen] = []
        self._master_stderr: IO[bytes] | None = None

    @property
    def uri(self) -> str:
        if self.port is None:
            raise RosMasterError("the master is not started")
        return f"http://{self.host}:{self.port}/"

    def env(self, base: dict | None = None) -> dict:
        """An environment in which ROS nodes talk to this master."""
        env = dict(os.environ if base is None else base)
        env["ROS_MASTER_URI"] = self.uri
        env["ROS_IP"] = self.host
        env.pop("ROS_HOSTNAME", None)
        if self.log_dir is not None:
            env["ROS_LOG_DIR"] = str(self.log_dir)
        return env

    def start(self) -> RosMaster:
        if self._master is not None:
            return self
        attempts = 1 if self._requested_port else 3
        last_error = ""
        for _ in range(attempts):
            self.port = self._requested_port or free_port(self.host)
            # A file, not a pipe: nobody drains the master's stderr while it runs.
            self._master_stderr = stderr = tempfile.TemporaryFile()
            self._master = subprocess.Popen(
                ["rosmaster", "--core", "-p", str(self.port), "-w", "3"],
                env=self.env(), stdout=subprocess.DEVNULL, stderr=self._master_stderr,
                start_new_session=True,
            )
            deadline = time.monotonic() + self.start_timeout
            while time.monotonic() < deadline:
                if self._master.poll() is not None:
                    stderr.seek(0)
                    last_error = stderr.read().decode(errors="replace").strip()
                    break
                answering = _master_pid(self.uri, timeout=0.5)
                if answering == self._master.pid:
                    self._set_run_id()
                    return self
                if answering is not None:
                    # Another master holds the port; ours will fail to bind.
                    last_error = f"port {self.port} is taken by another master (pid {answering})"
                    break
                time.sleep(0.05)
            else:
                last_error = f"no answer within {self.start_timeout:.0f} s"
            self._end_master()
        raise RosMasterError(f"rosmaster on port {self.port} did not start: {last_error}")

    def _set_run_id(self) -> None:
        # roslaunch-started nodes expect /run_id, which only roscore sets.
        proxy = xmlrpc.client.ServerProxy(self.uri)
        proxy.setParam("/magna_master", "/run_id", str(uuid.uuid1()))

    def spawn(self, argv: Sequence[str], env: dict | None = None, **popen_kwargs) -> subprocess.Popen:
        """Start a process bound to this master, in its own process group, ended by `stop()`."""
        if self._master is None:
            raise RosMasterError("start the master before spawning nodes")
        process = subprocess.Popen(list(argv), env=self.env(env), start_new_session=True, **popen_kwargs)
        self._children.append(process)
        return process

    def stop(self) -> None:
        for process in reversed(self._children):
            end_process_group(process)
        self._children.clear()
        self._end_master()

    def _end_master(self) -> None:
        if self._master is not None:
            end_process_group(self._master)
            self._master = None
        if self._master_stderr is not None:
            self._master_stderr.close()
            self._master_stderr = None

    @property
    def running(self) -> bool:
        return self._master is not None and self._master.poll() is None

    def __enter__(self) -> RosMaster:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
