"""The ROS side: a `Command` becomes a call of the ground station's /magna/gs/command service.

rospy is imported only here, and only when a client is made, so parsing and transcribing work on
a machine without ROS.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from magna_common import ros_names
from voice.interpret import Command, Parameter, parameter_json


class BackendError(RuntimeError):
    """The ground station cannot be reached; the message says what to start."""


@dataclass(frozen=True)
class Reply:
    accepted: bool
    message: str
    values: list[Parameter] = field(default_factory=list)
    sent_at: float = 0.0  # time.monotonic() when the request left

    def describe(self) -> str:
        """The ground station's answer as it is: an accepted command's message says what will happen ("UAV 2
        climbing to 7 m"), a refusal's why ("refused: UAV 1 is landing, so it cannot move")."""
        head = self.message if self.accepted else "refused: " + self.message
        if not self.values:
            return head
        return head + "\n" + "\n".join(f"  {v.name}: {v.text or f'{v.number:.1f}'}{' ' + v.unit if v.unit else ''}"
                                       for v in self.values)

    def spoken(self) -> str:
        """The answer as a short sentence for espeak-ng: the ground station's message (a refusal's already says
        why it cannot be done), or the values asked for."""
        if not self.accepted or not self.values:
            return _sentence(self.message)
        parts = []
        for v in self.values:
            who, _, what = v.name.partition(".")
            value = v.text or (f"{v.number:.0f} percent" if v.unit == "%" else f"{v.number:.1f} {v.unit}")
            parts.append(f"{who.replace('uav_', 'drone ')} {what.replace('.', ' ')} {value}")
        return ". ".join(parts)


def _sentence(text: str) -> str:
    text = text.strip()
    return text if not text or text.endswith((".", "!", "?")) else text + "."


def to_request_fields(command: Command) -> dict:
    """The GroundStationCommand request fields, NamedValues as plain dicts (no ROS needed)."""
    return {"intent": command.intent, "action": command.action, "agent": command.agent,
            "parameters": [parameter_json(p) for p in command.parameters]}


class GroundStationClient:
    """Calls /magna/gs/command; one per process."""

    def __init__(self, service: str = ros_names.GS_COMMAND, node_name: str = "magna_voice", master_wait: float = 0.0):
        """master_wait: seconds to wait for a ROS master that is not up yet (a mission still starting)."""
        import rospy
        from magna_msgs.msg import NamedValue
        from magna_msgs.srv import GroundStationCommand

        self._rospy, self._named_value = rospy, NamedValue
        self.service = service
        if not rospy.core.is_initialized():
            import rosgraph

            deadline = time.monotonic() + master_wait
            while not rosgraph.is_master_online() and time.monotonic() < deadline:
                time.sleep(0.2)  # roslaunch starts the master a few seconds after it is started
            if not rosgraph.is_master_online():  # else init_node would wait for a master forever
                raise BackendError(f"no ROS master at {rosgraph.get_master_uri()}: start the mission (roslaunch "
                                   "magna_gs simulation.launch mission_file:=...) or set ROS_MASTER_URI; "
                                   "`magna voice --dry-run` understands commands without sending them")
            rospy.init_node(node_name, anonymous=True, disable_signals=True)
        self._proxy = rospy.ServiceProxy(service, GroundStationCommand)

    def wait(self, timeout: float) -> None:
        try:
            self._rospy.wait_for_service(self.service, timeout=timeout)
        except self._rospy.ROSException:
            raise BackendError(f"the ground station's {self.service} is not up after {timeout:g} s: start a mission "
                               "(roslaunch magna_gs simulation.launch mission_file:=...) or check ROS_MASTER_URI; "
                               "`magna voice --dry-run` understands commands without sending them") from None

    def uav_ids(self) -> list[int]:
        """The UAVs flying now (every UAL server lists its id in /ual_ids)."""
        try:
            return sorted(int(i) for i in self._rospy.get_param(ros_names.UAL_IDS, []))
        except (TypeError, ValueError, self._rospy.ROSException):
            return []

    def wait_for_uavs(self, timeout: float) -> list[int]:
        """The UAVs in /ual_ids once the ground station knows where each one is ([] if none within `timeout` s).

        A mission that has just started is still spawning its UAVs: the ground station would refuse a
        command for a UAV whose pose it has not heard yet. Asking it where they all are is the check.
        """
        deadline = time.monotonic() + timeout
        where = Command("parameters", "get", "all", (Parameter("position", 0.0, "", ""),))
        while True:
            ids = self.uav_ids()
            if ids and self.send(where).accepted:
                return ids
            if time.monotonic() >= deadline:
                return ids
            time.sleep(0.2)

    def send(self, command: Command) -> Reply:
        values = [self._named_value(p.name, p.number, p.text, p.unit) for p in command.parameters]
        sent_at = time.monotonic()
        try:
            answer = self._proxy(intent=command.intent, action=command.action, agent=command.agent, parameters=values)
        except self._rospy.ServiceException as error:
            raise BackendError(f"{self.service} failed: {error}") from None
        return Reply(answer.accepted, answer.message,
                     [Parameter(v.name, v.number, v.text, v.unit) for v in answer.values], sent_at)
