"""Helpers shared by tests of several packages (importable as tests.support)."""
import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The real ROS-MAGNA files, read in place (never copied into the project): ../shared/ros_magna_corpus.
CORPUS = Path(os.environ.get("MAGNA_CORPUS", ROOT.parent / "shared" / "ros_magna_corpus"))

WAIT = 10.0  # s: a guard against hangs, never a performance expectation


def wait_until(predicate, what: str, timeout: float = WAIT, poll: float = 0.005) -> None:
    """Return as soon as `predicate()` holds; fail the test naming `what` after `timeout` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(poll)
    raise AssertionError(f"timed out waiting for {what}")
