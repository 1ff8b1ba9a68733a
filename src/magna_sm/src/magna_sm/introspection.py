"""Introspection over ROS: a running machine's structure and status on topics, and a viewer that redraws it.

Topics, under `<namespace>/<server name>/`:
- `structure` (magna_msgs/SMStructure): every container, on start and with each heartbeat;
- `status` (magna_msgs/SMStatus): a container's active states, on every transition and each heartbeat;
- service `get_structure` (magna_msgs/GetSMStructure): every container at once.
The heartbeat runs on wall time so a viewer sees a machine even when /clock is paused.
"""
from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from magna_common import ros_names as names
from magna_sm.container import Container, ContainerEvent, ContainerStructure
from magna_sm.draw import draw_structures

if TYPE_CHECKING:
    from magna_msgs.msg import SMStatus, SMStructure


def structure_to_msg(structure: ContainerStructure, stamp=None):
    from magna_msgs.msg import SMStructure

    msg = SMStructure()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.path = structure.path
    msg.container_type = structure.container_type
    msg.children = list(structure.children)
    msg.child_types = list(structure.child_types)
    msg.container_outcomes = list(structure.container_outcomes)
    msg.transitions_from = [t[0] for t in structure.transitions]
    msg.transitions_outcome = [t[1] for t in structure.transitions]
    msg.transitions_to = [t[2] for t in structure.transitions]
    return msg


def msg_to_structure(msg, initial_states=()) -> ContainerStructure:
    return ContainerStructure(
        path=msg.path, container_type=msg.container_type, children=tuple(msg.children),
        child_types=tuple(msg.child_types), container_outcomes=tuple(msg.container_outcomes),
        initial_states=tuple(initial_states),
        transitions=tuple(zip(msg.transitions_from, msg.transitions_outcome, msg.transitions_to, strict=True)))


class IntrospectionServer:
    """Publishes one machine's structure and status; `start()` after building, `stop()` when done."""

    def __init__(self, name: str, root: Container, namespace: str = names.SM_ROOT, heartbeat: float = 1.0):
        self.root = root
        self.prefix = f"{namespace.rstrip('/')}/{name}"
        self.heartbeat = heartbeat
        self._containers: list[Container] = []
        self._by_path: dict[str, Container] = {}
        self._last_outcome: dict[str, str] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> IntrospectionServer:
        import rospy
        from magna_msgs.msg import SMStatus, SMStructure
        from magna_msgs.srv import GetSMStructure, GetSMStructureResponse

        self._rospy = rospy
        self._containers = list(self.root.walk())
        self._by_path = {container.path: container for container in self._containers}
        self._structure_pub = rospy.Publisher(f"{self.prefix}/structure", SMStructure, queue_size=100)
        self._status_pub = rospy.Publisher(f"{self.prefix}/status", SMStatus, queue_size=100)
        self._service = rospy.Service(f"{self.prefix}/get_structure", GetSMStructure,
                                      lambda _req: GetSMStructureResponse(containers=self._structure_msgs()))
        self._status_type = SMStatus
        for container in self._containers:
            container.register_observer(self._on_event)
        self._thread = threading.Thread(target=self._beat, name=f"introspection {self.prefix}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        for container in self._containers:
            container.unregister_observer(self._on_event)
        if self._thread is not None:
            self._thread.join(timeout=2 * self.heartbeat + 1)
        if hasattr(self, "_service"):
            self._service.shutdown()
            self._structure_pub.unregister()
            self._status_pub.unregister()

    def _structure_msgs(self):
        stamp = self._rospy.Time.now()
        return [structure_to_msg(container.describe(), stamp) for container in self._containers]

    def _status_msg(self, container: Container, info: str):
        msg = self._status_type()
        msg.header.stamp = self._rospy.Time.now()
        msg.path = container.path
        msg.active_states = container.get_active_states()
        msg.initial_states = container.initial_states
        msg.last_outcome = self._last_outcome.get(container.path, "")
        msg.preempt_requested = container.preempt_requested()
        msg.info = info
        return msg

    def _on_event(self, event: ContainerEvent) -> None:
        if event.outcome:
            self._last_outcome[event.path] = event.outcome
        container = self._by_path.get(event.path)
        if container is None or self._stop.is_set():
            return
        info = {"start": "running", "transition": "running"}.get(event.kind, f"finished:{event.outcome}")
        self._status_pub.publish(self._status_msg(container, info))

    def _beat(self) -> None:
        while not self._stop.is_set() and not self._rospy.is_shutdown():
            for msg in self._structure_msgs():
                self._structure_pub.publish(msg)
            for container in self._containers:
                self._status_pub.publish(self._status_msg(container, "heartbeat"))
            self._stop.wait(self.heartbeat)


class MachineView:
    """What a viewer knows of a remote machine: the latest structure and status of each container."""

    def __init__(self):
        self._lock = threading.Lock()
        self._structures: dict[str, SMStructure] = {}
        self._statuses: dict[str, SMStatus] = {}
        self.version = 0  # bumps on every change that alters the picture

    def on_structure(self, msg: SMStructure) -> None:
        with self._lock:
            old = self._structures.get(msg.path)
            if old is None or self._key(old) != self._key(msg):
                self.version += 1
            self._structures[msg.path] = msg

    def on_status(self, msg: SMStatus) -> None:
        with self._lock:
            old = self._statuses.get(msg.path)
            if old is None or list(old.active_states) != list(msg.active_states):
                self.version += 1
            self._statuses[msg.path] = msg

    @staticmethod
    def _key(msg):
        return (tuple(msg.children), tuple(msg.transitions_from), tuple(msg.transitions_to))

    def active_paths(self) -> set[str]:
        with self._lock:
            return {f"{path}/{label}" for path, status in self._statuses.items() for label in status.active_states}

    def structures(self) -> list[ContainerStructure]:
        with self._lock:
            return [msg_to_structure(msg, self._statuses[path].initial_states if path in self._statuses else ())
                    for path, msg in self._structures.items()]

    def render(self, output: Path, title: str = "") -> Path:
        return draw_structures(self.structures(), output, self.active_paths(), title)


def run_viewer(server: str, output: Path, namespace: str = names.SM_ROOT, min_period: float = 0.5,
               once: bool = False, timeout: float = 10.0, window: bool = False) -> int:
    """Subscribe to a server's topics and redraw `output` whenever the machine changes."""
    import rospy
    from magna_msgs.msg import SMStatus, SMStructure

    view = MachineView()
    prefix = f"{namespace.rstrip('/')}/{server}"
    rospy.Subscriber(f"{prefix}/structure", SMStructure, view.on_structure, queue_size=100)
    rospy.Subscriber(f"{prefix}/status", SMStatus, view.on_status, queue_size=100)
    shower = None
    if window:
        try:
            shower = _Window()
        except Exception as error:  # no Tk, or the display refused us: the file still works
            rospy.logwarn(f"magna_sm viewer: no window ({error}); drawing to {output} only")
    drawn_version = -1
    deadline = time.monotonic() + timeout
    while not rospy.is_shutdown():
        if view.version != drawn_version and view.structures():
            drawn_version = view.version
            view.render(output, title=server)
            rospy.loginfo_throttle(5, f"magna_sm viewer: drew {output}")
            if shower is not None:
                shower.show(output)
            if once:
                return 0
        elif once and time.monotonic() > deadline:
            rospy.logerr(f"magna_sm viewer: no structure arrived on {prefix}/structure within {timeout:.0f} s")
            return 1
        time.sleep(min_period)
    return 0


class _Window:
    """A window showing the latest picture (only when a display exists)."""

    def __init__(self):
        import matplotlib
        matplotlib.use("TkAgg")
        import matplotlib.pyplot as plt
        self._plt = plt
        self._figure = plt.figure("magna_sm viewer")
        plt.ion()

    def show(self, image_path: Path) -> None:
        image = self._plt.imread(str(image_path))
        self._figure.clf()
        axes = self._figure.add_axes((0, 0, 1, 1))
        axes.imshow(image)
        axes.axis("off")
        self._plt.pause(0.01)
