"""Leaving a ROS node at once, once it has closed what it opened.

rospy's own shutdown (at exit) joins its threads: its XML-RPC server notices the end only at its
next half-second poll, then rospy sleeps another 0.1 s. A node that a batch starts for every
simulation (the ground station, a manager host) pays that each time. `leave_now` does what the
shutdown would tell the master, bounded, flushes the logs and ends the process.
"""
from __future__ import annotations

import logging
import os
import sys
import threading


def unregister_the_rest(timeout: float = 2.0) -> None:
    """Tell the master this node's remaining topics and services are gone (rospy's /rosout, /clock ...): what its
    shutdown would do, without the time it spends joining threads. Bounded: a master that does not answer
    within `timeout` s is left as a killed node would leave it."""
    import rosgraph
    import rospy
    from rospy.impl.registration import get_service_manager, get_topic_manager

    master, uri = rosgraph.Master(rospy.get_name()), rospy.core.get_node_uri()
    topics = get_topic_manager()

    def unregister() -> None:
        try:
            for name, _ in topics.get_subscriptions():
                master.unregisterSubscriber(name, uri)
            for name, _ in topics.get_publications():
                master.unregisterPublisher(name, uri)
            for name, service_uri in get_service_manager().get_services():
                master.unregisterService(name, service_uri)
        except Exception as error:  # noqa: BLE001 -- the master may be gone already; nothing left to tell it
            rospy.logdebug(f"{rospy.get_name()}: unregistering at exit: {error!r}")

    worker = threading.Thread(target=unregister, daemon=True, name="unregister at exit")
    worker.start()
    worker.join(timeout)


def flush_logs() -> None:
    """Flush every logging handler (the node's log file) without closing them: nothing is lost at os._exit."""
    for handler in list(logging._handlerList):  # type: ignore[attr-defined]  # what logging.shutdown walks
        target = handler()
        if target is not None:
            try:
                target.flush()
            except (OSError, ValueError):
                pass
    sys.stdout.flush()
    sys.stderr.flush()


def leave_now(status: int) -> None:
    """Unregister what is left from the master (if the node got that far), flush the logs, and end the process
    with `status`."""
    import rospy

    if rospy.core.is_initialized():
        unregister_the_rest()
    flush_logs()
    os._exit(status)
