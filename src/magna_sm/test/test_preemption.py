"""Preemption: prompt, reported as 'preempted', and repeatable on the same objects (smach's faults avoided)."""
import threading
import time

import pytest

from magna_sm import PREEMPTED, CBState, Concurrence, Sequence, StateMachine


class Blocking:
    """A leaf body that waits until preempted (or released), recording what it saw."""

    def __init__(self):
        self.started = threading.Event()
        self.saw_preempt = 0
        self.runs = 0
        self.patience = 10.0  # seconds to wait for a preemption before finishing normally

    def __call__(self, ud, state):
        self.runs += 1
        self.started.set()
        if state.wait_for_preempt(self.patience):
            self.saw_preempt += 1
            state.service_preempt()
            return "preempted"
        return "done"


def blocking_state(body):
    return CBState(body, ["done", "preempted"], pass_state=True)


def run_in_thread(container):
    result = {}
    thread = threading.Thread(target=lambda: result.setdefault("outcome", container.execute()), daemon=True)
    thread.start()
    return thread, result


def preempt_when_started(container, body, timeout=5.0):
    thread, result = run_in_thread(container)
    assert body.started.wait(timeout)
    start = time.monotonic()
    container.request_preempt()
    thread.join(timeout)
    assert not thread.is_alive(), "the machine did not stop after preemption"
    body.started.clear()
    return result["outcome"], time.monotonic() - start


def nested_machine():
    body = Blocking()
    inner = StateMachine(["done"])
    with inner:
        StateMachine.add("WAIT", blocking_state(body), {"done": "done"})
    outer = StateMachine(["finished"], name="MISSION")
    with outer:
        StateMachine.add("INNER", inner, {"done": "AFTER"})
        StateMachine.add("AFTER", CBState(lambda ud: "ok", ["ok"]), {"ok": "finished"})
    return outer, body


def test_preempting_a_running_machine_reaches_the_active_leaf_and_returns_preempted():
    outer, body = nested_machine()
    outcome, _elapsed = preempt_when_started(outer, body)
    assert outcome == PREEMPTED
    assert body.saw_preempt == 1


def test_the_same_machine_can_be_preempted_again_and_again():
    outer, body = nested_machine()
    for round_number in range(1, 6):
        outcome, _ = preempt_when_started(outer, body)
        assert outcome == PREEMPTED
        assert body.saw_preempt == round_number
    # ...and then still run to completion normally: no stale preemption left anywhere.
    assert not outer["INNER"]["WAIT"].preempt_requested() and not outer.preempt_requested()
    body.patience = 0.05
    assert outer.execute() == "finished"


def test_preempting_twice_is_harmless():
    outer, body = nested_machine()
    thread, result = run_in_thread(outer)
    assert body.started.wait(5)
    outer.request_preempt()
    outer.request_preempt()
    thread.join(5)
    assert result["outcome"] == PREEMPTED
    assert not outer.preempt_requested()
    assert not outer["INNER"].preempt_requested()


def test_a_leaf_that_ignores_preemption_still_stops_the_machine_after_it():
    after = []
    sm = StateMachine(["done"])
    gate = threading.Event()
    started = threading.Event()
    with sm:
        StateMachine.add("STUBBORN", CBState(lambda ud: started.set() or gate.wait(5) and "ok", ["ok"]),
                         {"ok": "NEXT"})
        StateMachine.add("NEXT", CBState(lambda ud: after.append(1) or "ok", ["ok"]), {"ok": "done"})
    thread, result = run_in_thread(sm)
    assert started.wait(5)
    sm.request_preempt()
    gate.set()
    thread.join(5)
    assert result["outcome"] == PREEMPTED
    assert after == [], "no state may start after the machine was preempted"


def test_preempted_concurrence_reports_preempted_and_preempts_every_child():
    bodies = [Blocking(), Blocking()]
    cc = Concurrence(["ok"], default_outcome="ok", outcome_map={"ok": {"A": "done", "B": "done"}})
    with cc:
        Concurrence.add("A", blocking_state(bodies[0]))
        Concurrence.add("B", blocking_state(bodies[1]))
    for round_number in (1, 2, 3):
        thread, result = run_in_thread(cc)
        assert all(body.started.wait(5) for body in bodies)
        cc.request_preempt()
        thread.join(5)
        assert result["outcome"] == PREEMPTED
        assert [body.saw_preempt for body in bodies] == [round_number, round_number]
        for body in bodies:
            body.started.clear()


def test_preempting_a_concurrence_inside_a_machine_propagates_preempted_upwards():
    body = Blocking()
    cc = Concurrence(["ok"], default_outcome="ok")
    with cc:
        Concurrence.add("WAIT", blocking_state(body))
    sm = StateMachine(["ok"], name="TOP")
    with sm:
        StateMachine.add("CC", cc, {"ok": "ok"})
    outcome, _ = preempt_when_started(sm, body)
    assert outcome == PREEMPTED


def test_empty_concurrence_returns_at_once():
    cc = Concurrence(["ok"], default_outcome="ok")
    thread, result = run_in_thread(cc)
    thread.join(2)
    assert not thread.is_alive()
    assert result["outcome"] == "ok"


def test_preempting_an_idle_machine_does_not_leak_into_its_next_run():
    ran = []
    sm = StateMachine(["done"])
    with sm:
        StateMachine.add("A", CBState(lambda ud: ran.append(1) or "ok", ["ok"]), {"ok": "done"})
    sm.request_preempt()
    assert sm.execute() == "done"
    assert ran == [1]


def test_children_of_a_concurrence_preempted_before_their_threads_start_still_stop():
    """child_termination_cb fires as the first child ends, possibly before another child's thread ran."""
    inner = StateMachine(["done"])
    with inner:
        StateMachine.add("LONG", blocking_state(Blocking()), {"done": "done"})
    cc = Concurrence(["stop", "ok"], default_outcome="ok", outcome_map={"stop": {"FAST": "stop"}},
                     child_termination_cb=lambda outcomes: True)
    with cc:
        Concurrence.add("FAST", CBState(lambda ud: "stop", ["stop"]))
        Concurrence.add("SLOW", inner)
    for _ in range(20):
        thread, result = run_in_thread(cc)
        thread.join(5)
        assert not thread.is_alive(), "a child missed the preemption and kept running"
        assert result["outcome"] == "stop"
        assert cc.child_outcomes["SLOW"] == PREEMPTED


def test_sequence_preemption():
    body = Blocking()
    seq = Sequence(["done"], connector_outcome="done")
    with seq:
        Sequence.add("ONE", blocking_state(body), {"preempted": "preempted"})
        Sequence.add("TWO", CBState(lambda ud: "done", ["done"]))
    outcome, _ = preempt_when_started(seq, body)
    assert outcome == PREEMPTED


@pytest.mark.parametrize("delay_us", [0, 20, 50, 100, 200, 400])
def test_preemption_racing_normal_completion(delay_us):
    """Whichever wins, the result is one of the two outcomes, nothing hangs, nothing stale remains."""
    seen = set()
    for _ in range(40):
        sm = StateMachine(["done"])
        with sm:
            StateMachine.add("A", CBState(lambda ud: "ok", ["ok"]), {"ok": "B"})
            StateMachine.add("B", CBState(lambda ud: "ok", ["ok"]), {"ok": "done"})
        thread, result = run_in_thread(sm)
        deadline = time.perf_counter() + delay_us * 1e-6
        while time.perf_counter() < deadline:
            pass
        sm.request_preempt()
        thread.join(5)
        assert not thread.is_alive()
        assert result["outcome"] in {"done", PREEMPTED}
        seen.add(result["outcome"])
        # A preemption that lost the race is gone with the run it aimed at.
        assert not sm.preempt_requested()
        assert not sm["A"].preempt_requested() and not sm["B"].preempt_requested()
        assert sm.execute() == "done"
    assert seen
