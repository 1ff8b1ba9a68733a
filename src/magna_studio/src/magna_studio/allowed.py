"""What the studio's page may reach through the bridge: the topics it may watch and the services it may call.

This list is the whole of the page's access to ROS. A topic is allowed by pattern, `<id>` standing for a
UAV id 1-999 written without leading zeros; a service by its exact name. Each comes with the one message
or service type the bridge uses for it. The page cannot publish, advertise, read parameters or call any
other service. The names come from magna_common.ros_names, the runtime contract of the nodes.
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from magna_common import ros_names as names

ID_PLACEHOLDER = "<id>"
# A UAV id: 1..999, no leading zero, ASCII digits only (`\d` would also match other scripts' digits).
_UAV_ID = "[1-9][0-9]{0,2}"


@dataclass(frozen=True)
class AllowedTopic:
    pattern: str  # the name with <id> for the UAV id, e.g. /uav_<id>/ual/pose
    type: str  # ROS message type, package/Name
    about: str

    def matches(self, name: str) -> bool:
        return _compiled(self.pattern).fullmatch(name) is not None


@dataclass(frozen=True)
class AllowedService:
    name: str
    type: str  # ROS service type, package/Name
    about: str


@functools.cache
def _compiled(pattern: str) -> re.Pattern[str]:
    return re.compile(re.escape(pattern).replace(re.escape(ID_PLACEHOLDER), _UAV_ID))


TOPICS: tuple[AllowedTopic, ...] = (
    AllowedTopic(names.ual(ID_PLACEHOLDER, "pose"), "geometry_msgs/PoseStamped", "a UAV's pose from its UAL"),
    AllowedTopic(names.ual(ID_PLACEHOLDER, "state"), "uav_abstraction_layer/State", "a UAV's UAL state"),
    AllowedTopic(names.battery(ID_PLACEHOLDER), "sensor_msgs/BatteryState", "a UAV's battery"),
    AllowedTopic(names.manager(ID_PLACEHOLDER, "navigation"), "magna_msgs/NavigationStep",
                 "a UAV manager's control steps; `role` is the role it flies"),
    AllowedTopic(names.sm_topic("mission", "status"), "magna_msgs/SMStatus", "the mission state machine's status"),
    AllowedTopic(names.sm_topic("mission", "structure"), "magna_msgs/SMStructure",
                 "the mission state machine's containers"),
    AllowedTopic(names.GS_CRITICAL_EVENT, "std_msgs/String",
                 "the ground station's critical event to every UAV (\"operator\" while the operator's is raised)"),
    AllowedTopic(names.GS_CRITICAL_EVENTS, "magna_msgs/CriticalEvent",
                 "each critical event the ground station records: collision, low battery, link or manager lost"),
    AllowedTopic("/clock", "rosgraph_msgs/Clock", "the simulated time"),
)

SERVICES: dict[str, AllowedService] = {service.name: service for service in (
    AllowedService(names.GS_COMMAND, "magna_msgs/GroundStationCommand",
                   "an operator's command: take off, land, move, turn, follow, get, set, mission standby/resume"),
    AllowedService(names.GS_CONTINUE, "std_srvs/Trigger", "let a mission waiting for the operator go on"),
    # magna_sm.introspection serves the whole structure: the page may connect after the topic's last message.
    AllowedService(names.sm_topic("mission", "get_structure"), "magna_msgs/GetSMStructure",
                   "every container of the mission state machine at once"),
)}


def topic_type(name: str) -> str | None:
    """The message type of an allowed topic, or None when the page may not subscribe to `name`."""
    if not name.isascii():  # the patterns are ASCII: no look-alike letters or digits get through
        return None
    for topic in TOPICS:
        if topic.matches(name):
            return topic.type
    return None


def service_type(name: str) -> str | None:
    """The service type of an allowed service, or None when the page may not call `name`."""
    service = SERVICES.get(name)
    return service.type if service is not None else None


def topic_patterns() -> list[str]:
    return [topic.pattern for topic in TOPICS]


def service_names() -> list[str]:
    return list(SERVICES)


def describe() -> dict[str, list[dict[str, str]]]:
    """The allow list as JSON-ready data, for the page's documentation and forms."""
    return {"topics": [{"pattern": t.pattern, "type": t.type, "about": t.about} for t in TOPICS],
            "services": [{"name": s.name, "type": s.type, "about": s.about} for s in SERVICES.values()]}
