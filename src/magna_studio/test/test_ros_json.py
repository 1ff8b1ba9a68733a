"""ROS messages to JSON-ready data and back, with the real generated classes."""
import io
import json
import math

import genpy
import pytest
from geometry_msgs.msg import PoseStamped
from magna_msgs.msg import NavigationStep, SMStatus
from magna_msgs.srv import GroundStationCommand, GroundStationCommandRequest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, CompressedImage

from magna_studio import allowed
from magna_studio.protocol import parse_request
from magna_studio.ros_json import (
    FieldType,
    dict_to_message,
    field_type,
    message_class,
    message_to_dict,
    request_class,
    service_class,
)


def pose(x=1.5, y=-2.0, z=3.25, frame_id="map"):
    msg = PoseStamped()
    msg.header.seq = 4
    msg.header.stamp = genpy.Time(12, 500_000_000)
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.w = 1.0
    return msg


def test_a_pose_as_json():
    assert message_to_dict(pose()) == {
        "header": {"seq": 4, "stamp": {"secs": 12, "nsecs": 500_000_000}, "frame_id": "map"},
        "pose": {"position": {"x": 1.5, "y": -2.0, "z": 3.25},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}


def test_a_pose_goes_there_and_back():
    original = pose(frame_id="uav_1")
    again = dict_to_message(PoseStamped, message_to_dict(original))
    assert again == original and isinstance(again.header.stamp, genpy.Time)


def test_a_navigation_step_with_nan_becomes_null_and_its_time_arrays_stay_exact():
    step = NavigationStep()
    step.row, step.role_number, step.role, step.algorithm = 17, 2, "agent_ad", "orca3d"
    step.goal.x = step.goal.y = step.goal.z = math.nan
    step.goal_distance = math.inf
    step.selected_velocity.x = 0.5
    step.feasible, step.fallback = NavigationStep.FEASIBLE, NavigationStep.FALLBACK_UNKNOWN
    step.uav_ids = [1, 3]
    step.pose_stamps = [genpy.Time(5, 1), genpy.Time(4, 999_999_999)]
    step.velocity_stamps = [genpy.Time(0, 0), genpy.Time(4, 2)]
    data = message_to_dict(step)
    assert data["role"] == "agent_ad" and data["row"] == 17 and data["role_number"] == 2
    assert data["goal"] == {"x": None, "y": None, "z": None} and data["goal_distance"] is None
    assert data["selected_velocity"] == {"x": 0.5, "y": 0.0, "z": 0.0}
    assert (data["feasible"], data["fallback"]) == (1, -1)
    assert data["uav_ids"] == [1, 3]
    assert data["pose_stamps"] == [{"secs": 5, "nsecs": 1}, {"secs": 4, "nsecs": 999_999_999}]
    text = json.dumps(data, allow_nan=False)  # strict JSON: no NaN left anywhere
    assert json.loads(text) == data
    again = dict_to_message(NavigationStep, data)  # null reads back as NaN
    assert math.isnan(again.goal.x) and math.isnan(again.goal_distance) and again.pose_stamps == step.pose_stamps


def test_a_received_message_converts_as_a_built_one():
    # What rospy hands the bridge: a message deserialised from the wire (bytes for uint8[], str for strings).
    image = CompressedImage(format="png", data=bytes([0, 7, 255]))
    buffer = io.BytesIO()
    image.serialize(buffer)
    received = CompressedImage().deserialize(buffer.getvalue())
    assert isinstance(received.data, bytes)
    assert message_to_dict(received)["data"] == [0, 7, 255] and message_to_dict(received)["format"] == "png"
    assert dict_to_message(CompressedImage, message_to_dict(received)).data == bytes([0, 7, 255])


def test_float32_arrays_and_clock():
    battery = BatteryState(percentage=0.5, cell_voltage=[4.0, float("nan")], present=True)
    data = message_to_dict(battery)
    assert data["percentage"] == 0.5 and data["cell_voltage"] == [4.0, None] and data["present"] is True
    assert message_to_dict(Clock(clock=genpy.Time(3, 4))) == {"clock": {"secs": 3, "nsecs": 4}}
    assert message_to_dict(SMStatus(active_states=["a", "b"]))["active_states"] == ["a", "b"]


def test_a_command_request_from_checked_args():
    text = json.dumps({"op": "call_service", "id": "c1", "service": "/magna/gs/command",
                       "args": {"intent": "basic_action", "action": "take_off", "agent": "2",
                                "parameters": [{"name": "height", "number": 7, "unit": "m"},
                                               {"name": "direction", "text": "up"}]}})
    request = dict_to_message(request_class("magna_msgs/GroundStationCommand"), parse_request(text).args)
    assert isinstance(request, GroundStationCommandRequest)
    assert (request.intent, request.action, request.agent) == ("basic_action", "take_off", "2")
    height, direction = request.parameters
    assert (height.name, height.number, height.text, height.unit) == ("height", 7.0, "", "m")
    assert isinstance(height.number, float)
    assert (direction.name, direction.number, direction.text) == ("direction", 0.0, "up")
    buffer = io.BytesIO()
    request.serialize(buffer)  # the request is fit for the wire
    assert GroundStationCommandRequest().deserialize(buffer.getvalue()) == request


def test_absent_fields_keep_their_defaults_and_unknown_ones_are_refused():
    request = dict_to_message(GroundStationCommandRequest, {"intent": "mission"})
    assert request.intent == "mission" and request.action == "" and request.parameters == []
    with pytest.raises(ValueError, match="magna_msgs/GroundStationCommandRequest has no field 'speed'"):
        dict_to_message(GroundStationCommandRequest, {"speed": 1})


def test_a_response_as_json():
    from magna_msgs.msg import NamedValue

    response = GroundStationCommand._response_class(accepted=False, message="UAV 3 is not in this mission",
                                                    values=[NamedValue(name="uav_1.battery", number=87.5, unit="%")])
    assert message_to_dict(response) == {
        "accepted": False, "message": "UAV 3 is not in this mission",
        "values": [{"name": "uav_1.battery", "number": 87.5, "text": "", "unit": "%"}]}


def test_field_types_as_genpy_writes_them():
    assert field_type("float64") == FieldType("float64")
    assert field_type("uint32[]") == FieldType("uint32", True, None)
    assert field_type("float64[9]") == FieldType("float64", True, 9)
    assert field_type("geometry_msgs/Point") == FieldType("geometry_msgs/Point")
    assert field_type("Header") == FieldType("std_msgs/Header")
    assert field_type("uint8[]").is_bytes and field_type("char[4]").is_bytes and not field_type("int8[]").is_bytes
    for bad in ("float64[-1]", "pkg/Name/extra", "", "a b"):
        with pytest.raises(ValueError):
            field_type(bad)


def test_every_allowed_type_has_its_generated_class():
    for topic in allowed.TOPICS:
        assert message_class(topic.type)._type == topic.type
    for service in allowed.SERVICES.values():
        assert service_class(service.type)._type == service.type


def test_type_names_are_checked_before_any_import():
    for bad in ("os/path", "magna_msgs/NoSuchMessage", "no_such_pkg/Thing", "../x/y", "geometry_msgs", "a/b/c"):
        with pytest.raises(LookupError):
            message_class(bad)
