"""Build-time validation: every problem found at once, each named by its container path."""
import pytest

from magna_sm import CBState, Concurrence, Iterator, StateMachine, ValidationError


def leaf(*outcomes):
    return CBState(lambda ud: outcomes[0], list(outcomes))


def problems_of(container):
    with pytest.raises(ValidationError) as raised:
        container.check()
    return raised.value.problems


def mission_with_bad_delivery():
    """/MISSION/1_filmed_delivery/2_filming, as a mission author would nest it."""
    filming = StateMachine(["succeeded"])
    with filming:
        StateMachine.add("follow", leaf("succeeded", "collision"), {"succeeded": "succeeded", "collision": "1_land"})
    delivery = Concurrence(["completed", "failed"], default_outcome="failed",
                           outcome_map={"completed": {"2_filming": "succeeded"}})
    with delivery:
        Concurrence.add("2_filming", filming)
    mission = StateMachine(["done"], name="MISSION")
    with mission:
        StateMachine.add("1_filmed_delivery", delivery, {"completed": "done", "failed": "done"})
    return mission


def test_transition_to_a_missing_state_names_the_full_path():
    problems = problems_of(mission_with_bad_delivery())
    assert ("/MISSION/1_filmed_delivery/2_filming/follow: outcome 'collision' goes to '1_land', "
            "which is neither a state nor an outcome of this machine") in problems


def test_every_problem_is_reported_at_once():
    sm = StateMachine(["done", "never"], name="M")
    with sm:
        StateMachine.add("A", leaf("ok", "lost"), {"ok": "B"})
        StateMachine.add("B", leaf("ok"), {"ok": "done"})
        StateMachine.add("ISLAND", leaf("ok"), {"ok": "done"})
        StateMachine.add("C", leaf("ok"), {"ok": "GHOST", "typo": "done"})
    problems = problems_of(sm)
    assert "/M/A: outcome 'lost' is not mapped (map it to a state or to one of ['done', 'never', 'preempted'])" \
        in problems
    assert "/M/ISLAND: unreachable from the initial state 'A'" in problems
    assert "/M/C: unreachable from the initial state 'A'" in problems
    assert "/M/C: outcome 'ok' goes to 'GHOST', which is neither a state nor an outcome of this machine" in problems
    assert ("/M/C: transition for outcome 'typo', which the state does not declare ['ok']") in problems
    assert "/M: no state leads to the container outcome 'never'" in problems


def test_duplicate_labels_are_refused_when_added():
    sm = StateMachine(["done"], name="M")
    with sm:
        StateMachine.add("A", leaf("done"))
        with pytest.raises(ValidationError, match="/M: duplicate state label 'A'"):
            StateMachine.add("A", leaf("done"))


def test_one_state_object_cannot_sit_in_two_places():
    shared = leaf("done")
    first, second = StateMachine(["done"], name="ONE"), StateMachine(["done"], name="TWO")
    first.add_state("X", shared)
    with pytest.raises(ValidationError, match="already /ONE/X"):
        second.add_state("Y", shared)


def test_execute_validates_before_running_anything():
    ran = []
    sm = StateMachine(["done"], name="M")
    with sm:
        StateMachine.add("FIRST", CBState(lambda ud: ran.append(1) or "ok", ["ok"]), {"ok": "MISSING"})
    with pytest.raises(ValidationError, match="MISSING"):
        sm.execute()
    assert ran == []


def test_empty_machine_and_bad_initial_state():
    assert problems_of(StateMachine(["done"], name="EMPTY")) == ["/EMPTY: has no states"]
    sm = StateMachine(["done"], name="M")
    with sm:
        StateMachine.add("A", leaf("done"))
    sm.set_initial_state("Z")
    assert "/M: initial state 'Z' is not a state of this machine" in problems_of(sm)


def test_concurrence_problems():
    cc = Concurrence(["ok", "unused"], default_outcome="missing", name="CC",
                     outcome_map={"ok": {"A": "nope", "GHOST": "done"}, "bogus": {"A": "done"}})
    with cc:
        Concurrence.add("A", leaf("done"))
    problems = problems_of(cc)
    assert "/CC: default_outcome 'missing' is not one of ['ok', 'unused', 'preempted']" in problems
    assert "/CC: outcome_map['ok'] expects 'A' to return 'nope', which it does not declare" in problems
    assert "/CC: outcome_map['ok'] names 'GHOST', not a child" in problems
    assert "/CC: outcome_map names 'bogus', not an outcome of the container" in problems
    assert "/CC: no outcome_map entry or default leads to the container outcome 'unused'" in problems


def test_iterator_outcome_that_neither_loops_nor_ends():
    it = Iterator(["done"], it=[1], exhausted_outcome="done", name="IT")
    with it:
        Iterator.set_contained_state("S", leaf("next", "weird"), loop_outcomes=["next"])
    assert problems_of(it) == ["/IT/S: outcome 'weird' neither loops nor ends the iterator "
                               "(add it to loop_outcomes, or to the iterator's outcomes)"]


def test_a_valid_machine_passes():
    sm = StateMachine(["done"])
    with sm:
        StateMachine.add("A", leaf("ok"), {"ok": "done"})
    sm.check()
    assert sm.execute() == "done"


def test_add_needs_an_open_container_of_the_right_kind():
    from magna_sm import StateMachineError
    with pytest.raises(StateMachineError, match="needs an open container"):
        StateMachine.add("A", leaf("done"))
    with Concurrence(["ok"], default_outcome="ok"), pytest.raises(StateMachineError, match="is the open container"):
        StateMachine.add("A", leaf("done"))
