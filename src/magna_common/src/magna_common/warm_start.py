"""Warm starts: a Python process that has imported a node's modules ahead of time runs the node when told.

A batch on a persistent stack starts a ground station for every simulation, and its Python
imports (rospy, numpy, the mission model: ~0.7 s on 2 cores) fall in the simulation's window.
`WarmStarter` keeps one process ready: prepared while the previous simulation flies (its set-up
left alone: that is when every core is busy), it has imported the modules and waits;
`start(command, log_path, env)` hands it the command instead of starting a new interpreter.

The process side, `python -m magna_common.warm_start MODULE...`: imports the modules, says
"ready" on stdout, reads one JSON line on stdin ({"script", "argv", "env", "log", "cwd"}),
then takes that environment and working directory, sends its output to the log, and runs the
script as __main__ with sys.argv = [script, *argv], as `python script argv...` would.

Whatever keeps a warm process from being used (it died, it is not ready in time, the command
is not the script it was prepared for) falls back to starting the command cold.
"""
from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import IO

READY = b"ready\n"
READY_TIMEOUT = 10.0  # wall s a warm process may still be importing when it is wanted


class WarmStarter:
    """Starts `python script ...` commands on a process prepared ahead, with `modules` imported."""

    def __init__(self, script: str, modules: Sequence[str], env: dict | None = None,
                 ready_timeout: float = READY_TIMEOUT):
        self.script = str(script)
        self.modules = list(modules)
        self.env = env  # the prepared process's environment while it imports (None: ours)
        self.ready_timeout = ready_timeout
        self._lock = threading.Lock()  # prepare() may run on a timer while start() runs
        self._ready: subprocess.Popen | None = None
        self._timer: threading.Timer | None = None
        self.warm_starts = self.cold_starts = 0

    @property
    def prepared(self) -> subprocess.Popen | None:
        """The warm process waiting for its command, if any."""
        return self._ready

    def prepare(self) -> None:
        """Start the next warm process, unless one is there already."""
        with self._lock:
            if self._ready is not None and self._ready.poll() is None:
                return
            self._ready = subprocess.Popen([sys.executable, "-m", __name__, *self.modules], stdin=subprocess.PIPE,
                                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=self.env,
                                           start_new_session=True)

    def prepare_in(self, delay: float) -> None:
        """prepare() after `delay` wall seconds (an earlier call not yet due is replaced)."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            self._timer = threading.Timer(max(0.0, delay), self.prepare)
            self._timer.daemon = True
            self._timer.start()

    def start(self, command: Sequence[str], log_path: Path, env: dict | None = None) -> subprocess.Popen:
        """Run `command` (its output appended to `log_path`, stdin empty, in its own session) on the warm process
        when it can take it, else as a new process."""
        command = list(command)
        process = self._take() if command[:2] == [sys.executable, self.script] else None
        if process is not None:
            order = {"script": self.script, "argv": command[2:], "env": dict(os.environ if env is None else env),
                     "log": str(Path(log_path).resolve()), "cwd": os.getcwd()}
            try:
                _pipe(process.stdin).write(json.dumps(order).encode() + b"\n")
                _pipe(process.stdin).close()
                self.warm_starts += 1
            except OSError:  # it died just now
                _end(process)
                process = None
        if process is None:
            process = cold_start(command, log_path, env)
            self.cold_starts += 1
        return process

    def close(self) -> None:
        """End the prepared process (it has run nothing), and any preparation still to come."""
        with self._lock:
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
            timer.join()  # a preparation already under way has put its process in place by now
        with self._lock:
            process, self._ready = self._ready, None
        if process is not None:
            _end(process)

    def _take(self) -> subprocess.Popen | None:
        """The prepared process once it says ready (waiting up to ready_timeout), or None."""
        with self._lock:
            process, self._ready = self._ready, None
        if process is None:
            return None
        deadline = time.monotonic() + self.ready_timeout
        said = b""
        out = _pipe(process.stdout)
        while process.poll() is None and len(said) < len(READY):
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([out], [], [], left)[0]:
                break
            chunk = os.read(out.fileno(), len(READY) - len(said))
            if not chunk:
                break
            said += chunk
        if said != READY or process.poll() is not None:
            _end(process)
            return None
        out.close()
        return process


def cold_start(command: Sequence[str], log_path: Path, env: dict | None = None) -> subprocess.Popen:
    """`command` as a new process: output appended to `log_path`, stdin empty, in its own session."""
    with open(log_path, "ab") as log:
        return subprocess.Popen(list(command), stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env=env, start_new_session=True)


def _pipe(stream: IO[bytes] | None) -> IO[bytes]:
    """A warm process's stdin or stdout: always a pipe (made with PIPE)."""
    if stream is None:
        raise OSError("a warm process without its pipe")
    return stream


def _end(process: subprocess.Popen) -> None:
    for stream in (process.stdin, process.stdout):
        if stream is not None:
            try:
                stream.close()
            except OSError:
                pass
    if process.poll() is None:
        process.kill()
    process.wait()


def _run(modules: Sequence[str]) -> None:
    import importlib
    import runpy

    for module in modules:
        importlib.import_module(module)
    os.write(1, READY)
    line = sys.stdin.buffer.readline()
    if not line:  # the starter closed without an order: nothing to run
        return
    order = json.loads(line)
    os.environ.clear()
    os.environ.update(order["env"])
    os.chdir(order["cwd"])
    with open(order["log"], "ab") as log:  # the node's output, as if started with stdout=log
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
    with open(os.devnull, "rb") as nothing:
        os.dup2(nothing.fileno(), 0)
    sys.argv = [order["script"], *order["argv"]]
    if "rospy.names" in sys.modules:  # rospy reads the remappings (__name:=, __log:=) from sys.argv at its import
        sys.modules["rospy.names"].reload_mappings(sys.argv)
    runpy.run_path(order["script"], run_name="__main__")


if __name__ == "__main__":
    _run(sys.argv[1:])
