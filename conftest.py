"""Fixtures shared by every test of the workspace.

`ros_master` starts one private rosmaster on a free port for the test session
and ends it, with every process started through it, at the end; `rospy_node`
joins this test process to that master (rospy allows one node per process).
`fresh_ros_master` gives a test a master of its own, for tests that start and
stop nodes as subprocesses.
"""
import os
import signal
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent


def _ensure_workspace_on_path():
    # The generated messages and the packages' libraries live in the devel space.
    devel_site = ROOT / "devel" / "lib" / "python3" / "dist-packages"
    if devel_site.is_dir() and str(devel_site) not in sys.path:
        sys.path.insert(0, str(devel_site))


_ensure_workspace_on_path()


def _let_ctrl_c_through():
    # A test run started in the background by a shell without job control (`make test &` in a script,
    # a CI step) inherits SIGINT ignored, and every process it starts would too: the tests of Ctrl-C
    # (TensorBoard, launches, the documented [background] commands) would then hang on processes that
    # cannot hear it. A handler here is reset to the default in each child at exec.
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


_let_ctrl_c_through()


@pytest.fixture(scope="session")
def ros_master(tmp_path_factory):
    from magna_common.ros_master import RosMaster

    master = RosMaster(log_dir=tmp_path_factory.mktemp("ros_log"))
    with master:
        yield master


@pytest.fixture(scope="session")
def rospy_node(ros_master):
    import rospy

    os.environ.update(ros_master.env())
    rospy.init_node("magna_pytest", anonymous=True, disable_signals=True)
    yield rospy
    rospy.signal_shutdown("pytest session finished")


@pytest.fixture
def fresh_ros_master(tmp_path):
    from magna_common.ros_master import RosMaster

    with RosMaster(log_dir=tmp_path / "ros_log") as master:
        yield master


@pytest.fixture(scope="session")
def recorded_run(tmp_path_factory):
    """One real simulation, flown once per session (tests/recorded_run.py): mlr and magna_viz read it."""
    from tests.recorded_run import record_run

    return record_run(tmp_path_factory.mktemp("recorded_run"))
