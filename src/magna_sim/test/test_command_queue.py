"""Work handed from other threads to the loop: results, errors, waits and stopping."""
import threading
import time

import pytest

from magna_sim.command_queue import CommandQueue, LoopStopped
from tests.support import WAIT, wait_until


class Loop:
    """A stand-in for the simulation loop: runs jobs and checks waiters until stopped."""

    def __init__(self, queue):
        self.queue, self.ticks, self.running = queue, 0, True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while self.running:
            self.queue.run_pending()
            self.ticks += 1
            self.queue.check_waiters()
            time.sleep(0.0005)

    def stop(self):
        self.running = False
        self.thread.join()


@pytest.fixture
def loop():
    queue = CommandQueue()
    running = Loop(queue)
    yield running
    running.stop()
    queue.stop()


def test_run_returns_the_result_computed_in_the_loop_thread(loop):
    assert loop.queue.run(lambda: threading.current_thread() is loop.thread) is True


def test_errors_come_back_to_the_caller(loop):
    with pytest.raises(ValueError, match="bad height"):
        loop.queue.run(lambda: (_ for _ in ()).throw(ValueError("bad height")))


def test_wait_for_returns_when_the_check_holds(loop):
    start = loop.ticks
    assert loop.queue.wait_for(lambda: "done" if loop.ticks >= start + 20 else None, timeout=10) == "done"
    assert loop.ticks >= start + 20


def test_wait_for_times_out_and_forgets_the_check(loop):
    with pytest.raises(TimeoutError):
        loop.queue.wait_for(lambda: None, timeout=0.05)
    assert loop.queue._waiters == []


def test_stop_releases_every_waiting_caller_with_its_reason():
    queue = CommandQueue()  # no loop: nothing would ever run a job or check a waiter
    outcomes = {}

    def call(name, request):
        try:
            outcomes[name] = request()
        except LoopStopped as err:
            outcomes[name] = f"LoopStopped: {err}"

    callers = [threading.Thread(target=call, args=("run", lambda: queue.run(lambda: 1)), daemon=True),
               threading.Thread(target=call, args=("wait_for", lambda: queue.wait_for(lambda: None)), daemon=True)]
    for caller in callers:
        caller.start()
    wait_until(lambda: len(queue._jobs) == 1 and len(queue._waiters) == 1, "both callers to be queued")
    tickets = [queue._jobs[0], queue._waiters[0]]
    queue.stop("bye")
    # Released by stop() itself, before it returns: not later by a caller noticing that the loop stopped.
    assert all(ticket.done.is_set() and isinstance(ticket.error, LoopStopped) for ticket in tickets)
    for caller in callers:
        caller.join(timeout=WAIT)
    assert outcomes == {"run": "LoopStopped: bye", "wait_for": "LoopStopped: bye"}
    with pytest.raises(LoopStopped):
        queue.run(lambda: 1)
    with pytest.raises(LoopStopped):
        queue.wait_for(lambda: 1)


def test_release_waiters_fails_the_waiting_callers_and_keeps_serving(loop):
    outcome = {}

    def wait_for_ever():
        try:
            outcome["wait_for"] = loop.queue.wait_for(lambda: None)
        except LoopStopped as err:
            outcome["wait_for"] = f"LoopStopped: {err}"

    caller = threading.Thread(target=wait_for_ever, daemon=True)
    caller.start()
    wait_until(lambda: loop.queue._waiters, "the caller to wait")
    loop.queue.run(lambda: loop.queue.release_waiters("the simulation was reset"))
    caller.join(timeout=WAIT)
    assert outcome == {"wait_for": "LoopStopped: the simulation was reset"}
    assert loop.queue.run(lambda: "still served") == "still served"
