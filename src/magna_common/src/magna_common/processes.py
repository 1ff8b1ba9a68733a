"""Processes started in a session of their own (ROS nodes, rosbag, launch files) and how they end.

Shared by the ground station, the Master, the replay and the tests; no ROS imports here.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import threading
import time
import xmlrpc.client
from collections.abc import Iterable
from pathlib import Path

# Every process of one simulation carries MAGNA_SIM_TOKEN=<token> in its environment, so that the
# Master can find (and end) those that roslaunch put in sessions of their own.
TOKEN_ENV = "MAGNA_SIM_TOKEN"


class TimeoutTransport(xmlrpc.client.Transport):
    """An XML-RPC transport that gives up on a master or node that does not answer."""

    def __init__(self, timeout: float):
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host):
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


def end_process_group(process: subprocess.Popen, grace: float = 5.0) -> None:
    """Stop a process started in its own session, and every child it made.

    SIGINT first (ROS nodes shut down cleanly on it), then SIGTERM, then SIGKILL.
    """
    if process.poll() is None:
        for sig, wait in ((signal.SIGINT, grace), (signal.SIGTERM, grace), (signal.SIGKILL, grace)):
            try:
                os.killpg(process.pid, sig)
            except ProcessLookupError:
                break
            try:
                process.wait(timeout=wait)
                break
            except subprocess.TimeoutExpired:
                continue
    # The leader may be gone while children it left behind in the group live on.
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    if process.poll() is None:
        process.wait(timeout=grace)


def parent_roslaunch() -> int | None:
    """The pid of the roslaunch that started this process as one of its nodes, or None."""
    parent = os.getppid()
    try:
        words = Path(f"/proc/{parent}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return None
    # `roslaunch ...`, `python3 /usr/bin/roslaunch ...` or `python3 -m roslaunch ...`
    return parent if any(os.path.basename(os.fsdecode(word)) == "roslaunch" for word in words[:3]) else None


def end_parent_launch(timeout: float = 20.0) -> bool:
    """End the roslaunch that started this node as Ctrl-C does, and wait until it stops us.

    roslaunch reports a `required` node that exits, even with status 0, in red ("REQUIRED
    process [...] has died!") and shuts the launch down. A required node that has finished its
    work normally calls this instead of just returning: the launch ends quietly, as at Ctrl-C,
    while a crash, an error status or a kill is still reported in red. Call it from the main
    thread. False when no roslaunch started this process (`rosrun`, a test) or when it did not
    stop us within `timeout` seconds (the node then exits and roslaunch reports it).
    """
    launch = parent_roslaunch()
    if launch is None:
        return False
    stopped = threading.Event()
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda *_: stopped.set()) for sig in signals}
    try:
        os.kill(launch, signal.SIGINT)
        return stopped.wait(timeout)
    except ProcessLookupError:  # it ended meanwhile
        return False
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


# --- processes, found through /proc --------------------------------------------------------------------

def pid_alive(pid: int) -> bool:
    """True while `pid` runs (a zombie waiting to be reaped counts as dead)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


def process_state(pid: int) -> str | None:
    """The state letter of `pid` in /proc (R running, S sleeping, T stopped, t traced, Z zombie...); None if gone."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return None


def ancestors(pid: int | None = None) -> set[int]:
    """`pid` (default: this process) and every process above it."""
    pid = os.getpid() if pid is None else pid
    chain = set()
    while pid > 1 and pid not in chain:
        chain.add(pid)
        try:
            with open(f"/proc/{pid}/stat") as stat:
                pid = int(stat.read().rsplit(")", 1)[1].split()[1])
        except (FileNotFoundError, ProcessLookupError, IndexError, ValueError):
            break
    return chain


def tagged_processes(name: str, value: str, exclude: Iterable[int] = ()) -> list[tuple[int, str]]:
    """Live processes whose environment holds `name=value`, as (pid, command line)."""
    needle = f"{name}={value}".encode()
    skip = set(exclude)
    found = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit() or int(entry.name) in skip:
            continue
        try:
            with open(f"/proc/{entry.name}/environ", "rb") as handle:
                if needle not in handle.read().split(b"\0"):
                    continue
            with open(f"/proc/{entry.name}/cmdline", "rb") as handle:
                command = handle.read().replace(b"\0", b" ").decode(errors="replace").strip()
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue
        if pid_alive(int(entry.name)):
            found.append((int(entry.name), command))
    return found


def kill_tagged(token: str, exclude: Iterable[int] = (), timeout: float = 5.0) -> list[str]:
    """SIGKILL every live process carrying MAGNA_SIM_TOKEN=token (but `exclude`); describe what was killed."""
    exclude = set(exclude)
    killed: list[str] = []
    deadline = time.monotonic() + timeout
    while True:
        left = tagged_processes(TOKEN_ENV, token, exclude)
        if not left or time.monotonic() > deadline:
            return killed
        for pid, command in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                continue
            description = f"{pid} {command[:200]}"
            if description not in killed:
                killed.append(description)
        time.sleep(0.05)


def set_parent_death_signal(sig: int = signal.SIGTERM) -> bool:
    """Ask Linux to send `sig` to this process when its parent dies (prctl PR_SET_PDEATHSIG)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(1, int(sig), 0, 0, 0) == 0  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return False
