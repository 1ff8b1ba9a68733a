"""Publishers for the simulator's high-rate streams (UAL topics, /clock, /tf).

rospy gives every subscriber connection of a publisher made with a queue_size a writer
thread of its own. With N UAVs each UAV manager listens to the pose and velocity of every
UAV, so the simulator ends up with N * N * 2 such threads plus one per node on /clock; at
rtf max they fight the simulation loop for the GIL, and the loop, not the physics, sets
the pace (10 UAVs: most of the simulator's samples were thread hand-overs). A publisher
without a queue writes to every connection's socket from the simulation loop itself: one
send() per subscriber, no hand-over. A subscriber that stops reading would block the loop
once its socket buffer (hundreds of kB on loopback) is full; rospy subscribers read in a
thread of their own whatever their queue size, and a dead one closes its socket.
"""
from __future__ import annotations

import warnings

import rospy


def stream_publisher(topic: str, msg_type, **kwargs) -> rospy.Publisher:
    """A rospy Publisher that writes in the caller's thread (queue_size=None, said on purpose)."""
    with warnings.catch_warnings():
        # rospy warns about a missing queue_size whether or not it was left out deliberately
        warnings.simplefilter("ignore")
        return rospy.Publisher(topic, msg_type, queue_size=None, **kwargs)
