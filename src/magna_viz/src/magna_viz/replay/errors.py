"""The two ways a replay ends early: bad input before anything starts, or a process that failed."""
from __future__ import annotations


class ReplayError(ValueError):
    """Bad input (missing bag, not a bag, outputs in the way, no display): nothing was started or written."""


class ReplayFailure(RuntimeError):
    """Something started failed (rviz, Xvfb, rosbag play): every process is ended, the message says where."""
