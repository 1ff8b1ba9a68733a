"""The one reader of a simulation's bag (`simulation.bag`): replay, the reports and mlr all read it here.

The ground station bags the runtime contract's topics (magna_common.ros_names); this reader sorts
their messages by kind, each kind a fixed set of topics:

    pose, velocity          /uav_{id}/ual/{kind}                 (UAL_TOPIC_PATTERN; owner: the UAV id)
    navigation, goal,       /magna/uav_{id}/{kind}               (MANAGER_TOPIC_PATTERN; owner: the UAV id)
    path/raw, path/smoothed
    status, structure       /magna/sm/{machine}/{kind}           (SM_TOPIC_PATTERN; owner: the machine)
    markers                 /magna/world/markers                 (WORLD_MARKERS; no owner)

Every message keeps when it happened: its header's stamp, or, unstamped (a zero stamp or no header),
when the bag got it, as magna_uav.ros_data counts them. Times are integer nanoseconds of the
simulation's clock (the bag starts near 0).

rosbags (pure Python) does the reading: `AnyReader` takes the message definitions from the bag itself,
so neither ROS nor magna_msgs need be installed. It is imported only when a bag is read.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from magna_common.errors import UserError
from magna_common.ros_names import MANAGER_TOPIC_PATTERN, SM_TOPIC_PATTERN, UAL_TOPIC_PATTERN, WORLD_MARKERS

UAL_KINDS = ("pose", "velocity")
MANAGER_KINDS = ("navigation", "goal", "path/raw", "path/smoothed")
SM_KINDS = ("status", "structure")
MARKERS = "markers"
KINDS = (*UAL_KINDS, *MANAGER_KINDS, *SM_KINDS, MARKERS)

_UAL = re.compile(UAL_TOPIC_PATTERN)
_MANAGER = re.compile(MANAGER_TOPIC_PATTERN)
_SM = re.compile(SM_TOPIC_PATTERN)


class BagError(UserError):
    """The file is not a bag rosbags can read (missing, truncated, not a bag); the message names it."""

    def __init__(self, path: Path, reason: str):
        super().__init__(f"{path}: not a readable ROS bag ({reason})")
        self.path = path
        self.reason = reason


def topic_kind(topic: str) -> tuple[str, int | str | None] | None:
    """(kind, owner) of one of the bagged topics of the module docstring; None for any other topic."""
    if match := _UAL.fullmatch(topic):
        return match.group(2), int(match.group(1))
    if match := _MANAGER.fullmatch(topic):
        return match.group(2), int(match.group(1))
    if match := _SM.fullmatch(topic):
        return match.group(2), match.group(1)
    if topic == WORLD_MARKERS:
        return MARKERS, None
    return None


@dataclass(frozen=True)
class BagMessage:
    kind: str
    owner: int | str | None  # the UAV id, the state machine's name, or None (markers)
    stamp: int  # ns: the header's stamp, or the log time when unstamped
    log_time: int  # ns: when the bag got it
    msg: Any  # the message as rosbags deserializes it: the fields and values of the ROS message

    @property
    def time(self) -> float:
        """The stamp in seconds."""
        return self.stamp / 1e9


@dataclass
class SimulationBag:
    path: Path
    start: int  # ns: the first and last log time; 0 for a bag without messages
    end: int
    message_count: int
    topics: tuple[str, ...]  # every topic of the bag, read or not
    messages: dict[str, list[BagMessage]] = field(default_factory=dict)  # by kind, each in the bag's order

    @property
    def duration(self) -> float:
        """Seconds from the first message to the last."""
        return max(self.end - self.start, 0) / 1e9

    def of(self, kind: str) -> list[BagMessage]:
        """The messages of one kind that were read, in the bag's order (by log time)."""
        return self.messages.get(kind, [])

    def by_owner(self, kind: str) -> dict:
        """The messages of one kind per owner (UAV id or state machine), each list in the bag's order."""
        owners: dict = {}
        for message in self.of(kind):
            owners.setdefault(message.owner, []).append(message)
        return owners

    def uav_ids(self, kind: str = "pose") -> list[int]:
        """The UAVs with a topic of this kind in the bag (whether or not its messages were read)."""
        ids = set()
        for topic in self.topics:
            known = topic_kind(topic)
            if known is not None and known[0] == kind and isinstance(known[1], int):
                ids.add(known[1])
        return sorted(ids)


def stamp_ns(msg: Any, log_time: int) -> int:
    """The message's header stamp in ns; the log time when it has no header or a zero stamp."""
    header = getattr(msg, "header", None)
    if header is None:
        return int(log_time)
    ns = int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    return ns if ns > 0 else int(log_time)


def read_simulation_bag(path: str | Path, kinds: tuple[str, ...] = KINDS) -> SimulationBag:
    """The bag's extent and topics, and the messages of `kinds` (default all of KINDS); BagError when the file
    cannot be read as a bag."""
    from rosbags.highlevel import AnyReader

    path = Path(path)
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        raise ValueError(f"unknown message kinds {unknown}; known: {', '.join(KINDS)}")
    if not path.is_file():
        raise BagError(path, "no such file")
    try:
        with AnyReader([path]) as reader:
            count = reader.message_count
            # rosbags' end_time is one past the last message (an open end)
            bag = SimulationBag(path, reader.start_time if count else 0, reader.end_time - 1 if count else 0, count,
                                tuple(sorted({c.topic for c in reader.connections})))
            wanted = {}
            for connection in reader.connections:
                known = topic_kind(connection.topic)
                if known is not None and known[0] in kinds:
                    wanted[connection.id] = known
            chosen = [c for c in reader.connections if c.id in wanted]
            # no connections at all would mean every message to rosbags
            for connection, log_time, raw in reader.messages(connections=chosen) if chosen else ():
                msg = reader.deserialize(raw, connection.msgtype)
                kind, owner = wanted[connection.id]
                bag.messages.setdefault(kind, []).append(
                    BagMessage(kind, owner, stamp_ns(msg, log_time), int(log_time), msg))
    except Exception as err:  # rosbags raises an error type per format and part; each means "cannot read it"
        raise BagError(path, f"{type(err).__name__}: {err}") from None
    return bag


__all__ = ["KINDS", "MANAGER_KINDS", "MARKERS", "SM_KINDS", "UAL_KINDS", "BagError", "BagMessage", "SimulationBag",
           "read_simulation_bag", "stamp_ns", "topic_kind"]
