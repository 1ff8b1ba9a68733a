"""The node's order desk without ROS: goals queue for the state machine, the newest preempts the one
flying and those still waiting, each client gets its order's answer, and dying refuses what comes next."""
import threading

from magna_uav.manager import ABORTED, PREEMPTED, RoleResult
from magna_uav.order_desk import Order, OrderDesk
from tests.support import WAIT, wait_until


def test_a_goal_is_taken_by_the_machine_and_released_when_answered():
    desk, order = OrderDesk(), Order("take_off", {"height": 2.0})
    desk.submit(order)
    assert desk.take(timeout=WAIT) is order and desk.current is order
    assert not order.preempt_requested()
    desk.release(order)
    order.finish(RoleResult("succeeded", "up"))
    assert desk.current is None and order.done.is_set() and order.result.outcome == "succeeded"


def test_with_nothing_waiting_take_gives_nothing():
    assert OrderDesk().take(timeout=0.01) is None


def test_a_new_goal_preempts_the_role_flying():
    desk, flying, newer = OrderDesk(), Order("follow_path", None), Order("land", None)
    desk.submit(flying)
    desk.take(timeout=WAIT)
    desk.submit(newer)
    assert flying.preempt_requested() and not newer.preempt_requested()
    desk.release(flying)
    flying.finish(RoleResult(PREEMPTED, "follow_path preempted by the ground station"))
    assert desk.take(timeout=WAIT) is newer and desk.current is newer


def test_goals_that_were_replaced_before_they_started_are_answered_preempted():
    desk = OrderDesk()
    first, second, third = Order("take_off", None), Order("basic_move", None), Order("land", None)
    for order in (first, second, third):
        desk.submit(order)
    assert desk.take(timeout=WAIT) is third
    for replaced in (first, second):
        assert replaced.result.outcome == PREEMPTED
        assert replaced.result.message == f"{replaced.action} replaced by a newer goal before it started"


def test_a_goal_cancelled_by_its_client_is_preempted():
    cancelled = threading.Event()
    order = Order("follow_path", None, cancelled.is_set)
    assert not order.preempt_requested()
    cancelled.set()
    assert order.preempt_requested()


def test_dying_preempts_every_order_and_refuses_new_ones():
    desk, flying, waiting = OrderDesk(), Order("follow_path", None), Order("land", None)
    desk.submit(flying)
    desk.take(timeout=WAIT)
    desk.submit(waiting)
    desk.die()
    assert desk.dying and flying.preempt_requested() and waiting.preempt_requested()
    late = Order("take_off", None)
    desk.submit(late)
    assert late.result == RoleResult(ABORTED, "the UAV manager is shutting down")


def test_die_wakes_a_machine_waiting_for_a_goal():
    desk, taken = OrderDesk(), []
    machine = threading.Thread(target=lambda: taken.append(desk.take(timeout=WAIT)))
    machine.start()
    desk.die()
    machine.join(WAIT)
    assert not machine.is_alive() and taken == [None] and desk.dying


def test_each_client_gets_its_order_answered_by_the_machine():
    """Two action-server threads and the machine: the second goal preempts the first while it flies."""
    desk = OrderDesk()

    def machine():
        for _ in range(2):
            order = desk.take(timeout=WAIT)
            while not order.preempt_requested() and order.action == "follow_path":
                order.preempt.wait(0.01)  # flying until a newer goal comes
            outcome = PREEMPTED if order.preempt_requested() else "succeeded"
            desk.release(order)
            order.finish(RoleResult(outcome, order.action))

    answers = {}

    def client(order):
        desk.submit(order)
        answers[order.action] = order.wait(shutting_down=lambda: False)

    flying, landing = Order("follow_path", None), Order("land", None)
    threads = [threading.Thread(target=machine), threading.Thread(target=client, args=(flying,))]
    for thread in threads:
        thread.start()
    wait_until(lambda: desk.current is flying, "the machine to fly the path")
    threads.append(threading.Thread(target=client, args=(landing,)))
    threads[-1].start()
    for thread in threads:
        thread.join(WAIT)
    assert answers == {"follow_path": RoleResult(PREEMPTED, "follow_path"), "land": RoleResult("succeeded", "land")}
    assert desk.current is None


def test_a_client_waiting_while_the_node_shuts_down_gets_aborted():
    order = Order("take_off", None)
    assert order.wait(shutting_down=lambda: True, poll=0.001) == RoleResult(ABORTED, "the node is shutting down")
