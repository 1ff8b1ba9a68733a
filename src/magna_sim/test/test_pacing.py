"""Real-time factor parsing and pacing, against a fake clock."""
import math

import pytest

from magna_sim.pacing import Hold, Pacer, parse_real_time_factor


@pytest.mark.parametrize("value, expected", [(1.0, 1.0), ("10", 10.0), ("max", math.inf), (0, math.inf),
                                             ("inf", math.inf), ("0.5", 0.5)])
def test_parse(value, expected):
    assert parse_real_time_factor(value) == expected


@pytest.mark.parametrize("bad", ["fast-ish", -1, "nan"])
def test_parse_refuses_nonsense(bad):
    with pytest.raises(ValueError, match="real_time_factor"):
        parse_real_time_factor(bad)


class FakeClock:
    def __init__(self):
        self.now, self.slept = 100.0, []

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        self.slept.append(seconds)
        self.now += seconds


def test_pacer_sleeps_sim_time_over_factor():
    clock = FakeClock()
    pacer = Pacer(4.0, clock=clock, sleep=clock.sleep)
    pacer.wait(0.0)
    pacer.wait(1.0)  # 1 s of sim at 4x is due 0.25 s of wall after start
    assert clock.now == pytest.approx(100.25)
    clock.now += 1.0  # the loop fell behind by less than the lag limit? no: far behind
    pacer.wait(2.0)
    assert clock.slept == [pytest.approx(0.25)]  # no catch-up sprint and no extra sleep


def test_as_fast_as_possible_never_sleeps():
    clock = FakeClock()
    pacer = Pacer(math.inf, clock=clock, sleep=clock.sleep)
    for t in range(100):
        pacer.wait(t)
    assert clock.slept == []


def test_restart_forgets_the_time_spent_paused():
    clock = FakeClock()
    pacer = Pacer(2.0, clock=clock, sleep=clock.sleep)
    pacer.wait(0.0)
    clock.now += 0.3  # a pause shorter than the lag limit: without restart the loop would sprint
    pacer.restart()
    pacer.wait(0.0)
    pacer.wait(1.0)  # 1 s of sim at 2x: 0.5 s of wall after the restart
    assert clock.slept == [pytest.approx(0.5)]


def test_hold_counts_changes_and_says_what_happened():
    hold = Hold(paused=True)
    assert hold.paused and hold.changes == 0
    assert hold.set(True, 1.0) == "already paused at t=1.000 s" and hold.changes == 0
    assert hold.set(False, 1.0) == "resumed at t=1.000 s" and not hold.paused and hold.changes == 1
    assert hold.set(True, 2.5) == "paused at t=2.500 s" and hold.paused and hold.changes == 2
