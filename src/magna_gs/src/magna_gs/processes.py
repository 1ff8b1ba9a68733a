"""Processes started in a session of their own (ROS nodes, rosbag, launch files) and how they end.

Shared by the ground station and magna_master (which depends on magna_gs); no ROS imports here.
"""
from __future__ import annotations

import os
import signal
import subprocess
import threading
import xmlrpc.client
from pathlib import Path


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
