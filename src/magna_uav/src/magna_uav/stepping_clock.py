"""The control loop's clock: steps on the shared tick grid, each announced to the simulator (its lockstep).

Steps fall on the ticks k / control_rate of simulated time (after a role's first step, which runs
when the role begins): every manager of a simulation steps at the same instants, whatever time
its role began, so the managers of one process can solve ORCA-3D together at each tick
(nai.orca_batch) and the simulator's lockstep waits on one instant per tick, not one per UAV.
`tick` is the index of the tick the current step was slept to; None for a role's first step.

While a role flies, every step's simulated time is announced (the node publishes it on
/magna/uav_{id}/control_step, std_msgs/Float64) before the loop sleeps; `release()` announces
RELEASED when the loop stops stepping (idle hovers on a held setpoint and needs no pacing).
magna_sim then never runs more than its ~lockstep_lead ahead of a manager that is flying, however
loaded the machine. Nothing listens on a real UAV, and the announcement costs one small message.
No ROS here: the node passes the time source, a wait until a simulated time, and the publisher.
"""
from __future__ import annotations

import math
from collections.abc import Callable

from magna_uav.manager import Clock

RELEASED = -1.0  # announced when the loop stops stepping: the simulator need not wait for this UAV

# A time this close to a tick (in periods) is on it: clock values are floats of whole nanoseconds.
_ON_TICK = 1e-6


def next_tick(sim_time: float, period: float) -> int:
    """The index of the first tick (k * period) strictly after `sim_time`."""
    return math.floor(sim_time / period + _ON_TICK) + 1


class SteppingClock:
    def __init__(self, time_now: Callable[[], float], wait_until: Callable[[float], None],
                 announce: Callable[[float], None], period: float):
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"SteppingClock period is {period!r}: give 1 / control_rate, a positive number of "
                             "simulated seconds")
        self._time_now, self._wait_until, self._announce = time_now, wait_until, announce
        self.period = float(period)
        self.last = RELEASED  # the simulated time of the latest step
        self.tick: int | None = None  # the tick the current step was slept to; None for a role's first step

    @property
    def tick_key(self) -> tuple[float, int] | None:
        """(period, tick) of the current step, equal for every clock stepping at this instant with this period;
        None for a role's first step."""
        return None if self.tick is None else (self.period, self.tick)

    def now(self) -> float:
        self.last = self._time_now()
        return self.last

    def sleep(self) -> None:
        """Until the next tick after the latest step (at once when that tick has passed already)."""
        self._announce(self.last)
        tick = next_tick(self.last, self.period)
        self._wait_until((tick - _ON_TICK) * self.period)  # a tick's clock value may be a nanosecond short
        self.tick = tick

    def release(self) -> None:
        self._announce(RELEASED)
        self.tick = None

    def clock(self) -> Clock:
        """The manager's view of this clock."""
        return Clock(self.now, self.sleep)
