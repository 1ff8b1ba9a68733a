"""TimeAlarms: each waiter rings at its instant, not at every change of the time."""
import threading

from magna_uav.time_alarms import TimeAlarms


class Time:
    def __init__(self, now=0.0):
        self.now = now

    def __call__(self):
        return self.now


def test_an_instant_already_reached_needs_no_alarm():
    alarms = TimeAlarms(Time(2.0))
    assert alarms.set(2.0) is None and alarms.set(1.5) is None and alarms.waiting == 0


def test_each_alarm_rings_when_its_instant_comes_and_not_before():
    time = Time(0.0)
    alarms = TimeAlarms(time)
    tick_1, tick_2, also_1 = alarms.set(0.1), alarms.set(0.2), alarms.set(0.1)
    for now in (0.01, 0.05, 0.09):  # /clock messages between the ticks wake nobody
        time.now = now
        assert alarms.ring_due() == 0
    assert not tick_1.wait(0) and not also_1.wait(0)
    time.now = 0.1
    assert alarms.ring_due() == 2
    assert tick_1.wait(0) and also_1.wait(0) and not tick_2.wait(0) and alarms.waiting == 1
    time.now = 0.35  # a jump past an instant rings it too
    assert alarms.ring_due() == 1 and tick_2.wait(0) and alarms.waiting == 0


def test_time_going_back_rings_every_alarm_so_each_waiter_can_tell():
    time = Time(5.0)
    alarms = TimeAlarms(time)
    alarms.ring_due()
    far, farther = alarms.set(9.0), alarms.set(12.0)
    time.now = 0.0  # a reset
    assert alarms.ring_due() == 2 and far.wait(0) and farther.wait(0)
    again = alarms.set(0.1)  # set after the reset: rings on the new time line
    time.now = 0.05
    assert alarms.ring_due() == 0 and not again.wait(0)


def test_a_waiting_thread_wakes_when_its_instant_is_rung():
    time = Time(0.0)
    alarms = TimeAlarms(time)
    alarm = alarms.set(1.0)
    woke = threading.Event()
    thread = threading.Thread(target=lambda: alarm.wait(30) and woke.set())
    thread.start()
    time.now = 1.0
    alarms.ring_due()
    thread.join(30)
    assert woke.is_set()
