"""Processes started in a session of their own (ROS nodes, rosbag, launch files) and how they end.

Shared by the ground station and magna_master (which depends on magna_gs); no ROS imports here.
"""
from __future__ import annotations

import os
import signal
import subprocess
import xmlrpc.client


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
