"""simulation.bag: `rosbag record` in a process group of its own, and a way to know it is listening.

`rosbag record --regex` looks for new topics by asking the master about once a wall second, so
a topic that appears mid-mission (each UAV's pose and velocity appear when it is spawned) is
missed until then. The ground station asks `wait_listening` while simulated time stands still
after spawning, so the bag holds every pose from the take-off on. Listening means an inbound
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

import rosgraph
import rosgraph.names
import roslib.packages

from magna_gs.processes import TimeoutTransport, end_process_group

WATCHER = "/magna_bag_watcher"  # the caller id of our master and node queries


class BagRecorder:
    def __init__(self, path: Path, topics_regex: str, node_name: str | None = None):
        """Start recording the topics matching `topics_regex` into `path` (written as `path`.active until closed).

        The node is named so we can ask it what it listens to; the default name is unique per ground
        station process, since a second node of the same name would make the master shut the first down.
        """
        self.path = Path(path)
        node_name = node_name or f"magna_bag_{os.getpid()}"
        self.node = rosgraph.names.ns_join(rosgraph.names.get_ros_namespace(), node_name)
        found = roslib.packages.find_node("rosbag", "record")
        if not found:
            raise RuntimeError("rosbag's record executable was not found; install it: apt-get install rosbag")
        self.process = subprocess.Popen(
            [found[0], "--quiet", "-O", str(self.path), "--regex", topics_regex, f"__name:={node_name}"],
            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def listening_to(self) -> set[str]:
        """The topics the recorder has a publisher connection on now (empty while it is not up)."""
        try:
            uri = rosgraph.Master(WATCHER).lookupNode(self.node)
            code, _, links = xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(2.0)).getBusInfo(WATCHER)
        except (rosgraph.MasterException, OSError, xmlrpc.client.Error):
            return set()
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

        A recorder that died or had to be killed leaves `path`.active without an index; it is kept
        under that name (readers would refuse it as `path`) and the error says how to mend it.
        """
        early_exit = self.process.poll()
        end_process_group(self.process, grace=grace)
        active = self.path.with_name(self.path.name + ".active")
        if active.exists():
            why = (f"rosbag record ended by itself (exit code {early_exit})" if early_exit is not None
                   else f"rosbag did not close it within {grace:.0f} s")
            raise RuntimeError(f"{active} has no index: {why}. To read what it holds: `rosbag reindex {active}`, "
                               f"then rename it to {self.path.name}")
