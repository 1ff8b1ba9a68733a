"""The UAL's arrival rule that magna_sim and ual_mavlink share."""
from magna_common.ual_arrival import Arrival


def test_arrival_needs_the_hold_and_gives_up_without_progress():
    arrival = Arrival((0, 0, 2), yaw=0.0, now=0.0, hold_time=1.0, stuck_time=5.0)
    arrival.update((0, 0, 1.9), 0.0, now=0.0)
    arrival.update((0, 0, 1.9), 0.0, now=0.9)
    assert not arrival.arrived
    arrival.update((0, 0, 1.7), 0.0, now=1.0)  # out of the 0.165 m radius: the hold starts again
    arrival.update((0, 0, 1.95), 0.0, now=1.1)
    arrival.update((0, 0, 1.95), 0.5, now=2.0)  # heading off by more than 0.325 rad: not there
    arrival.update((0, 0, 1.95), 0.1, now=2.1)
    arrival.update((0, 0, 1.95), 0.1, now=3.1)
    assert arrival.arrived
    stuck = Arrival((5, 0, 2), yaw=None, now=0.0, stuck_time=5.0)
    for now in range(7):
        stuck.update((0, 0, 2), 0.0, now=float(now))
    assert stuck.stuck.startswith("at (0.00, 0.00, 2.00), 5.00 m from (5.00, 0.00, 2.00), and has come no nearer in "
                                  "5 s")


def test_the_stuck_reason_names_the_clock_it_was_measured_on():
    stuck = Arrival((0, 0, 3), yaw=None, now=0.0, radius=0.1, stuck_time=2.0, time_unit="s of simulated time")
    for now in (0.0, 1.0, 2.5):
        stuck.update((0, 0, 1), 1.0, now=now)
    assert stuck.stuck == ("at (0.00, 0.00, 1.00), 2.00 m from (0.00, 0.00, 3.00), and has come no nearer in 2 s of "
                           "simulated time (nearest 2.00 m; arrival needs 0.1 m)")
