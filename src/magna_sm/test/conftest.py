"""Fixtures of magna_sm's ROS tests."""
import re

import pytest


@pytest.fixture
def ns(request):
    """A ROS namespace of this test's own, so tests sharing the session's node never cross."""
    module = request.module.__name__.rsplit(".", 1)[-1]
    return f"/{module}/" + re.sub(r"[^A-Za-z0-9_]", "_", request.node.name)
