"""The ground station's hold on simulated time during set-up, with a stand-in for /magna/sim/pause."""
from types import SimpleNamespace

from magna_gs import sim_pause
from magna_gs.sim_pause import SimulationPause


class PauseService:
    def __init__(self):
        self.calls = []

    def __call__(self, data):
        self.calls.append(data)
        return SimpleNamespace(success=True, message="paused" if data else "resumed")


class StandIn(SimulationPause):
    def __init__(self):
        super().__init__()
        self.service_proxy = PauseService()

    def _connect(self):
        return self.service_proxy


def test_setup_pauses_and_time_runs_only_when_needed():
    pause = StandIn()
    pause.stand_still()  # world_config
    pause.stand_still()  # spawn_agents: already paused, no second call
    with pause.time_needed():  # a wait: time runs
        pass
    pause.stand_still()  # the next setup state stops it again
    pause.run()  # an operator's command
    assert pause.service_proxy.calls == [True, False, True, False]


def test_no_setup_state_pauses_while_a_goal_needs_time():
    pause = StandIn()
    pause.stand_still()
    with pause.time_needed():  # a follow_path in a Concurrence ...
        pause.stand_still()  # ... beside a world_config: no pause, or the flight would freeze
        with pause.time_needed():
            pass
        pause.stand_still()
    pause.stand_still()  # both done: the setup state may pause again
    assert pause.service_proxy.calls == [True, False, True]


def test_the_wall_time_spent_standing_still_is_counted(monkeypatch):
    wall = {"now": 100.0}
    monkeypatch.setattr(sim_pause.time, "monotonic", lambda: wall["now"])
    pause = StandIn()
    pause.stand_still()
    wall["now"] += 2.5
    assert pause.still_wall_now() == 2.5  # the pause going on counts
    pause.run()
    wall["now"] += 10.0
    assert pause.still_wall == 2.5 and pause.still_wall_now() == 2.5
