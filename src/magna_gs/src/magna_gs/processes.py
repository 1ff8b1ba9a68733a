"""The processes the ground station starts (UAV managers, rosbag record) and how it ends them."""
from __future__ import annotations

import os
import signal
import subprocess


def end_group(process: subprocess.Popen, grace: float = 5.0) -> None:
    """End a process we started and everything in its process group: SIGINT, then SIGTERM, then SIGKILL."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if process.poll() is not None:
            return
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            return
        try:
            process.wait(grace)
        except subprocess.TimeoutExpired:
            continue
