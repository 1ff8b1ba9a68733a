"""magna_mavlink's tests: the scripted autopilot (fake_autopilot.py) and a running backend on the wall clock."""
import sys
import threading
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # fake_autopilot: test folders are not packages

from fake_autopilot import FakeAutopilot  # noqa: E402

from magna_common.ports import free_port  # noqa: E402
from magna_mavlink import autopilot as ap  # noqa: E402
from magna_mavlink.backend import Settings, UalBackend  # noqa: E402
from magna_mavlink.commands import Commander  # noqa: E402
from magna_mavlink.link import MavlinkLink  # noqa: E402
from magna_mavlink.vehicle_state import VehicleState  # noqa: E402

# Short times so the tests take seconds; the rules are the node's. The heartbeat timeout leaves room for a
# loaded machine: the scripted autopilot shares this process (and its GIL) with the backend.
FAST = dict(hold_pose_time=0.3, take_off_speed=2.0, heartbeat_timeout=1.0, arm_retry=0.3, mode_timeout=3.0,
            stuck_time=10.0)


class Flight:
    """A FakeAutopilot, ual_mavlink's link and backend to it, and the backend's tick at 30 Hz of wall time."""

    def __init__(self, autopilot=ap.PX4, arming="auto", system_id=3, origin_geo=None, **settings):
        port = free_port(udp=True)
        self.url = f"udpin:127.0.0.1:{port}"
        self.fake = FakeAutopilot(f"udpout:127.0.0.1:{port}", system_id=system_id, autopilot=autopilot).start()
        self.vehicle = VehicleState(origin_geo)
        self.link = MavlinkLink(self.url, system_id, on_message=lambda msg: self.vehicle.update(msg, time.monotonic()))
        self.link.open()
        self.link.wait_for_vehicle(10.0)
        self.backend = UalBackend(self.vehicle, Commander(self.link, autopilot),
                                  Settings(uav_id=system_id, arming=arming, **{**FAST, **settings}), self.url)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self):
        while not self._stop.is_set():
            self.backend.tick(time.monotonic())
            self._stop.wait(1.0 / 30.0)

    def close(self):
        self._stop.set()
        self._thread.join(timeout=5)
        self.backend.close()
        self.link.close()
        self.fake.stop()


@pytest.fixture
def flight():
    """Start flights with flight(**options); all are ended after the test."""
    started = []

    def start(**options):
        started.append(Flight(**options))
        return started[-1]

    yield start
    for one in started:
        one.close()
