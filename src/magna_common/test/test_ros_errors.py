"""rospy's service errors read as the server's reason, without the Python bytes literal."""
from magna_common.ros_errors import service_error_text


def test_the_wrapped_bytes_literal_becomes_the_reason():
    error = RuntimeError("service [/uav_1/ual/land] responded with an error: "
                         "b'service cannot process request: land refused: UAV 1 is landed'")
    assert service_error_text(error) == "/uav_1/ual/land: land refused: UAV 1 is landed"


def test_a_reason_with_non_ascii_text_is_decoded():
    error = RuntimeError("service [/s] responded with an error: b'error processing request: caf\\xc3\\xa9'")
    assert service_error_text(error) == "/s: café"


def test_other_errors_stay_as_they_are():
    assert service_error_text(RuntimeError("timeout exceeded while waiting for service /x")) == (
        "timeout exceeded while waiting for service /x")
