"""SimpleActionState against a live action server: goals, results, custom outcomes, timeouts, preemption, reuse."""
import threading
import time

import pytest

pytestmark = pytest.mark.ros


@pytest.fixture
def action(rospy_node, ns):
    """An action server on a fresh namespace whose behaviour each test scripts through `plan`."""
    from magna_msgs.msg import TakeOffAction, TakeOffResult

    from magna_sm.simple_action import SimpleActionServer

    name = ns
    plan = {"mode": "succeed", "goals": [], "cancelled": 0}

    def execute(goal):
        plan["goals"].append(goal.height)
        if plan["mode"] == "succeed":
            server.set_succeeded(TakeOffResult(outcome=plan.get("outcome", "succeeded"), message="done"))
        elif plan["mode"] == "abort":
            server.set_aborted(TakeOffResult(outcome="aborted", message="motor failure"))
        else:  # hover until cancelled
            while not server.is_preempt_requested() and not rospy_node.is_shutdown():
                time.sleep(0.01)
            plan["cancelled"] += 1
            server.set_preempted(TakeOffResult(outcome="preempted", message="cancelled"))

    server = SimpleActionServer(name, TakeOffAction, execute_cb=execute, auto_start=False)
    server.start()
    yield name, plan
    server.shutdown()


def make_state(name, **kwargs):
    from magna_msgs.msg import TakeOffAction

    from magna_sm.action_state import SimpleActionState
    return SimpleActionState(name, TakeOffAction, server_wait_timeout=10, **kwargs)


def run(state, **userdata):
    from magna_sm import StateMachine
    outcomes = list(state.get_registered_outcomes())
    machine = StateMachine(outcomes)
    machine.userdata.update(userdata)
    machine.add_state("ACT", state)
    return machine.execute(), machine


def test_fixed_goal_succeeds_and_result_lands_in_userdata(action):
    from magna_msgs.msg import TakeOffGoal
    name, plan = action
    outcome, machine = run(make_state(name, goal=TakeOffGoal(height=3.0), result_key="take_off_result",
                                      output_keys=[]))
    assert outcome == "succeeded"
    assert plan["goals"] == [3.0]
    # The result went to the state's userdata key (the machine's store).
    assert machine.userdata["take_off_result"].message == "done"


def test_goal_from_userdata_key_slots_and_callback(action):
    from magna_msgs.msg import TakeOffGoal
    name, plan = action
    run(make_state(name, goal_key="the_goal"), the_goal=TakeOffGoal(height=1.5))
    run(make_state(name, goal_slots=["height"]), height=2.5)
    run(make_state(name, goal_cb=lambda ud, goal: TakeOffGoal(height=ud.base + 1), input_keys=["base"]), base=4.0)
    assert plan["goals"] == [1.5, 2.5, 5.0]


def test_result_cb_returns_a_custom_outcome(action):
    from magna_sm.action_state import outcome_from_result
    name, plan = action
    plan["outcome"] = "collision"
    state = make_state(name, result_cb=outcome_from_result, outcomes=["collision", "low_battery"])
    assert run(state)[0] == "collision"


def test_aborted_goal_gives_aborted(action):
    name, plan = action
    plan["mode"] = "abort"
    state = make_state(name)
    assert run(state)[0] == "aborted"
    from actionlib_msgs.msg import GoalStatus
    assert state.last_status == GoalStatus.ABORTED


def test_preempting_cancels_the_goal_and_the_state_can_run_again(action):
    name, plan = action
    plan["mode"] = "hover"
    state = make_state(name)
    from magna_sm import StateMachine
    machine = StateMachine(["succeeded", "aborted"])
    machine.add_state("ACT", state)
    for round_number in (1, 2, 3):
        result = {}
        thread = threading.Thread(target=lambda out=result: out.setdefault("outcome", machine.execute()), daemon=True)
        thread.start()
        deadline = time.monotonic() + 10
        while len(plan["goals"]) < round_number and time.monotonic() < deadline:
            time.sleep(0.01)
        machine.request_preempt()
        thread.join(10)
        assert result["outcome"] == "preempted"
        assert plan["cancelled"] == round_number, "the server never saw the cancel"
    plan["mode"] = "succeed"
    assert machine.execute() == "succeeded"  # reused after three preemptions


def test_exec_timeout_cancels_and_aborts(action):
    name, plan = action
    plan["mode"] = "hover"
    assert run(make_state(name, exec_timeout=0.3))[0] == "aborted"
    assert plan["cancelled"] == 1


def test_missing_server_times_out_as_aborted(rospy_node):
    from magna_msgs.msg import TakeOffAction

    from magna_sm.action_state import SimpleActionState
    state = SimpleActionState("/nobody/serves/this", TakeOffAction, server_wait_timeout=0.3)
    assert run(state)[0] == "aborted"


def test_goal_and_goal_key_together_are_refused():
    from magna_msgs.msg import TakeOffAction, TakeOffGoal

    from magna_sm.action_state import SimpleActionState
    with pytest.raises(ValueError, match="either goal or goal_key"):
        SimpleActionState("/x", TakeOffAction, goal=TakeOffGoal(), goal_key="g")
