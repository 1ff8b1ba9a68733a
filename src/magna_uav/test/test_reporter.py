"""The reporter without ROS: what reaches the ground station's state_actualization service, in order,
without the control loop waiting; refusals warned about, a missing ground station tolerated."""
import threading
from types import SimpleNamespace

from magna_uav.reporter import Reporter
from tests.support import WAIT, wait_until


class GroundStationDown(Exception):
    pass


class FakeGroundStation:
    """The state_actualization service: records each request; may refuse, be absent, or be slow."""

    def __init__(self):
        self.requests, self.refuse, self.absent = [], set(), False
        self.open = threading.Event()
        self.open.set()

    def call(self, **request):
        self.open.wait(WAIT)
        if self.absent:
            raise GroundStationDown
        self.requests.append(request)
        refused = request["state"] in self.refuse
        return SimpleNamespace(success=not refused, message=f"no {request['state']} here" if refused else "")


def reporter_for(station, running=lambda: True, **logs):
    return Reporter(3, station.call, running, unreachable=(GroundStationDown,), poll=0.01, **logs)


def test_the_states_reach_the_ground_station_in_order_with_their_events():
    station = FakeGroundStation()
    reporter = reporter_for(station)
    for state, event in (("idle", ""), ("take_off", ""), ("take_off_collision", "collision"), ("idle", "")):
        reporter.report(state, event)
    wait_until(lambda: len(station.requests) == 4, "four reports")
    assert station.requests == [{"id": 3, "state": "idle", "critical_event": ""},
                                {"id": 3, "state": "take_off", "critical_event": ""},
                                {"id": 3, "state": "take_off_collision", "critical_event": "collision"},
                                {"id": 3, "state": "idle", "critical_event": ""}]


def test_reporting_never_waits_for_the_ground_station():
    station = FakeGroundStation()
    station.open.clear()  # the service hangs
    reporter = reporter_for(station)
    for state in ("idle", "follow_path", "follow_path_succeeded"):
        reporter.report(state)  # returns at once, though nothing has been answered
    assert station.requests == []
    station.open.set()
    wait_until(lambda: len(station.requests) == 3, "the queued reports")
    assert [r["state"] for r in station.requests] == ["idle", "follow_path", "follow_path_succeeded"]


def test_a_refused_state_is_warned_about_and_the_next_still_sent():
    station, warnings = FakeGroundStation(), []
    station.refuse = {"land"}
    reporter = reporter_for(station, warn=warnings.append)
    reporter.report("land")
    reporter.report("idle")
    wait_until(lambda: len(station.requests) == 2, "both reports")
    assert warnings == ["ground station refused the state of UAV 3: no land here"]


def test_without_a_ground_station_reports_are_dropped_quietly():
    station, said = FakeGroundStation(), []
    station.absent = True
    reporter = reporter_for(station, warn=said.append, debug=said.append)
    reporter.report("idle")
    wait_until(lambda: said, "the dropped report")
    station.absent = False
    reporter.report("take_off")
    wait_until(lambda: station.requests, "the report once a ground station serves")
    assert said == ["no ground station to report 'idle' to"]
    assert station.requests == [{"id": 3, "state": "take_off", "critical_event": ""}]


def test_the_sending_thread_ends_with_the_node():
    running = threading.Event()
    running.set()
    reporter = reporter_for(FakeGroundStation(), running=running.is_set)
    running.clear()
    reporter._thread.join(WAIT)
    assert not reporter._thread.is_alive()
