"""The control loop's stepping clock without ROS: each step's simulated time is announced before the loop
sleeps, and the release once the loop stops stepping; flown by the real manager against simulated time."""
import math

import pytest

from magna_uav.config import configs_from_mission
from magna_uav.evaluator import Evaluator
from magna_uav.manager import UavManager
from magna_uav.nai.interface import NavigationInterface
from magna_uav.recorder import Recorder
from magna_uav.roles import TakeOffRole
from magna_uav.stepping_clock import RELEASED, SteppingClock, next_tick
from magna_uav.world_view import WorldView

from .kinematic import KinematicUav, KinematicWorld


class SimulatedTime:
    """A simulator's clock published at 240 Hz (as magna_sim's /clock values fall): a wait ends on the first
    value at or after its target. Notes what it heard meanwhile."""

    RATE = 240

    def __init__(self, t: float = 0.0):
        self.t, self.heard = t, []

    def now(self) -> float:
        return self.t

    def wait_until(self, target: float) -> None:
        self.heard.append(("slept", self.t))
        self.t = max(self.t, math.ceil(round(target * self.RATE, 6)) / self.RATE)

    def announce(self, sim_time: float) -> None:
        self.heard.append(("announced", sim_time))


def test_each_step_is_announced_before_the_loop_sleeps():
    sim = SimulatedTime()
    clock = SteppingClock(sim.now, sim.wait_until, sim.announce, 0.1)
    for _ in range(3):
        clock.now()
        clock.sleep()
    assert sim.heard == [("announced", 0.0), ("slept", 0.0), ("announced", 0.1), ("slept", 0.1),
                         ("announced", 0.2), ("slept", 0.2)]
    assert clock.now() == clock.last == 0.3


def test_release_tells_the_simulator_the_loop_stopped_stepping():
    sim = SimulatedTime()
    clock = SteppingClock(sim.now, sim.wait_until, sim.announce, 0.1)
    clock.now()
    clock.sleep()
    assert clock.tick_key == (0.1, 1)
    clock.release()
    assert sim.heard[-1] == ("announced", RELEASED) and RELEASED < 0
    assert clock.tick is None and clock.tick_key is None, "the next role's first step is on no shared tick"


def test_clocks_started_at_different_times_step_at_the_same_ticks():
    """Two managers whose roles began 37.5 ms apart: after each first step both step at k / rate, with the
    same tick keys and clock values, as the managers of a host must to solve ORCA-3D together."""
    steps = {}
    for began in (1.0125, 1.05):
        sim = SimulatedTime(began)
        clock = SteppingClock(sim.now, sim.wait_until, sim.announce, 0.1)
        seen = []
        for _ in range(4):
            seen.append((clock.now(), clock.tick_key))
            clock.sleep()
        steps[began] = seen
    first, second = steps.values()
    assert first[0] == (1.0125, None) and second[0] == (1.05, None), "a role's first step runs when it begins"
    assert first[1:] == second[1:]
    assert [key for _, key in first[1:]] == [(0.1, 11), (0.1, 12), (0.1, 13)]
    for (t, _), k in zip(first[1:], (11, 12, 13), strict=True):
        assert -1e-9 <= t - k * 0.1 < 1 / SimulatedTime.RATE, f"step at {t} is on tick {k}'s first clock value"


def test_a_step_past_its_next_tick_does_not_wait_and_takes_the_tick_after_it():
    sim = SimulatedTime()
    clock = SteppingClock(sim.now, sim.wait_until, sim.announce, 0.1)
    clock.now()
    sim.t = 0.25  # the simulator ran on during the step (within its lockstep lead)
    clock.sleep()
    assert clock.now() == 0.25 and clock.tick == 1, "tick 1 (0.1 s) has passed: no wait"
    clock.sleep()
    assert clock.tick == 3 and 0.3 <= clock.now() < 0.3 + 1 / SimulatedTime.RATE


def test_next_tick_takes_a_clock_value_a_nanosecond_off_a_tick_as_on_it():
    assert next_tick(0.29999999999, 0.1) == 4 and next_tick(0.30000000000000004, 0.1) == 4
    assert next_tick(0.2999, 0.1) == 3 and next_tick(0.0, 0.1) == 1
    with pytest.raises(ValueError, match="period"):
        SteppingClock(lambda: 0.0, lambda t: None, lambda t: None, 0.0)


def test_a_flown_role_announces_every_recorded_step_but_its_last():
    """The last step ends the role without sleeping: the node's release follows it."""
    (config,) = configs_from_mission([{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 1]}],
                                     "test")
    view = WorldView(1)
    uav = KinematicUav(1, [0, 0, 0], config.safety_radius, config.max_speed)
    world = KinematicWorld(view, [uav], dt=0.1)
    announced = []
    clock = SteppingClock(world.now, lambda target: world.sleep(), announced.append, world.dt)  # one dt per tick
    recorder = Recorder(1, [])
    manager = UavManager(view, uav, NavigationInterface(config.max_speed, config.safety_radius),
                         Evaluator(config), recorder, clock.clock())
    result = manager.run_role(TakeOffRole(2.0))
    clock.release()
    assert result.outcome == "succeeded" and recorder.rows > 2
    step_times = [recorder.row(i)["time"] for i in range(recorder.rows)]
    assert announced == [*step_times[:-1], RELEASED]
    assert clock.last == step_times[-1]
