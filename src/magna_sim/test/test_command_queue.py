"""Work handed from other threads to the loop: results, errors, waits and stopping."""
import threading
import time

import pytest

from magna_sim.command_queue import CommandQueue, LoopStopped


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


def test_stop_releases_waiting_callers():
    queue = CommandQueue()  # no loop: nothing would ever run
    errors = []

    def call():
        try:
            queue.run(lambda: 1)
        except LoopStopped as err:
            errors.append(err)

    caller = threading.Thread(target=call)
    caller.start()
    time.sleep(0.05)
    queue.stop("bye")
    caller.join(timeout=5)
    assert not caller.is_alive() and len(errors) == 1
    with pytest.raises(LoopStopped):
        queue.run(lambda: 1)
