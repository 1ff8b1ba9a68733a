"""Keeps magna_sim's time standing still while a mission sets up.

Starting a UAV manager takes a few wall seconds (a Python process importing rospy, numpy,
the mission); at rtf max an idle simulator turns them into minutes of simulated time in
which nothing happens, which then count in the mission's duration and flatter its
sim/wall factor, and it takes CPU from the processes starting. So the simulation launch
starts the simulator paused, the setup states (world_config, spawn_agents) pause it, and
it runs while something needs simulated time to pass: an action goal, a wait or saving
the CSVs (each holds `time_needed()` while it runs), an algorithm change, an operator's
command, the finishing sequence. Resuming only then (not at the end of each setup state)
keeps the idle simulator from racing ahead between two setup states: empty, it steps
hundreds of times faster than real time. A setup state never pauses while another state
needs time (a world_config beside flying UAVs in a Concurrence): that would freeze them.

Against another simulator (no /magna/sim/pause service) it warns once and does nothing.
"""
from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

import rospy
from std_srvs.srv import SetBool

from magna_common import ros_names as names


class SimulationPause:
    def __init__(self, service: str = names.SIM_PAUSE, wait: float = 30.0):
        self.service, self.wait = service, wait
        self._proxy = None
        self._missing = False
        self._paused: bool | None = None  # as last set here; None: not known (the launch decides)
        self._still_since: float | None = None
        self.still_wall = 0.0  # wall seconds the simulator stood still at our request
        self._needing = 0  # states running now that need simulated time to pass
        self._lock = threading.RLock()  # no pause slips in between a check and a resume

    def still_wall_now(self) -> float:
        """Wall seconds stood still so far, the current pause included."""
        ongoing = time.monotonic() - self._still_since if self._still_since is not None else 0.0
        return self.still_wall + ongoing

    def stand_still(self) -> None:
        """Pause, unless a state that needs time is running."""
        with self._lock:
            if not self._needing:
                self.set(True)

    def run(self) -> None:
        with self._lock:
            self.set(False)

    @contextlib.contextmanager
    def time_needed(self) -> Iterator[None]:
        """Time runs inside the block, and no setup state pauses it meanwhile."""
        with self._lock:
            self._needing += 1
            self.set(False)
        try:
            yield
        finally:
            with self._lock:
                self._needing -= 1

    def set(self, paused: bool) -> None:
        """Pause (True) or resume (False) the simulator, if it has the service; a repeat costs nothing."""
        with self._lock:
            if paused == self._paused:
                return
            proxy = self._connect()
            if proxy is None:
                return
            try:
                answer = proxy(data=paused)
            except rospy.ServiceException as error:  # the simulator went away: nothing left to pause
                rospy.logwarn(f"{self.service}: {error}")
                return
            self._paused = paused
            if paused:
                self._still_since = time.monotonic()
            elif self._still_since is not None:
                self.still_wall += time.monotonic() - self._still_since
                self._still_since = None
            rospy.logdebug(f"{self.service}: {answer.message}")

    def _connect(self):
        if self._proxy is None and not self._missing:
            try:
                rospy.wait_for_service(self.service, timeout=self.wait)
            except rospy.ROSException:
                self._missing = True
                rospy.logwarn(f"{self.service} did not come within {self.wait:g} s: the simulator cannot be "
                              f"paused, so simulated time runs on while UAVs are spawned")
                return None
            self._proxy = rospy.ServiceProxy(self.service, SetBool, persistent=False)
        return self._proxy
