"""A state machine's introspection messages -> which state was active when (a Gantt timeline).

The ground station's machine publishes, per container (magna_sm.introspection):

- `structure` (SMStructure): its children, their types and its transitions, at start and as a heartbeat;
- `status` (SMStatus): its active children, the outcome of the child that finished last, and `info`
  ("running" on a transition, "heartbeat", "finished:<outcome>" when the container itself ends).

Each status message is compared with the container's previous one: a label that appears starts an
interval, a label that disappears ends one, with `last_outcome` as its outcome when it is the only
one that ended in that message (two ending at once would be a guess). Heartbeats are read the same
way, so they also repair a missed transition. A container's first message being a heartbeat that
already lists active children means those started before the recording (`started_before`); what is
still active when the recording ends is closed there (`unfinished`). Ending a container state also
ends whatever its own children still had open.

Labels are registered as `{id}_{name}` by the mission loader; a leaf whose label starts with the id
of a UAV of the mission is that UAV's state. Containers are not tied to a UAV: a concurrence named
`1_take_off` runs the take-off of every UAV.
"""
from __future__ import annotations

import re
from collections.abc import Collection, Iterable
from dataclasses import dataclass, field

from magna_sm.container import ContainerStructure

CONTAINER_TYPES = frozenset({"StateMachine", "Concurrence", "Sequence", "Iterator"})
FINISHED = "finished:"
_UAV_LABEL = re.compile(r"(\d+)_")


@dataclass(frozen=True)
class StatusEvent:
    """One SMStatus message: a container's active children at `time` (simulated seconds)."""

    time: float
    path: str  # the container, e.g. "/MISSION/1_take_off"
    active_states: tuple[str, ...]
    last_outcome: str = ""
    info: str = ""


@dataclass(frozen=True)
class StateInfo:
    """One state of the machine, in drawing order."""

    path: str  # "/MISSION/1_take_off/2_take_off"
    container: str  # "/MISSION/1_take_off"
    label: str  # "2_take_off"
    kind: str  # its class: "CallbackState", "MissionActionState", "Concurrence", ...
    is_container: bool
    depth: int  # 0 for the root's children
    uav_id: int | None  # the UAV a leaf acts for, from its label


@dataclass(frozen=True)
class StateInterval:
    """A stretch of time during which one state was active."""

    path: str
    container: str
    label: str
    start: float
    end: float
    outcome: str | None  # None when the messages do not tell it
    next_state: str | None  # where the container's transition for that outcome leads
    uav_id: int | None
    kind: str
    started_before: bool = False  # already active in the first message of its container
    unfinished: bool = False  # still active when the recording ended

    @property
    def duration(self) -> float:
        return self.end - self.start


@dataclass
class Timeline:
    states: list[StateInfo] = field(default_factory=list)
    intervals: list[StateInterval] = field(default_factory=list)  # by start time
    outcome: str | None = None  # the root container's own outcome, when it finished in the recording
    finished_at: float | None = None

    def state(self, path: str) -> StateInfo | None:
        return next((s for s in self.states if s.path == path), None)

    def intervals_of(self, path: str) -> list[StateInterval]:
        return [i for i in self.intervals if i.path == path]

    def ran(self, path: str) -> bool:
        return any(i.path == path for i in self.intervals)

    def leaves(self) -> list[StateInfo]:
        return [s for s in self.states if not s.is_container]


def uav_of(label: str, uav_ids: Collection[int] | None = None) -> int | None:
    """The UAV id a label names by its "<id>_" prefix (only ids in `uav_ids`, when given)."""
    match = _UAV_LABEL.match(label)
    if match is None:
        return None
    uav = int(match.group(1))
    return uav if uav_ids is None or uav in uav_ids else None


def build_timeline(structures: Iterable[ContainerStructure], statuses: Iterable[StatusEvent], end_time: float,
                   uav_ids: Collection[int] | None = None) -> Timeline:
    """The timeline of the messages: statuses in the order they were recorded, structures as
    `magna_sm.introspection.msg_to_structure` reads them (the last one per path wins)."""
    shapes = {s.path: s for s in structures}
    states = _states_in_order(shapes, uav_ids)
    by_path = {s.path: s for s in states}
    builder = _Builder(shapes, by_path, uav_ids)
    for event in statuses:
        builder.feed(event)
    builder.close_all(end_time)
    known = set(by_path)
    # states heard in statuses but absent from every structure message still get a row, after the rest
    for interval in builder.intervals:
        if interval.path not in known:
            known.add(interval.path)
            states.append(StateInfo(interval.path, interval.container, interval.label, interval.kind,
                                    interval.path in shapes, interval.container.count("/") - 1, interval.uav_id))
    root = _root(shapes, builder.finished)
    return Timeline(states, sorted(builder.intervals, key=lambda i: (i.start, i.path)),
                    builder.finished.get(root, (None, None))[0] if root else None,
                    builder.finished.get(root, (None, None))[1] if root else None)


def _root(shapes: dict[str, ContainerStructure], finished: dict) -> str | None:
    paths = list(shapes) or list(finished)
    return min(paths, key=lambda p: (p.count("/"), p)) if paths else None


def _states_in_order(shapes: dict[str, ContainerStructure], uav_ids) -> list[StateInfo]:
    children = {f"{p}/{c}" for s in shapes.values() for c in s.children for p in [s.path]}
    roots = sorted((p for p in shapes if p not in children), key=lambda p: (p.count("/"), p))
    out: list[StateInfo] = []

    def walk(path: str, depth: int) -> None:
        shape = shapes[path]
        for label, kind in zip(shape.children, shape.child_types, strict=False):
            child = f"{path}/{label}"
            is_container = child in shapes or kind in CONTAINER_TYPES
            out.append(StateInfo(child, path, label, kind, is_container, depth,
                                 None if is_container else uav_of(label, uav_ids)))
            if child in shapes and child != path:
                walk(child, depth + 1)

    for root in roots:
        walk(root, 0)
    return out


class _Builder:
    def __init__(self, shapes: dict[str, ContainerStructure], states: dict[str, StateInfo], uav_ids):
        self.shapes = shapes
        self.states = states
        self.uav_ids = uav_ids
        self.active: dict[str, list[str]] = {}  # container -> active labels, in message order
        self.open: dict[str, tuple[float, bool]] = {}  # state path -> (start, started_before)
        self.intervals: list[StateInterval] = []
        self.finished: dict[str, tuple[str, float]] = {}  # container -> (outcome, time)

    def feed(self, event: StatusEvent) -> None:
        first = event.path not in self.active
        old = self.active.get(event.path, [])
        new = list(dict.fromkeys(event.active_states))
        ended = [label for label in old if label not in new]
        for label in ended:
            outcome = event.last_outcome if len(ended) == 1 and event.last_outcome else None
            self._close(f"{event.path}/{label}", event.time, outcome)
        for label in new:
            if label not in old:
                self.open[f"{event.path}/{label}"] = (event.time, first and event.info == "heartbeat")
        self.active[event.path] = new
        if event.info.startswith(FINISHED):
            for label in new:  # a finished container has no active child, whatever the message lists
                self._close(f"{event.path}/{label}", event.time, None)
            self.active[event.path] = []
            self.finished[event.path] = (event.info[len(FINISHED):], event.time)

    def _close(self, path: str, time: float, outcome: str | None, unfinished: bool = False) -> None:
        if path in self.active:  # a container state: its children end with it
            for label in self.active[path]:
                self._close(f"{path}/{label}", time, None, unfinished)
            self.active[path] = []
        if path not in self.open:
            return
        start, before = self.open.pop(path)
        container, label = path.rsplit("/", 1)
        info = self.states.get(path)
        kind = info.kind if info else ("Container" if path in self.shapes else "")
        uav = info.uav_id if info else (None if path in self.shapes else uav_of(label, self.uav_ids))
        self.intervals.append(StateInterval(path, container, label, start, max(time, start), outcome,
                                            self._next(container, label, outcome), uav, kind, before, unfinished))

    def _next(self, container: str, label: str, outcome: str | None) -> str | None:
        shape = self.shapes.get(container)
        if outcome is None or shape is None or shape.container_type == "Concurrence":
            return None  # a concurrence's "transitions" map its children's outcomes onto its own, no next state
        return next((to for source, out, to in shape.transitions if source == label and out == outcome), None)

    def close_all(self, end_time: float) -> None:
        for path in sorted(self.open, key=lambda p: -p.count("/")):  # children before their containers
            if path in self.open:
                self._close(path, max(end_time, self.open[path][0]), None, unfinished=True)


__all__ = ["CONTAINER_TYPES", "StateInfo", "StateInterval", "StatusEvent", "Timeline",
           "build_timeline", "uav_of"]
