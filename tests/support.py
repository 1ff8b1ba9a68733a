"""Helpers shared by tests of several packages (importable as tests.support)."""
import time

WAIT = 10.0  # s: a guard against hangs, never a performance expectation


def wait_until(predicate, what: str, timeout: float = WAIT, poll: float = 0.005) -> None:
    """Return as soon as `predicate()` holds; fail the test naming `what` after `timeout` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(poll)
    raise AssertionError(f"timed out waiting for {what}")
