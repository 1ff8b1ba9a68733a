"""The bridge node over a live master: `rosrun magna_studio bridge --port 0`, a page played by tornado's client.

This test process publishes poses and serves a stub ground-station command service on the session's private
master; the assertions are on what arrives over the WebSocket. Every wait has a guard timeout and waits on a
condition, never on a duration.
"""
import asyncio
import json
import os
import queue
import signal
import subprocess
import threading
import time
import uuid

import pytest
import tornado.httpclient
from geometry_msgs.msg import PoseStamped
from magna_msgs.srv import GroundStationCommand, GroundStationCommandResponse
from tornado.websocket import websocket_connect

from magna_common import ros_names as names
from magna_common.processes import end_process_group

START_GUARD = 60.0  # s: the node's start on a busy machine; a guard, not an expectation
GUARD = 30.0  # s: any other wait
POSE_TOPIC = names.ual(1, "pose")


class BridgeNode:
    """The node under test, its stdout drained (rospy logs there too) and searchable."""

    def __init__(self, ros_master, *options: str,
                 argv: tuple[str, ...] = ("rosrun", "magna_studio", "bridge", "--port", "0")):
        self.process = ros_master.spawn([*argv, *options], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True)
        self.lines: list[str] = []
        self._new = queue.Queue()
        threading.Thread(target=self._drain, daemon=True).start()
        self.url = self.wait_for_line("bridge: ws://", START_GUARD).split("bridge: ", 1)[1].strip()

    def _drain(self):
        for line in self.process.stdout:
            self.lines.append(line)
            self._new.put(line)
        self._new.put(None)

    def wait_for_line(self, start: str, guard: float = GUARD) -> str:
        deadline = time.monotonic() + guard
        while True:
            try:
                line = self._new.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f"the bridge printed no line with {start!r}:\n{''.join(self.lines)}") from None
            if line is None:
                raise AssertionError(f"the bridge ended ({self.process.wait()}):\n{''.join(self.lines)}")
            if start in line:
                return line

    def stop(self):
        end_process_group(self.process)


@pytest.fixture
def bridge(ros_master, rospy_node):
    node = BridgeNode(ros_master)
    try:
        yield node
    finally:
        node.stop()


def run(scenario):
    asyncio.run(asyncio.wait_for(scenario, 4 * GUARD))


async def until(predicate, what: str):
    deadline = time.monotonic() + GUARD
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.01)


async def receive(connection, wanted, what: str) -> dict:
    """The next message for which `wanted(message)` holds (others are skipped)."""
    async def read():
        while True:
            text = await connection.read_message()
            assert text is not None, f"the bridge closed the connection while we waited for {what}"
            message = json.loads(text)
            if wanted(message):
                return message

    try:
        return await asyncio.wait_for(read(), GUARD)
    except TimeoutError:
        raise AssertionError(f"timed out waiting for {what}") from None


async def send(connection, **message):
    await connection.write_message(json.dumps(message))


def pose(x: float, frame_id: str) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = frame_id
    msg.header.stamp.secs, msg.header.stamp.nsecs = 41, 5
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, -2.5, 7.25
    msg.pose.orientation.w = 1.0
    return msg


def is_pose(token: str):
    return lambda m: m.get("op") == "publish" and m["msg"]["header"]["frame_id"] == token


def test_poses_arrive_as_publish_ops_to_every_page_through_one_subscriber(bridge, rospy_node):
    rospy = rospy_node
    token = f"test-{uuid.uuid4().hex[:8]}"  # tells our poses from any other test's on the same topic
    publisher = rospy.Publisher(POSE_TOPIC, PoseStamped, queue_size=100)

    async def scenario():
        first = await websocket_connect(bridge.url)
        second = await websocket_connect(bridge.url)
        for page in (first, second):
            await send(page, op="subscribe", id="poses", topic=POSE_TOPIC, type="geometry_msgs/PoseStamped")
        await until(lambda: publisher.get_num_connections() >= 1, "the bridge to subscribe")
        publisher.publish(pose(1.5, token))
        expected = {"op": "publish", "topic": POSE_TOPIC, "msg": {
            "header": {"stamp": {"secs": 41, "nsecs": 5}, "frame_id": token},
            "pose": {"position": {"x": 1.5, "y": -2.5, "z": 7.25},
                     "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}}
        for page in (first, second):
            message = await receive(page, is_pose(token), "the pose")
            assert isinstance(message["msg"]["header"].pop("seq"), int)  # rospy numbers what it publishes
            assert message == expected
        assert publisher.get_num_connections() == 1  # one subscriber for both pages
        await send(first, op="unsubscribe", id="poses", topic=POSE_TOPIC)
        publisher.publish(pose(2.0, token))
        assert (await receive(second, is_pose(token), "the second pose"))["msg"]["pose"]["position"]["x"] == 2.0
        second.close()
        await until(lambda: publisher.get_num_connections() == 0, "the bridge to unsubscribe when no page watches")
        first.close()

    try:
        run(scenario())
    finally:
        publisher.unregister()


def test_bridge_launch_starts_the_node_for_a_stack_started_by_hand(ros_master, rospy_node):
    rospy = rospy_node
    node = BridgeNode(ros_master, argv=("roslaunch", "magna_studio", "bridge.launch", "port:=0"))
    token = f"launch-{uuid.uuid4().hex[:8]}"
    publisher = rospy.Publisher(POSE_TOPIC, PoseStamped, queue_size=10)

    async def scenario():
        connection = await websocket_connect(node.url)
        await send(connection, op="subscribe", id="s1", topic=POSE_TOPIC)
        await until(lambda: publisher.get_num_connections() >= 1, "the launched bridge to subscribe")
        publisher.publish(pose(1.5, token))
        message = await receive(connection, is_pose(token), "the pose through the launched bridge")
        assert message["msg"]["pose"]["position"]["x"] == 1.5
        connection.close()

    try:
        run(scenario())
    finally:
        publisher.unregister()
        node.stop()


def test_the_throttle_holds_and_the_newest_pose_still_arrives(bridge, rospy_node):
    rospy = rospy_node
    token = f"test-{uuid.uuid4().hex[:8]}"
    publisher = rospy.Publisher(POSE_TOPIC, PoseStamped, queue_size=100)
    interval = 1.0  # s: the page's throttle_rate
    count = 30
    received = []

    async def scenario():
        page = await websocket_connect(bridge.url)
        await send(page, op="subscribe", topic=POSE_TOPIC, throttle_rate=int(interval * 1000), queue_length=1)
        await until(lambda: publisher.get_num_connections() >= 1, "the bridge to subscribe")
        start = time.monotonic()
        for x in range(count):
            publisher.publish(pose(float(x), token))
        while not received or received[-1] != count - 1:
            message = await receive(page, is_pose(token), "the newest pose")
            received.append(message["msg"]["pose"]["position"]["x"])
        elapsed = time.monotonic() - start
        # The bridge sent these at least `interval` apart, all within `elapsed`.
        assert len(received) <= 1 + elapsed / interval, (received, elapsed)
        assert received == sorted(set(received))  # in order, none twice
        page.close()

    try:
        run(scenario())
    finally:
        publisher.unregister()
    left = json.loads(bridge.wait_for_line("left: {").split("left: ", 1)[1])  # the page's counts, for benches
    assert left["sent"] >= len(received) and left["refused"] == 0 and left["calls"] == 0


class StubGroundStation:
    """/magna/gs/command: accepts a mission standby, refuses anything else as the ground station would."""

    def __init__(self, rospy):
        self.requests = []
        self.service = rospy.Service(names.GS_COMMAND, GroundStationCommand, self.handle)

    def handle(self, request):
        self.requests.append(request)
        if request.action == "crash":
            raise RuntimeError("the stub fails on purpose")
        if (request.intent, request.action) == ("mission", "standby"):
            return GroundStationCommandResponse(accepted=True, message="mission paused")
        return GroundStationCommandResponse(
            accepted=False, message=f"mission action {request.action!r} is unknown: give standby, resume, critical")


def test_commands_are_answered_with_their_messages_and_refusals_keep_the_connection(bridge, rospy_node):
    station = StubGroundStation(rospy_node)

    def answer_to(request_id):
        return lambda m: m.get("id") == request_id

    async def scenario():
        page = await websocket_connect(bridge.url)
        await send(page, op="call_service", id="c1", service=names.GS_COMMAND,
                   args={"intent": "mission", "action": "standby", "agent": "all",
                         "parameters": [{"name": "delay", "number": 7, "unit": "s"}]})
        assert await receive(page, answer_to("c1"), "the accepted command's answer") == {
            "op": "service_response", "id": "c1", "service": names.GS_COMMAND, "result": True,
            "values": {"accepted": True, "message": "mission paused", "values": []}}
        await send(page, op="call_service", id="c2", service=names.GS_COMMAND,
                   args={"intent": "mission", "action": "launch"})
        refused = await receive(page, answer_to("c2"), "the refused command's answer")
        assert refused["result"] is True and refused["values"]["accepted"] is False
        assert refused["values"]["message"] == "mission action 'launch' is unknown: give standby, resume, critical"

        # Hostile and malformed messages: each gets a status error, and the page can go on.
        for request_id, message, says in [
            ("h1", {"op": "call_service", "service": "/rosapi/topics"}, "service '/rosapi/topics' is not open"),
            ("h2", {"op": "subscribe", "topic": "/rosout"}, "topic '/rosout' is not open"),
            ("h3", {"op": "publish", "topic": names.GS_CRITICAL_EVENT, "msg": {"data": "x"}}, "is not allowed"),
            ("h4", {"op": "call_service", "service": names.GS_COMMAND, "args": {"intent": True}},
             "args.intent is true, a boolean; give a string"),
        ]:
            await send(page, id=request_id, **message)
            status = await receive(page, answer_to(request_id), f"the refusal of {request_id}")
            assert status["op"] == "status" and status["level"] == "error" and says in status["msg"], status
        await page.write_message("this is not JSON")
        status = await receive(page, lambda m: m.get("op") == "status", "the refusal of a frame that is not JSON")
        assert "not JSON" in status["msg"]
        await page.write_message(b"\x00\x01", binary=True)
        status = await receive(page, lambda m: m.get("op") == "status", "the refusal of a binary frame")
        assert "binary" in status["msg"]

        # A failing service and one nobody serves come back as result false with the error.
        await send(page, op="call_service", id="c3", service=names.GS_COMMAND, args={"action": "crash"})
        failed = await receive(page, answer_to("c3"), "the failed call's answer")
        assert failed["result"] is False and failed["op"] == "service_response"
        assert failed["values"].startswith(f"{names.GS_COMMAND}: ") and "stub fails on purpose" in failed["values"]
        await send(page, op="call_service", id="c4", service=names.GS_CONTINUE)
        missing = await receive(page, answer_to("c4"), "the answer of a service nobody serves")
        assert missing["result"] is False and "unavailable" in missing["values"]

        await send(page, op="call_service", id="c5", service=names.GS_COMMAND,
                   args={"intent": "mission", "action": "standby"})
        assert (await receive(page, answer_to("c5"), "a command after the refusals"))["values"]["accepted"] is True
        page.close()

    try:
        run(scenario())
    finally:
        station.service.shutdown()
    assert [r.action for r in station.requests] == ["standby", "launch", "crash", "standby"]  # no refused one
    assert station.requests[0].parameters[0].number == 7.0 and station.requests[0].parameters[0].unit == "s"


def test_a_call_that_takes_too_long_is_answered_with_result_false(ros_master, rospy_node):
    from std_srvs.srv import Trigger, TriggerResponse

    node = BridgeNode(ros_master, "--call-timeout", "0.5")
    answered = threading.Event()  # the stub answers only once the page has its timeout: no race on durations

    def slow(_request):
        answered.wait(4 * GUARD)
        return TriggerResponse(success=True, message="too late")

    service = rospy_node.Service(names.GS_CONTINUE, Trigger, slow)

    async def scenario():
        page = await websocket_connect(node.url)
        await send(page, op="call_service", id="slow", service=names.GS_CONTINUE)
        late = await receive(page, lambda m: m.get("id") == "slow", "the timeout's answer")
        answered.set()
        assert late["op"] == "service_response" and late["result"] is False
        # Sent at once by an idle pool, as a rule; a machine slow enough to start it late gets the other words.
        assert late["values"] in (f"{names.GS_CONTINUE}: no answer within 0.5 s (it may have been carried out)",
                                  f"{names.GS_CONTINUE}: no answer within 0.5 s (it was not sent)")
        page.close()

    try:
        run(scenario())
    finally:
        answered.set()
        service.shutdown()
        node.stop()


def test_pages_from_foreign_origins_are_refused(bridge):
    port = bridge.url.rsplit(":", 1)[1].strip("/")

    async def connect(origin, host=None):
        headers = {"Origin": origin} if origin else {}
        if host:
            headers["Host"] = host
        return await websocket_connect(tornado.httpclient.HTTPRequest(bridge.url, headers=headers))

    async def scenario():
        for origin, host in [("http://evil.example", None), ("null", None),
                             # a DNS-rebinding page: its Origin matches the Host it asks for
                             (f"http://evil.example:{port}", f"evil.example:{port}"),
                             ("http://127.0.0.1.evil.example:8000", None)]:
            with pytest.raises(tornado.httpclient.HTTPClientError) as refused:
                await connect(origin, host)
            assert refused.value.code == 403, origin
        for origin in ("http://localhost:8000", "http://127.0.0.1:5173", None):
            page = await connect(origin)
            await send(page, op="subscribe", id="s", topic="/rosout")
            assert "not open" in (await receive(page, lambda m: m.get("id") == "s", "an answer"))["msg"]
            page.close()

    run(scenario())


@pytest.mark.parametrize("how", ["SIGINT", "SIGTERM", "rosnode kill"])
def test_the_node_ends_cleanly(ros_master, how):
    node = BridgeNode(ros_master)
    try:
        if how == "rosnode kill":
            subprocess.run(["rosnode", "kill", "/magna_studio_bridge"], env=ros_master.env(), capture_output=True,
                           timeout=GUARD, check=True)
        else:
            os.killpg(node.process.pid, getattr(signal, how))
        assert node.process.wait(timeout=GUARD) == 0, "".join(node.lines)
    finally:
        node.stop()
