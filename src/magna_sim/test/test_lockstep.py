"""The simulator's lockstep with the UAV managers, against a fake wall clock."""
import pytest

from magna_sim.pacing import Lockstep


class Wall:
    def __init__(self):
        self.now = 50.0

    def __call__(self):
        return self.now


def test_nobody_engaged_never_holds():
    assert not Lockstep(clock=Wall()).holds(123.0)


def test_holds_while_an_engaged_controller_is_more_than_the_lead_behind():
    wall = Wall()
    lockstep = Lockstep(lead=0.15, timeout=1.0, clock=wall)
    lockstep.heard(1, 2.0)
    lockstep.heard(2, 2.1)
    assert not lockstep.holds(2.15)  # both within the lead
    assert lockstep.holds(2.2)  # UAV 1 would be 0.2 s behind
    lockstep.heard(1, 2.1)
    assert not lockstep.holds(2.2)
    assert lockstep.holds(2.3) and lockstep.let_go == []


def test_a_released_controller_no_longer_holds():
    lockstep = Lockstep(clock=Wall())
    lockstep.heard(3, 1.0)
    assert lockstep.holds(5.0)
    lockstep.heard(3, -1.0)  # the manager went idle
    assert not lockstep.holds(5.0)
    lockstep.heard(3, 4.9)  # flying again
    assert not lockstep.holds(5.0) and lockstep.holds(5.1)
    lockstep.forget(3)  # the UAV was deleted
    assert not lockstep.holds(99.0)


def test_a_silent_controller_is_let_go_after_the_timeout_and_said_so():
    wall = Wall()
    lockstep = Lockstep(lead=0.1, timeout=1.0, clock=wall)
    lockstep.heard(4, 1.0)
    lockstep.heard(5, 1.0)
    wall.now += 0.5
    lockstep.heard(5, 1.05)
    assert lockstep.holds(1.2)
    wall.now += 0.6  # UAV 4 silent for 1.1 s, UAV 5 for 0.6 s
    assert lockstep.holds(1.2) and lockstep.let_go == [4]
    wall.now += 0.5
    assert not lockstep.holds(1.2) and lockstep.let_go == [4, 5]


@pytest.mark.parametrize("lead, timeout, field", [(0.0, 1.0, "~lockstep_lead"),
                                                  (0.1, float("nan"), "~lockstep_timeout")])
def test_bad_settings_name_the_parameter(lead, timeout, field):
    with pytest.raises(ValueError, match=field):
        Lockstep(lead=lead, timeout=timeout)
