"""The message API: GRVC UAL v3 checksums, and every magna_msgs type built, serialized and read back."""
import importlib
import io
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

# Literal values from GRVC UAL v3 (the list), not imported from our code.
UAL_MD5 = {
    ("msg", "State"): "533576484916e98b63315c3434a12ab9",
    ("srv", "TakeOff"): "92f7691c5527d6fb3cc35d20a69e7778",
    ("srv", "Land"): "c37d0c321494079f6ac6aae0680a10e1",
    ("srv", "GoToWaypoint"): "1b4a030ed9ba0e5a2761567aa99a96b7",
    ("srv", "GoToWaypointGeo"): "a636a108541a3b824065d8407258fbe8",
    ("srv", "SetHome"): "27f767d7f04b6ba462fa116e03c0b202",
}


@pytest.mark.parametrize(("kind", "name"), sorted(UAL_MD5))
def test_ual_types_have_grvc_checksums(kind, name):
    module = importlib.import_module(f"uav_abstraction_layer.{kind}")
    assert getattr(module, name)._md5sum == UAL_MD5[(kind, name)]


def test_ual_state_constants_in_grvc_order():
    from uav_abstraction_layer.msg import State

    names = ["UNINITIALIZED", "LANDED_DISARMED", "LANDED_ARMED", "TAKING_OFF",
             "FLYING_AUTO", "FLYING_MANUAL", "LANDING"]
    assert [getattr(State, n) for n in names] == list(range(7))
    assert State.__slots__ == ["state"]


def test_ual_float32param_exists_with_one_field():
    from uav_abstraction_layer.srv import Float32ParamRequest

    assert Float32ParamRequest.__slots__ == ["param"]
    assert Float32ParamRequest._slot_types == ["float32"]


def _definitions(kind):
    return sorted(p.stem for p in (ROOT / "src" / "magna_msgs" / kind).glob(f"*.{kind}"))


def _roundtrip(msg):
    buffer = io.BytesIO()
    msg.serialize(buffer)
    copy = type(msg)()
    copy.deserialize(buffer.getvalue())
    return copy


def _filled(msg_type):
    """An instance with a recognisable value in every top-level primitive field."""
    msg = msg_type()
    for slot, slot_type in zip(msg.__slots__, msg._slot_types, strict=True):
        if slot_type == "string[]":
            setattr(msg, slot, ["a", "b"])
        elif slot_type == "float64[]":
            setattr(msg, slot, [0.5, -2.0])
        elif slot_type == "bool[]":
            setattr(msg, slot, [True, False])
        elif slot_type == "uint8[]":  # rospy hands a uint8[] over as bytes
            setattr(msg, slot, bytes([7, 8]))
        elif slot_type.startswith(("int", "uint")) and slot_type.endswith("[]"):
            setattr(msg, slot, [7, 8])
        elif slot_type == "string":
            setattr(msg, slot, f"{slot}-value")
        elif slot_type == "bool":
            setattr(msg, slot, True)
        elif slot_type.startswith("float"):
            setattr(msg, slot, 1.5)
        elif slot_type.startswith(("int", "uint")):
            setattr(msg, slot, 7)
    return msg


def _assert_every_field_documented(path):
    for line in path.read_text().splitlines():
        code = line.split("#", 1)[0].strip()
        if code and code != "---" and "=" not in code:
            assert "#" in line, f"{path.name}: field '{code}' has no comment"


@pytest.mark.parametrize("name", _definitions("msg"))
def test_magna_messages_roundtrip_and_are_documented(name):
    msg_type = getattr(importlib.import_module("magna_msgs.msg"), name)
    msg = _filled(msg_type)
    assert _roundtrip(msg) == msg
    _assert_every_field_documented(ROOT / "src" / "magna_msgs" / "msg" / f"{name}.msg")


@pytest.mark.parametrize("name", _definitions("srv"))
def test_magna_services_roundtrip_and_are_documented(name):
    module = importlib.import_module("magna_msgs.srv")
    for part in ("Request", "Response"):
        msg = _filled(getattr(module, f"{name}{part}"))
        assert _roundtrip(msg) == msg
    _assert_every_field_documented(ROOT / "src" / "magna_msgs" / "srv" / f"{name}.srv")


@pytest.mark.parametrize("name", _definitions("action"))
def test_magna_actions_have_feedback_and_outcome(name):
    module = importlib.import_module("magna_msgs.msg")
    for part in ("Action", "ActionGoal", "ActionResult", "ActionFeedback", "Goal", "Result", "Feedback"):
        assert hasattr(module, f"{name}{part}"), f"{name}{part} was not generated"
    feedback = getattr(module, f"{name}Feedback")(percent_complete=42.0)
    feedback.current_target.x = 3.0
    assert _roundtrip(feedback) == feedback
    result = getattr(module, f"{name}Result")(outcome="collision", message="hit uav 2")
    assert _roundtrip(result).outcome == "collision"
    _assert_every_field_documented(ROOT / "src" / "magna_msgs" / "action" / f"{name}.action")


def test_required_services_exist():
    module = importlib.import_module("magna_msgs.srv")
    for name in ("StateActualization", "Die", "SimulationTermination", "AlgorithmControl", "GroundStationCommand",
                 "AddWorldPart", "GetFreeSpacePoseSet", "DeleteWorldPart", "SpawnModel", "DeleteModel",
                 "OrcaComputeVelocity", "OrcaComputeVelocities"):
        assert hasattr(module, name), name


def test_typed_messages_cross_a_live_master(rospy_node):
    """A ground-station command with named parameters survives a real service call."""
    from magna_msgs.msg import NamedValue
    from magna_msgs.srv import GroundStationCommand, GroundStationCommandResponse

    rospy = rospy_node
    seen = []

    def handle(request):
        seen.append(request)
        return GroundStationCommandResponse(accepted=True, message="ok",
                                            values=[NamedValue(name="battery", number=0.8, unit="%")])

    server = rospy.Service("/magna/test/command", GroundStationCommand, handle)
    try:
        rospy.wait_for_service("/magna/test/command", timeout=10)
        call = rospy.ServiceProxy("/magna/test/command", GroundStationCommand)
        answer = call(intent="basic_action", action="move", agent="2",
                      parameters=[NamedValue(name="direction", text="up"),
                                  NamedValue(name="distance", number=5.0, unit="m")])
    finally:
        server.shutdown()
    assert answer.accepted and answer.values[0].number == pytest.approx(0.8)
    assert seen[0].agent == "2"
    assert [(p.name, p.text, p.number) for p in seen[0].parameters] == [("direction", "up", 0.0),
                                                                         ("distance", "", 5.0)]
