"""The ground station's side of the UTM: the UAVs' current flight plans, and word to the UAV managers of a change.

The UTM node publishes every issued plan on /magna/utm/flight_plans. A plan newer than the
one known is stored with the simulated time it arrived, T, and T goes to the UAV's manager on
/magna/uav_{id}/utm_new_flightplan (std_msgs/Float64): the manager ends, with the outcome
utm_new_flightplan, a follow_path whose goal was sent at or before T, i.e. made before the
plan changed. A follow_path "from utm" is made from the stored plan and sent after T.
"""
from __future__ import annotations

import json
import threading
import time

import numpy as np
import rospy
from std_msgs.msg import Float64, String

from magna_common import ros_names as names


class UtmLink:
    def __init__(self, ids, wait: float = 10.0):
        self.wait = wait  # wall seconds for the UTM node's first word
        self.lock = threading.Lock()
        self.plans: dict[int, dict] = {}  # UAV id -> {"version", "waypoints", "changed_at"}
        self.last_paths: dict[int, np.ndarray] = {}  # what each UAV was last sent to fly
        self.warned: set[int] = set()
        self.heard = threading.Event()
        self.notify = {i: rospy.Publisher(names.manager(i, "utm_new_flightplan"), Float64, queue_size=1, latch=True)
                       for i in ids}
        self.subscriber = rospy.Subscriber(names.UTM_FLIGHT_PLANS, String, self._on_plans, queue_size=10)

    def _on_plans(self, msg: String) -> None:
        try:
            plans = json.loads(msg.data)["plans"]
        except (ValueError, KeyError, TypeError) as error:
            rospy.logerr(f"UTM: unreadable flight plans on {names.UTM_FLIGHT_PLANS}: {error}")
            return
        changed = []
        with self.lock:
            for key, plan in plans.items():
                uav_id = int(key)
                known = self.plans.get(uav_id)
                if known is not None and known["version"] >= plan["version"]:
                    continue
                now = rospy.get_time()
                self.plans[uav_id] = {"version": plan["version"], "changed_at": now,
                                      "waypoints": np.asarray(plan["waypoints"], dtype=float).reshape(-1, 3)}
                changed.append((uav_id, plan["version"], now))
        self.heard.set()
        for uav_id, version, now in changed:
            rospy.loginfo(f"UTM: UAV {uav_id} has a new flight plan (version {version}) at t = {now:.2f} s")
            if uav_id in self.notify:
                self.notify[uav_id].publish(Float64(now))

    def remember(self, uav_id: int, points) -> None:
        """A path the UAV was sent to fly of its own: what "from utm" flies while the UTM has no plan for it."""
        with self.lock:
            self.last_paths[uav_id] = np.asarray(points, dtype=float).reshape(-1, 3)

    def path_for(self, uav_id: int) -> np.ndarray:
        """The waypoints of the UAV's current plan, for a follow_path "from utm"; ValueError when there is none."""
        if not self.heard.wait(self.wait):
            raise ValueError(f"follow_path from utm: nothing from the UTM node on {names.UTM_FLIGHT_PLANS} within "
                             f"{self.wait:g} s; did it start (rosrun magna_gs utm)? See its log")
        with self.lock:
            plan, last = self.plans.get(uav_id), self.last_paths.get(uav_id)
        if plan is None:
            if last is None:
                raise ValueError(f"follow_path from utm: the UTM has issued no flight plan for UAV {uav_id} and the "
                                 f"UAV has flown no path yet; give one in the UTM plan (utm_plan:=FILE)")
            if uav_id not in self.warned:
                self.warned.add(uav_id)
                rospy.logwarn(f"follow_path from utm: no UTM flight plan for UAV {uav_id}; it flies its last path "
                              f"again")
            return last
        # Sent after the change, so the manager cannot take this goal for one made before it.
        deadline = time.monotonic() + 5.0
        while rospy.get_time() <= plan["changed_at"] and time.monotonic() < deadline and not rospy.is_shutdown():
            time.sleep(0.001)
        return plan["waypoints"]
