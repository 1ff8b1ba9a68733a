"""Errors of ROS services as people should read them (no ROS import: the text is all there is)."""
from __future__ import annotations

import ast
import re

# rospy: "service [/uav_1/ual/land] responded with an error: b'service cannot process request: <reason>'"
_WRAPPED = re.compile(r"service \[(?P<name>[^\]]*)\] responded with an error: (?P<reason>.*)", re.S)
_SERVER_PREFIXES = ("service cannot process request: ", "error processing request: ")


def service_error_text(error: BaseException) -> str:
    """`/uav_1/ual/land: land refused: ...` for rospy's wrapped form with its Python bytes literal;
    any other error as it is."""
    text = str(error)
    match = _WRAPPED.fullmatch(text)
    if match is None:
        return text
    reason = match["reason"]
    if reason[:2] in ("b'", 'b"'):
        try:
            reason = ast.literal_eval(reason).decode("utf-8", "replace")
        except (ValueError, SyntaxError, AttributeError):
            pass
    for prefix in _SERVER_PREFIXES:
        reason = reason.removeprefix(prefix)
    return f"{match['name']}: {reason}"
