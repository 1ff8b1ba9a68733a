"""The bridge's checks of what a page sends: valid requests of each op, and malformed and hostile ones refused
with an error that names the op, the id, the field and the fix."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from magna_studio import allowed
from magna_studio.protocol import (
    MAX_ARRAY_LENGTH,
    MAX_FRAME_BYTES,
    MAX_ID_LENGTH,
    MAX_STRING_LENGTH,
    CallService,
    ConnectionLimiter,
    ProtocolError,
    RateLimited,
    Subscribe,
    Unsubscribe,
    parse_request,
)

POSE = "/uav_1/ual/pose"
COMMAND = "/magna/gs/command"


def frame(**fields) -> str:
    return json.dumps(fields)


def refusal(text: str) -> ProtocolError:
    with pytest.raises(ProtocolError) as caught:
        parse_request(text)
    return caught.value


def command(args, request_id="c1") -> str:
    return frame(op="call_service", id=request_id, service=COMMAND, args=args)


# --- valid requests -----------------------------------------------------------------------------------------

def test_subscribe_with_every_option():
    request = parse_request(frame(op="subscribe", id="s1", topic="/uav_12/ual/pose", type="geometry_msgs/PoseStamped",
                                  throttle_rate=250, queue_length=5, compression="none"))
    assert request == Subscribe("/uav_12/ual/pose", "geometry_msgs/PoseStamped", "s1", 250, 5)


def test_subscribe_defaults_and_the_type_comes_from_the_allow_list():
    request = parse_request(frame(op="subscribe", topic="/magna/uav_999/navigation"))
    assert request == Subscribe("/magna/uav_999/navigation", "magna_msgs/NavigationStep", None, 0, 1)


@pytest.mark.parametrize("topic", ["/uav_1/ual/pose", "/uav_7/ual/state", "/uav_42/mavros/battery",
                                   "/magna/uav_3/navigation", "/magna/sm/mission/status",
                                   "/magna/sm/mission/structure", "/magna/gs/critical_event",
                                   "/magna/gs/critical_events", "/clock"])
def test_every_allowed_topic_can_be_watched(topic):
    request = parse_request(frame(op="subscribe", topic=topic))
    assert isinstance(request, Subscribe) and request.type == allowed.topic_type(topic)


def test_the_allow_list_describes_what_it_lets_through():
    described = allowed.describe()
    assert [t["pattern"] for t in described["topics"]] == allowed.topic_patterns()
    assert {s["name"]: s["type"] for s in described["services"]} == {
        "/magna/gs/command": "magna_msgs/GroundStationCommand", "/magna/gs/continue": "std_srvs/Trigger",
        "/magna/sm/mission/get_structure": "magna_msgs/GetSMStructure"}
    for topic in described["topics"]:
        for uav_id in ("1", "999"):
            assert allowed.topic_type(topic["pattern"].replace("<id>", uav_id)) == topic["type"]


def test_roslibjs_defaults_are_accepted():
    # roslibjs sends queue_length 0 and compression "none" unless told otherwise
    request = parse_request(frame(op="subscribe", id="subscribe:/clock:1", type="rosgraph_msgs/Clock",
                                  topic="/clock", compression="none", throttle_rate=0, queue_length=0))
    assert request == Subscribe("/clock", "rosgraph_msgs/Clock", "subscribe:/clock:1", 0, 0)


def test_unsubscribe():
    assert parse_request(frame(op="unsubscribe", id="s1", topic=POSE)) == Unsubscribe(POSE, "s1")


def test_a_command_is_checked_against_the_request_message():
    request = parse_request(command({"intent": "mission", "action": "standby", "agent": "all",
                                     "parameters": [{"name": "height", "number": 7, "unit": "m"}]}))
    assert request == CallService(COMMAND, "magna_msgs/GroundStationCommand",
                                  {"intent": "mission", "action": "standby", "agent": "all",
                                   "parameters": [{"name": "height", "number": 7.0, "unit": "m"}]}, "c1")
    assert isinstance(request.args["parameters"][0]["number"], float)


def test_missing_fields_are_left_for_the_defaults_and_args_may_be_absent():
    assert parse_request(command({"action": "resume"})).args == {"action": "resume"}
    request = parse_request(frame(op="call_service", service="/magna/gs/continue"))
    assert request == CallService("/magna/gs/continue", "std_srvs/Trigger", {}, None)
    assert parse_request(frame(op="call_service", service="/magna/sm/mission/get_structure", args={},
                               type="magna_msgs/GetSMStructure")).type == "magna_msgs/GetSMStructure"


def test_an_error_converts_to_a_rosbridge_status():
    status = refusal(command({"intent": 3})).to_status()
    assert status == {"op": "status", "level": "error", "id": "c1",
                      "msg": 'call_service (id "c1"): args.intent is the number 3; give a string'}
    assert "id" not in refusal("[]").to_status()


# --- malformed frames -----------------------------------------------------------------------------------------

@pytest.mark.parametrize(("text", "says"), [
    ("", "not JSON"),
    ("{op: subscribe}", "not JSON"),
    ('{"op": "subscribe", "topic": "/clock"', "not JSON"),
    ('{"op": "subscribe", "topic": "/clock"} {}', "not JSON"),
    ('{"op": "subscribe", "topic": "/clock", "x": NaN}', "NaN"),
    ('{"op": "subscribe", "topic": "/clock", "x": -Infinity}', "-Infinity"),
    ('{"op": "subscribe", "topic": "/clock", "x": 1e999}', "beyond a double's range"),
    ('{"op": "subscribe", "topic": "/clock", "x": ' + "9" * 5000 + "}", "not JSON"),
    ('[{"op": "subscribe", "topic": "/clock"}]', "holds an array"),
    ('"subscribe"', "holds the string"),
    ("null", "holds null"),
    ("42", "holds the number 42"),
    ('{"op": "subscribe", "topic": "/clock", "topic": "/rosout"}', "key topic twice"),
])
def test_frames_that_are_not_one_json_object_are_refused(text, says):
    error = refusal(text)
    assert says in str(error) and error.op is None


def test_binary_frames_are_refused():
    assert "binary" in str(refusal(frame(op="subscribe", topic="/clock").encode()))


def test_a_frame_over_the_size_limit_is_refused_before_parsing():
    padding = "x" * MAX_FRAME_BYTES
    assert "larger than 64 KiB" in str(refusal(frame(op="subscribe", topic="/clock", id=padding)))
    # the limit counts bytes: characters of 3 bytes each reach it with a third of the characters
    wide = "\u20ac" * (MAX_FRAME_BYTES // 3 + 1)
    assert "larger than" in str(refusal(frame(op="subscribe", topic="/clock", id=wide)))


@pytest.mark.parametrize("depth", [17, 200, 100_000 // 2])
def test_deep_nesting_is_refused(depth):
    nested = "[" * depth + "]" * depth
    text = '{"op": "call_service", "service": "/magna/gs/command", "args": {"x": ' + nested + "}}"
    if len(text) > MAX_FRAME_BYTES:
        assert "larger than" in str(refusal(text))
    else:
        assert "nested more than 16 levels" in str(refusal(text))


def test_python_parsers_recursion_limit_is_reported_as_nesting():
    nested = "[" * 30_000 + "]" * 30_000  # under the size limit, far beyond Python's recursion limit
    assert "nested more than" in str(refusal('{"op": "subscribe", "x": ' + nested + "}"))


# --- ops and their fields -------------------------------------------------------------------------------------

@pytest.mark.parametrize("op", ["publish", "advertise", "unadvertise", "advertise_service", "service_response",
                                "set_level", "fragment", "auth", "status"])
def test_rosbridge_ops_other_than_the_three_are_refused(op):
    error = refusal(frame(op=op, id="x1", topic="/magna/gs/critical_event", msg={"data": "x"}))
    assert f"op '{op}' is not allowed" in str(error) and "subscribe, unsubscribe or call_service" in str(error)
    assert error.to_status()["id"] == "x1"  # the page can tell which of its messages was refused


@pytest.mark.parametrize(("message", "says"), [
    ({"topic": "/clock"}, "op is missing; give op: subscribe, unsubscribe or call_service"),
    ({"op": "Subscribe", "topic": "/clock"}, "op 'Subscribe' is unknown"),
    ({"op": ["subscribe"], "topic": "/clock"}, "op is an array"),
    ({"op": None}, "op is null"),
    ({"op": "get_param", "name": "/magna/hyperparameters"}, "is unknown"),
])
def test_a_missing_or_unknown_op_is_refused(message, says):
    assert says in str(refusal(json.dumps(message)))


@pytest.mark.parametrize(("message", "field", "says"), [
    ({"op": "subscribe", "topic": POSE, "latch": True}, "latch", "is not a field of this op"),
    ({"op": "unsubscribe", "topic": POSE, "throttle_rate": 5}, "throttle_rate", "give only op, id, topic"),
    ({"op": "call_service", "service": COMMAND, "timeout": 5}, "timeout", "is not a field"),
    ({"op": "subscribe", "topic": POSE, "compression": "png"}, "compression", 'give "none" or leave it out'),
    ({"op": "subscribe", "topic": POSE, "compression": "cbor"}, "compression", "the string 'cbor'"),
    ({"op": "subscribe", "topic": POSE, "fragment_size": 1000}, "fragment_size", "sends whole messages"),
    ({"op": "subscribe"}, "topic", "is missing"),
    ({"op": "subscribe", "topic": 5}, "topic", "is the number 5"),
    ({"op": "call_service"}, "service", "is missing"),
    ({"op": "subscribe", "topic": POSE, "type": "geometry_msgs/Pose"}, "type", "geometry_msgs/PoseStamped"),
    ({"op": "subscribe", "topic": POSE, "type": "geometry_msgs/msg/PoseStamped"}, "type", "or leave it out"),
    ({"op": "call_service", "service": COMMAND, "type": "std_srvs/Trigger"}, "type",
     '"magna_msgs/GroundStationCommand"'),
    ({"op": "subscribe", "topic": POSE, "throttle_rate": True}, "throttle_rate", "true, a boolean"),
    ({"op": "subscribe", "topic": POSE, "throttle_rate": 100.5}, "throttle_rate", "whole number"),
    ({"op": "subscribe", "topic": POSE, "throttle_rate": "100"}, "throttle_rate", "the string '100'"),
    ({"op": "subscribe", "topic": POSE, "throttle_rate": -1}, "throttle_rate", "from 0 to 60000"),
    ({"op": "subscribe", "topic": POSE, "throttle_rate": 60001}, "throttle_rate", "out of range"),
    ({"op": "subscribe", "topic": POSE, "queue_length": 101}, "queue_length", "from 0 to 100"),
    ({"op": "subscribe", "topic": POSE, "queue_length": False}, "queue_length", "boolean"),
    ({"op": "call_service", "service": COMMAND, "args": ["mission", "standby"]}, "args", "is an array"),
    ({"op": "call_service", "service": COMMAND, "args": None}, "args", "is null"),
])
def test_fields_of_an_op_are_checked(message, field, says):
    error = refusal(json.dumps({"id": "r7", **message}))
    assert error.field == field and says in str(error), str(error)
    assert error.op == message["op"] and error.request_id == "r7"
    assert str(error).startswith(f'{message["op"]} (id "r7"): {field} ')


@pytest.mark.parametrize(("request_id", "says"), [
    (7, "id is the number 7; give the id as a string"),
    (True, "id is true, a boolean"),
    ({"x": 1}, "id is an object"),
    ("", "id is 0 characters long"),
    ("i" * (MAX_ID_LENGTH + 1), f"id is {MAX_ID_LENGTH + 1} characters long; give 1 to {MAX_ID_LENGTH}"),
    ("a\nb", "control or invisible characters"),
    ("a\x00b", "control or invisible characters"),
    ("\u202egnp.exe", "control or invisible characters"),  # right-to-left override
    ("a\u200bb", "control or invisible characters"),  # zero-width space
])
def test_a_bad_id_is_refused_and_not_echoed(request_id, says):
    error = refusal(frame(op="subscribe", id=request_id, topic=POSE))
    assert says in str(error) and error.request_id is None and "id" not in error.to_status()


def test_the_longest_printable_id_is_kept():
    request_id = "subscribe:/uav_1/ual/pose:" + "é" * (MAX_ID_LENGTH - 26)
    assert parse_request(frame(op="subscribe", id=request_id, topic=POSE)).id == request_id


# --- names: only the allow list, exactly ---------------------------------------------------------------------

@pytest.mark.parametrize("topic", [
    "/rosout", "/rosapi/topics", "/magna/gs/command", "/magna/hyperparameters",
    "/uav_1/ual/set_pose", "/uav_1/ual/velocity", "/uav_1/ual/pose/extra", "/magna/sm/uav_1/status",
    "/uav_0/ual/pose", "/uav_01/ual/pose", "/uav_1000/ual/pose", "/uav_-1/ual/pose", "/uav_/ual/pose",
    "/uav_1/ual/../ual/pose", "/uav_1/ual/./pose", "/uav_1//ual/pose", "//uav_1/ual/pose", "/uav_1/ual/pose/",
    "uav_1/ual/pose", "~pose", "/uav_*/ual/pose", "/uav_.*/ual/pose", "/uav_[0-9]/ual/pose", "/uav_1/ual/pos.",
    "/UAV_1/ual/pose", "/uav_1/ual/pose ", " /uav_1/ual/pose", "/uav_1/ual/pose\n", "/uav_1/ual/pose\x00",
    "/uav_1/ual/pose%00", "/uav_\uff11/ual/pose", "/uav_\u0661/ual/pose", "/uav_1/u\u0430l/pose",  # fullwidth
    "/uav_1/ual/pose\u200b", "/clock\u0000", "/CLOCK", "/clock/", "/" + "a" * 300, "",
])
def test_only_allowed_topics_exactly(topic):
    error = refusal(frame(op="subscribe", id="s", topic=topic))
    assert error.field == "topic" and ("is not open to the page" in str(error) or "characters long" in str(error))
    assert str(error).isascii()  # the name is shown escaped: no control or look-alike characters in logs


@pytest.mark.parametrize("service", ["/rosapi/topics", "/rosapi/get_param", "/magna/gs/stop", "/magna/sim/reset",
                                     "/magna/gs/command/", "/magna/gs/command\n", "/magna/gs/comm\u0430nd",
                                     "/uav_1/ual/take_off", "/rosout/get_loggers", "/magna/sm/uav_1/get_structure",
                                     "/magna/gs/*"])
def test_only_allowed_services_exactly(service):
    error = refusal(frame(op="call_service", id="c9", service=service, args={}))
    assert error.field == "service" and "is not open to the page" in str(error)
    assert COMMAND in str(error)  # the fix names the services that are open


def test_a_long_hostile_name_is_cut_short_in_the_message():
    error = refusal(frame(op="subscribe", topic="/" + "<script>" * 30))
    assert len(str(error)) < 600 and "<script>" * 10 not in str(error)


# --- a call's args, field by field ------------------------------------------------------------------------------

@pytest.mark.parametrize(("args", "field", "says"), [
    ({"intent": 3}, "args.intent", "the number 3; give a string"),
    ({"intent": None}, "args.intent", "is null"),
    ({"intent": "x" * (MAX_STRING_LENGTH + 1)}, "args.intent", f"give at most {MAX_STRING_LENGTH}"),
    ({"agent": "1\n2"}, "args.agent", "control or invisible characters"),
    ({"agent": "\ud800"}, "args.agent", "control or invisible characters"),  # a lone surrogate
    ({"speed": 3}, "args.speed", "is not a field of magna_msgs/GroundStationCommand"),
    ({"parameters": {"name": "x"}}, "args.parameters", "give an array of magna_msgs/NamedValue"),
    ({"parameters": [{"name": "x"}] * (MAX_ARRAY_LENGTH + 1)}, "args.parameters", f"at most {MAX_ARRAY_LENGTH}"),
    ({"parameters": ["x"]}, "args.parameters[0]", "give an object with the fields of magna_msgs/NamedValue"),
    ({"parameters": [{"name": "height", "value": 5}]}, "args.parameters[0].value",
     "is not a field of magna_msgs/NamedValue; give only name, number, text, unit"),
    ({"parameters": [{}, {"number": True}]}, "args.parameters[1].number", "true, a boolean; give a number"),
    ({"parameters": [{"number": "5"}]}, "args.parameters[0].number", "the string '5'"),
    ({"parameters": [{"number": 10 ** 400}]}, "args.parameters[0].number", "out of the range of float64"),
    ({"parameters": [{"number": [1]}]}, "args.parameters[0].number", "is an array"),
    ({"parameters": [{"__class__": 1}]}, "args.parameters[0].__class__", "is not a field"),
    ({"__slots__": []}, "args.__slots__", "is not a field"),
])
def test_command_args_are_checked_recursively(args, field, says):
    error = refusal(command(args))
    assert error.field == field and says in str(error), str(error)
    assert str(error).startswith(f'call_service (id "c1"): {field} ')


def test_a_service_without_request_fields_takes_no_args():
    error = refusal(frame(op="call_service", service="/magna/gs/continue", args={"force": True}))
    assert error.field == "args.force" and "give no fields" in str(error)


def test_numbers_are_checked_against_the_ros_types_range():
    from magna_studio.protocol import check_message

    class Ranges:  # a message class as genpy writes one
        _type = "test/Ranges"
        __slots__ = ["small", "unsigned", "single", "flag", "stamp", "span", "raw", "triple"]
        _slot_types = ["int8", "uint32", "float32", "bool", "time", "duration", "uint8[]", "float64[3]"]

    good = {"small": -128, "unsigned": 2 ** 32 - 1, "single": 3.4e38, "flag": False,
            "stamp": {"secs": 1, "nsecs": 999_999_999}, "span": {"secs": -5}, "raw": [0, 255], "triple": [1, 2, 3.5]}
    assert check_message(good, Ranges, "args") == {**good, "single": 3.4e38, "triple": [1.0, 2.0, 3.5]}
    for args, field, says in [
        ({"small": 128}, "args.small", "out of the range of int8"),
        ({"small": 1.5}, "args.small", "give a whole number"),
        ({"unsigned": -1}, "args.unsigned", "out of the range of uint32"),
        ({"single": 3.5e38}, "args.single", "out of the range of float32"),
        ({"flag": 1}, "args.flag", "give true or false"),
        ({"flag": "true"}, "args.flag", "give true or false"),
        ({"stamp": 5}, "args.stamp", 'give the time as {"secs": S, "nsecs": N}'),
        ({"stamp": {"secs": -1}}, "args.stamp.secs", "out of the range of uint32"),
        ({"stamp": {"nsecs": 1_000_000_000}}, "args.stamp.nsecs", "give 0 to 999999999"),
        ({"stamp": {"sec": 1}}, "args.stamp.sec", "give only secs and nsecs"),
        ({"raw": [256]}, "args.raw[0]", "out of the range of uint8"),
        ({"raw": "AAE="}, "args.raw", "give an array of uint8"),  # no base64
        ({"triple": [1, 2]}, "args.triple", "give exactly 3"),
    ]:
        with pytest.raises(ProtocolError) as caught:
            check_message(args, Ranges, "args")
        assert caught.value.field == field and says in str(caught.value), str(caught.value)


def test_a_request_class_that_cannot_be_found_is_reported():
    def missing(service_type):
        raise LookupError(f"no generated class for {service_type}")

    with pytest.raises(ProtocolError) as caught:
        parse_request(command({}), find_request_class=missing)
    assert "args cannot be checked: no generated class for magna_msgs/GroundStationCommand" in str(caught.value)


# --- the connection's budget ------------------------------------------------------------------------------------

class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_the_limiter_allows_a_burst_then_the_rate_and_reports_a_run_of_refusals_once():
    clock = Clock()
    limiter = ConnectionLimiter(messages_per_second=10, burst=5, clock=clock)
    for _ in range(5):
        limiter.admit_message()
    reports = []
    for _ in range(3):
        with pytest.raises(RateLimited) as caught:
            limiter.admit_message()
        reports.append(caught.value.report)
    assert reports == [True, False, False] and "more than 10 messages a second" in str(caught.value)
    clock.now += 0.1  # one message's worth
    limiter.admit_message()
    with pytest.raises(RateLimited) as caught:
        limiter.admit_message()
    assert caught.value.report  # a new run of refusals is reported again
    clock.now += 60.0  # the bucket refills up to the burst, no further
    for _ in range(5):
        limiter.admit_message()
    with pytest.raises(RateLimited):
        limiter.admit_message()


def test_the_limiter_bounds_subscriptions_and_calls_in_flight():
    limiter = ConnectionLimiter(max_subscriptions=2, max_calls_in_flight=1)
    limiter.admit_subscription("/clock", [])
    limiter.admit_subscription("/clock", ["/clock", POSE])  # again: replaces, does not add
    with pytest.raises(ProtocolError) as caught:
        limiter.admit_subscription("/uav_2/ual/pose", ["/clock", POSE])
    assert "at most 2 topics" in str(caught.value) and "unsubscribe" in str(caught.value)
    limiter.start_call()
    with pytest.raises(ProtocolError) as caught:
        limiter.start_call()
    assert "at most 1" in str(caught.value) and "service_response" in str(caught.value)
    limiter.end_call()
    limiter.start_call()
    assert limiter.calls_in_flight == 1


# --- no ROS needed ---------------------------------------------------------------------------------------------

def test_protocol_imports_and_checks_subscriptions_without_ros():
    # A finder that refuses every ROS module, as on a machine without ROS.
    code = """
import importlib.abc, sys
class NoRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in {"rospy", "genpy", "roslib", "rosgraph", "geometry_msgs", "magna_msgs", "std_msgs"}:
            raise ImportError("no ROS here: " + name)
sys.meta_path.insert(0, NoRos())
from magna_studio.protocol import parse_request
print(parse_request('{"op": "subscribe", "topic": "/clock"}').type)
"""
    studio_src = Path(__file__).resolve().parents[1] / "src"
    common_src = Path(__file__).resolve().parents[2] / "magna_common" / "src"
    env = dict(os.environ, PYTHONPATH=f"{studio_src}:{common_src}")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "rosgraph_msgs/Clock"
