"""The control loop's clock, announcing each control step to the simulator (its lockstep).

While a role flies, every step's simulated time is announced (the node publishes it on
/magna/uav_{id}/control_step, std_msgs/Float64) before the loop sleeps; `release()` announces
RELEASED when the loop stops stepping (idle hovers on a held setpoint and needs no pacing).
magna_sim then never runs more than its ~lockstep_lead ahead of a manager that is flying, however
loaded the machine. Nothing listens on a real UAV, and the announcement costs one small message.
No ROS here: the node passes the time source, the sleep of one control period and the publisher.
"""
from __future__ import annotations

from collections.abc import Callable

from magna_uav.manager import Clock

RELEASED = -1.0  # announced when the loop stops stepping: the simulator need not wait for this UAV


class SteppingClock:
    def __init__(self, time_now: Callable[[], float], sleep_period: Callable[[], None],
                 announce: Callable[[float], None]):
        self._time_now, self._sleep_period, self._announce = time_now, sleep_period, announce
        self.last = RELEASED  # the simulated time of the latest step

    def now(self) -> float:
        self.last = self._time_now()
        return self.last

    def sleep(self) -> None:
        self._announce(self.last)
        self._sleep_period()

    def release(self) -> None:
        self._announce(RELEASED)

    def clock(self) -> Clock:
        """The manager's view of this clock."""
        return Clock(self.now, self.sleep)
