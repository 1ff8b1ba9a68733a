"""The control loop's stepping clock without ROS: each step's simulated time is announced before the loop
sleeps, and the release once the loop stops stepping; flown by the real manager against simulated time."""
from magna_uav.config import configs_from_mission
from magna_uav.evaluator import Evaluator
from magna_uav.manager import UavManager
from magna_uav.nai.interface import NavigationInterface
from magna_uav.recorder import Recorder
from magna_uav.roles import TakeOffRole
from magna_uav.stepping_clock import RELEASED, SteppingClock
from magna_uav.world_view import WorldView

from .kinematic import KinematicUav, KinematicWorld


class SimulatedTime:
    """A simulator's clock that moves one control period per sleep, noting what it heard meanwhile."""

    def __init__(self, period: float = 0.1):
        self.t, self.period, self.heard = 0.0, period, []

    def now(self) -> float:
        return self.t

    def sleep(self) -> None:
        self.heard.append(("slept", self.t))
        self.t = round(self.t + self.period, 9)

    def announce(self, sim_time: float) -> None:
        self.heard.append(("announced", sim_time))


def test_each_step_is_announced_before_the_loop_sleeps():
    sim = SimulatedTime()
    clock = SteppingClock(sim.now, sim.sleep, sim.announce)
    for _ in range(3):
        clock.now()
        clock.sleep()
    assert sim.heard == [("announced", 0.0), ("slept", 0.0), ("announced", 0.1), ("slept", 0.1),
                         ("announced", 0.2), ("slept", 0.2)]
    assert clock.now() == clock.last == 0.3


def test_release_tells_the_simulator_the_loop_stopped_stepping():
    sim = SimulatedTime()
    clock = SteppingClock(sim.now, sim.sleep, sim.announce)
    clock.now()
    clock.release()
    assert sim.heard == [("announced", RELEASED)] and RELEASED < 0


def test_a_flown_role_announces_every_recorded_step_but_its_last():
    """The last step ends the role without sleeping: the node's release follows it."""
    (config,) = configs_from_mission([{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 1]}],
                                     "test")
    view = WorldView(1)
    uav = KinematicUav(1, [0, 0, 0], config.safety_radius, config.max_speed)
    world = KinematicWorld(view, [uav], dt=0.1)
    announced = []
    clock = SteppingClock(world.now, world.sleep, announced.append)
    recorder = Recorder(1, [])
    manager = UavManager(view, uav, NavigationInterface(config.max_speed, config.safety_radius),
                         Evaluator(config), recorder, clock.clock())
    result = manager.run_role(TakeOffRole(2.0))
    clock.release()
    assert result.outcome == "succeeded" and recorder.rows > 2
    step_times = [recorder.row(i)["time"] for i in range(recorder.rows)]
    assert announced == [*step_times[:-1], RELEASED]
    assert clock.last == step_times[-1]
