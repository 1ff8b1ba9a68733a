"""simulation.bag: `rosbag record` in a process group of its own, and a way to know it is listening.

The recorder is given every topic by name (`mission_topics`), known from the mission's UAV ids,
not a `--regex`: with a regex, rosbag looks for new topics on a timer of simulated time, so
while time stands still it finds none, and after that it misses up to a simulated second of
each UAV. A named topic is subscribed at start, and the master tells the recorder the moment
a publisher appears. The ground station asks `wait_listening` while time stands still after
spawning, so the bag holds every pose from the take-off on. Listening means an inbound
connection in the recorder's own bus info (the node's `getBusInfo`), not only a subscription
the master knows of: messages sent before the connection is made are lost.

The recorder is rosbag's `record` executable itself, not the `rosbag record` script: the script
runs it as a child and exits on SIGINT without waiting for it, so whoever stops the script
cannot know when the bag is written and may take a file that has no index yet.
"""
from __future__ import annotations

import os
import subprocess
import time
import xmlrpc.client
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import rosgraph
import rosgraph.names
import roslib.packages

from magna_common import ros_names as names
from magna_common.processes import TimeoutTransport, end_process_group

WATCHER = "/magna_bag_watcher"  # the caller id of our master and node queries
# The UAL pose and velocity and the managers' navigation steps let mlr rebuild every recorded
# control step from the bag (mlr.bags), e.g. for flights whose CSVs are lost or never written.
# A hil or real UAV's bridge says there when its MAVLink link is lost and found again.
WORLD_TOPICS = ("/tf", "/tf_static", names.WORLD_MARKERS, names.sm_topic("mission", "structure"),
                names.sm_topic("mission", "status"), names.GS_CRITICAL_EVENT, names.UTM_FLIGHT_PLANS)


def uav_topics(uav_id: int) -> list[str]:
    """What simulation.bag holds of one UAV."""
    return [names.ual(uav_id, "pose"), names.ual(uav_id, "velocity"),
            *(names.manager(uav_id, topic) for topic in ("navigation", "path/raw", "path/smoothed", "goal")),
            names.utm_flight_plan(uav_id), names.mavlink_link(uav_id)]


def mission_topics(uav_ids: Iterable[int]) -> list[str]:
    """What simulation.bag holds for a mission of these UAVs."""
    return [*WORLD_TOPICS, *(topic for i in uav_ids for topic in uav_topics(i))]


class BagRecorder:
    def __init__(self, path: Path, topics: Iterable[str], node_name: str | None = None):
        """Start recording `topics` into `path` (written as `path`.active until closed).

        The node is named so we can ask it what it listens to; the default name is unique per ground
        station process, since a second node of the same name would make the master shut the first down.
        """
        self.path = Path(path)
        node_name = node_name or f"magna_bag_{os.getpid()}"
        self.node = rosgraph.names.ns_join(rosgraph.names.get_ros_namespace(), node_name)
        found = roslib.packages.find_node("rosbag", "record")
        if not found:
            raise RuntimeError("rosbag's record executable was not found; install it: apt-get install python3-rosbag")
        self.process = subprocess.Popen(
            [found[0], "--quiet", "-O", str(self.path), *topics, f"__name:={node_name}"],
            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def listening_to(self) -> set[str]:
        """The topics the recorder has a publisher connection on now (empty while it is not up)."""
        try:
            uri = rosgraph.Master(WATCHER).lookupNode(self.node)
            # XML-RPC answers are untyped: the node API answers [code, status message, rows]
            answer: Any = xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(2.0)).getBusInfo(WATCHER)
        except (rosgraph.MasterException, OSError, xmlrpc.client.Error):
            return set()
        code, _, links = answer
        # a row: connection id, the other end, direction ("i": inbound), transport, topic[, connected]
        return {row[4] for row in links if row[2] == "i" and (len(row) < 6 or row[5])} if code == 1 else set()

    def wait_listening(self, topics: Iterable[str], timeout: float, poll: float = 0.05) -> list[str]:
        """Wait (wall time) until the recorder is connected to each topic; return those it still is not."""
        wanted = list(topics)
        deadline = time.monotonic() + timeout
        while True:
            listening = self.listening_to() if wanted else set()
            missing = [t for t in wanted if t not in listening]
            if not missing or self.process.poll() is not None or time.monotonic() >= deadline:
                return missing
            time.sleep(poll)

    def close(self, grace: float = 10.0) -> None:
        """Stop recording: on SIGINT rosbag writes the index and renames the file from .active.

        A recorder that died or had to be killed leaves `path`.active without an index, or nothing;
        the file is kept under that name (readers would refuse it as `path`) and the error says so.
        """
        early_exit = self.process.poll()
        end_process_group(self.process, grace=grace)
        why = (f"rosbag record ended by itself (exit code {early_exit})" if early_exit is not None
               else f"rosbag did not close it within {grace:.0f} s")
        active = self.path.with_name(self.path.name + ".active")
        if active.exists():
            raise RuntimeError(f"{active} has no index: {why}. To read what it holds: `rosbag reindex {active}`, "
                               f"then rename it to {self.path.name}")
        if early_exit is not None and not self.path.exists():
            raise RuntimeError(f"no {self.path.name} was written: {why}")
