"""An operator command's goals get a bounded moment with their managers: one ended at once makes a refusal."""
import threading
import time
from types import SimpleNamespace

from actionlib_msgs.msg import GoalStatus

from magna_gs.command_goals import GRACE, CommandGoals, refusal_message

BOUND = 30.0  # wall s: far more than the stand-in managers take, so a settled wait never runs it out


class Client:
    """A SimpleActionClient whose server answers from a thread of its own, `delay` s after the goal: `script` is
    a list of ("feedback",) or ("done", status, message)."""

    def __init__(self, *script, delay=0.02):
        self.script, self.delay = script, delay

    def send_goal(self, goal, done_cb=None, active_cb=None, feedback_cb=None):
        def answer():
            for event in self.script:
                time.sleep(self.delay)
                if event[0] == "feedback":
                    feedback_cb(SimpleNamespace(percent_complete=0.0))
                else:
                    done_cb(event[1], SimpleNamespace(outcome="aborted", message=event[2]))

        threading.Thread(target=answer, daemon=True).start()


def settled(goals):
    """The refusals, once every goal settled: the wait must not have run out its (long) bound."""
    refused = goals.refusals()
    assert not goals.waited_out, "the answer waited for the bound though every goal had settled"
    return refused


def test_a_goal_aborted_at_once_is_a_refusal_with_the_managers_reason():
    goals = CommandGoals(bound=BOUND)
    reason = "basic_move: UAL refused: go_to_waypoint refused: UAV 1 is LANDING"
    goals.send(Client(("done", GoalStatus.ABORTED, reason)), object(), 1, "move")
    refused = settled(goals)
    assert [(w.uav_id, w.verb, w.reason) for w in refused] == [(1, "move", reason)]
    assert refusal_message(refused, []) == f"UAV 1 could not move: {reason}"


def test_a_goal_past_its_first_steps_is_taken_without_waiting_for_the_bound():
    goals = CommandGoals(bound=BOUND)
    goals.send(Client(("feedback",), ("feedback",)), object(), 2, "take off")
    goals.send(Client(("done", GoalStatus.SUCCEEDED, "already flying")), object(), 1, "take off")
    assert settled(goals) == []


def test_a_goal_ended_by_its_first_step_is_a_refusal_though_its_feedback_came_first():
    goals = CommandGoals(bound=BOUND)
    goals.send(Client(("feedback",), ("done", GoalStatus.ABORTED, "take_off: UAL refused: ..."), delay=0.05),
               object(), 1, "take off")
    assert [w.reason for w in settled(goals)] == ["take_off: UAL refused: ..."]


def test_a_goal_with_one_step_and_no_result_is_taken_after_its_grace_not_the_bound():
    goals = CommandGoals(bound=BOUND)
    goals.send(Client(("feedback",)), object(), 1, "take off")  # a take-off's later steps send no feedback
    start = time.monotonic()
    assert settled(goals) == []
    assert time.monotonic() - start >= GRACE  # it did give a result the grace to come (a lower bound: not luck)


def test_a_goal_with_no_news_counts_as_taken_once_the_bound_is_over():
    goals = CommandGoals(bound=0.3)
    goals.send(Client(), object(), 1, "land")  # a land goal sends no feedback
    goals.send(Client(("feedback",)), object(), 2, "move")  # one step: its result could still follow
    start = time.monotonic()
    assert goals.refusals() == [] and goals.waited_out
    assert time.monotonic() - start >= 0.3  # the whole bound (a lower bound: not luck)


def test_one_uav_of_several_ending_its_goal_names_it_and_what_still_goes_on():
    goals = CommandGoals(bound=BOUND)
    goals.send(Client(("feedback",), ("feedback",)), object(), 1, "move")
    goals.send(Client(("done", GoalStatus.REJECTED, "")), object(), 2, "move")
    refused = settled(goals)
    assert [w.uav_id for w in refused] == [2]
    assert refusal_message(refused, ["UAV 1 climbing to 5 m"]) == (
        "UAV 2 could not move: its manager ended the goal at once; still sent: UAV 1 climbing to 5 m")


def test_no_goals_no_wait():
    assert settled(CommandGoals(bound=BOUND)) == []
