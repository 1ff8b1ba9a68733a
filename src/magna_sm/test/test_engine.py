"""The engine's execution semantics: transitions, userdata, nesting, Concurrence, Sequence, Iterator."""
import re
import sys
import threading

import pytest

from magna_sm import (
    CBState,
    Concurrence,
    InvalidOutcomeError,
    Iterator,
    Sequence,
    State,
    StateExecutionError,
    StateMachine,
    UserData,
    UserDataError,
)


def returns(outcome, log=None, name=None, **keys):
    def cb(ud):
        if log is not None:
            log.append(name)
        return outcome
    return CBState(cb, outcomes=[outcome], **keys)


def test_core_imports_no_ros():
    import subprocess
    code = "import sys, magna_sm; sys.exit(any(m.split('.')[0] in ('rospy', 'roslib', 'genpy') for m in sys.modules))"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_transitions_follow_outcomes_in_order():
    log = []
    sm = StateMachine(["done", "failed"])
    with sm:
        StateMachine.add("A", returns("next", log, "A"), {"next": "B"})
        StateMachine.add("B", CBState(lambda ud: log.append("B") or "bad", ["good", "bad"]),
                         {"good": "done", "bad": "C"})
        StateMachine.add("C", returns("failed", log, "C"))
    assert sm.execute() == "failed"
    assert log == ["A", "B", "C"]
    assert sm.last_outcome == "failed"


def test_userdata_flows_through_remapping_and_back_to_the_parent():
    def produce(ud):
        ud.value = 21
        return "ok"

    def double(ud):
        ud.result = ud.x * 2
        return "ok"

    sm = StateMachine(["ok"], output_keys=["answer"])
    with sm:
        StateMachine.add("PRODUCE", CBState(produce, ["ok"], output_keys=["value"]), {"ok": "DOUBLE"})
        StateMachine.add("DOUBLE", CBState(double, ["ok"], input_keys=["x"], output_keys=["result"]),
                         {"ok": "ok"}, remapping={"x": "value", "result": "answer"})
    parent = UserData()
    assert sm.execute(parent) == "ok"
    assert parent["answer"] == 42


@pytest.mark.parametrize(("keys", "body", "message"), [
    ({}, lambda ud: ud.secret, "reads undeclared userdata key 'secret'"),
    ({}, lambda ud: setattr(ud, "secret", 1), "writes undeclared userdata key 'secret'"),
    ({"input_keys": ["secret"]}, lambda ud: setattr(ud, "secret", 1), "'secret' is input-only (read-only)"),
    ({"output_keys": ["secret"]}, lambda ud: ud.secret, "'secret' is output-only"),
])
def test_undeclared_and_read_only_keys_raise_naming_the_state(keys, body, message):
    sm = StateMachine(["ok"], name="ROOT")
    sm.userdata["secret"] = 0
    with sm:
        StateMachine.add("NOSY", CBState(lambda ud: body(ud) or "ok", ["ok"], **keys))
    with pytest.raises(UserDataError, match=re.escape(message)) as raised:
        sm.execute()
    assert "/ROOT/NOSY" in str(raised.value)


def test_io_keys_are_read_and_write():
    def bump(ud):
        ud.n = ud.n + 1
        return "ok"

    sm = StateMachine(["ok"])
    sm.userdata.n = 1
    with sm:
        StateMachine.add("BUMP", CBState(bump, ["ok"], io_keys=["n"]))
    sm.execute()
    assert sm.userdata.n == 2


def test_nesting_to_any_depth_reports_paths():
    depth = 6
    leaf = returns("ok")
    inner = None
    for level in range(depth):
        container = StateMachine(["ok"])
        with container:
            StateMachine.add(f"L{level}", inner if inner is not None else leaf)
        inner = container
    inner._label = "TOP"
    assert inner.execute() == "ok"
    assert leaf.path == "/TOP" + "".join(f"/L{level}" for level in reversed(range(depth)))


def test_undeclared_outcome_is_an_error_naming_the_state():
    sm = StateMachine(["ok"], name="M")
    with sm:
        StateMachine.add("LIAR", CBState(lambda ud: "surprise", ["ok"]))
    with pytest.raises(InvalidOutcomeError, match="/M/LIAR returned outcome 'surprise'"):
        sm.execute()


def test_exception_in_a_state_names_its_path():
    def boom(ud):
        raise RuntimeError("motor failure")

    sm = StateMachine(["ok"], name="M")
    with sm:
        StateMachine.add("BOOM", CBState(boom, ["ok"]))
    with pytest.raises(StateExecutionError, match="/M/BOOM raised RuntimeError: motor failure"):
        sm.execute()


def _concurrence(**kwargs):
    cc = Concurrence(["all_ok", "one_failed", "other"], default_outcome="other", **kwargs)
    with cc:
        Concurrence.add("A", returns("succeeded"))
        Concurrence.add("B", CBState(lambda ud: "aborted", ["succeeded", "aborted"]))
    return cc


def test_concurrence_runs_children_in_parallel_threads():
    barrier = threading.Barrier(3, timeout=5)  # passes only if all three run at once

    def meet(ud):
        barrier.wait()
        return "done"

    cc = Concurrence(["ok"], default_outcome="ok")
    with cc:
        for label in "ABC":
            Concurrence.add(label, CBState(meet, ["done"]))
    assert cc.execute() == "ok"
    assert cc.child_outcomes == {"A": "done", "B": "done", "C": "done"}


def test_outcome_map_entry_with_most_satisfied_conditions_wins():
    cc = _concurrence(outcome_map={"one_failed": {"B": "aborted"}, "all_ok": {"A": "succeeded"},
                                   "other": {"A": "succeeded", "B": "aborted"}})
    assert cc.execute() == "other"  # two conditions beat one
    cc2 = _concurrence(outcome_map={"one_failed": {"B": "aborted"}, "all_ok": {"A": "succeeded", "B": "succeeded"}})
    assert cc2.execute() == "one_failed"


def test_outcome_cb_overrides_the_map_and_default_applies_last():
    seen = []
    cc = _concurrence(outcome_map={"all_ok": {"A": "succeeded"}},
                      outcome_cb=lambda outcomes: seen.append(outcomes) or "one_failed")
    assert cc.execute() == "one_failed"
    assert seen == [{"A": "succeeded", "B": "aborted"}]
    unmet = {"all_ok": {"A": "succeeded", "B": "succeeded"}}
    assert _concurrence(outcome_map=unmet, outcome_cb=lambda o: None).execute() == "other"


def test_child_termination_cb_preempts_the_remaining_children():
    started = threading.Event()

    def slow(ud, state):
        started.set()
        if state.wait_for_preempt(10):
            state.service_preempt()
            return "preempted"
        return "done"

    def quick(ud):
        started.wait(5)
        return "collision"

    cc = Concurrence(["collision", "ok"], default_outcome="ok",
                     outcome_map={"collision": {"QUICK": "collision"}},
                     child_termination_cb=lambda outcomes: "collision" in outcomes.values())
    with cc:
        Concurrence.add("SLOW", CBState(slow, ["done", "preempted"], pass_state=True))
        Concurrence.add("QUICK", CBState(quick, ["collision"]))
    assert cc.execute() == "collision"
    assert cc.child_outcomes == {"QUICK": "collision", "SLOW": "preempted"}


def test_concurrence_child_exception_stops_the_others_and_propagates():
    def slow(ud, state):
        state.wait_for_preempt(10)
        return "done"

    def boom(ud):
        raise ValueError("bad sensor")

    cc = Concurrence(["ok"], default_outcome="ok", name="CC")
    with cc:
        Concurrence.add("SLOW", CBState(slow, ["done"], pass_state=True))
        Concurrence.add("BOOM", CBState(boom, ["ok"]))
    with pytest.raises(StateExecutionError, match="/CC/BOOM raised ValueError"):
        cc.execute()


def test_sequence_connects_children_in_order():
    log = []
    seq = Sequence(["succeeded", "aborted"], connector_outcome="succeeded")
    with seq:
        Sequence.add("ONE", returns("succeeded", log, "ONE"))
        Sequence.add("TWO", CBState(lambda ud: log.append("TWO") or "succeeded", ["succeeded", "aborted"]))
        Sequence.add("THREE", returns("succeeded", log, "THREE"))
    assert seq.execute() == "succeeded"
    assert log == ["ONE", "TWO", "THREE"]


def test_sequence_other_outcomes_leave_early():
    log = []
    seq = Sequence(["succeeded", "aborted"], connector_outcome="succeeded")
    with seq:
        Sequence.add("ONE", CBState(lambda ud: log.append("ONE") or "aborted", ["succeeded", "aborted"]))
        Sequence.add("TWO", returns("succeeded", log, "TWO"))
    assert seq.execute() == "aborted"
    assert log == ["ONE"]


def test_iterator_runs_once_per_item_and_can_break():
    seen = []

    def visit(ud):
        seen.append(ud.waypoint)
        return "collision" if ud.waypoint == "wp3" else "reached"

    it = Iterator(["succeeded", "collision"], it=["wp1", "wp2", "wp3", "wp4"], it_label="waypoint",
                  exhausted_outcome="succeeded")
    with it:
        Iterator.set_contained_state("VISIT", CBState(visit, ["reached", "collision"], input_keys=["waypoint"]),
                                     loop_outcomes=["reached"])
    assert it.execute() == "collision"
    assert seen == ["wp1", "wp2", "wp3"]


def test_iterator_exhausts_with_items_from_a_callable():
    seen = []
    it = Iterator(["done"], it=lambda: range(3), it_label="i", exhausted_outcome="done")
    with it:
        Iterator.set_contained_state("RUN", CBState(lambda ud: seen.append(ud.i) or "next", ["next"],
                                                    input_keys=["i"]), loop_outcomes=["next"])
    assert it.execute() == "done"
    assert seen == [0, 1, 2]


def test_custom_state_subclass():
    class Counter(State):
        def __init__(self):
            super().__init__(["again", "enough"], io_keys=["count"])

        def execute(self, ud):
            ud.count += 1
            return "enough" if ud.count >= 3 else "again"

    sm = StateMachine(["done"])
    sm.userdata.count = 0
    with sm:
        StateMachine.add("COUNT", Counter(), {"again": "COUNT", "enough": "done"})
    assert sm.execute() == "done"
    assert sm.userdata.count == 3
