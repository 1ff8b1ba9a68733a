"""Every node script answers `rosrun PKG NODE --help` with its usage and exit status 0, without a ROS master.

The nodes are tests.support.ros_nodes(): scripts under src/*/nodes/, programs installed with
catkin_install_python, and installed C++ programs. ROS_MASTER_URI points at a free port where nothing listens, so a node
that starts ROS before reading its arguments hangs (rospy keeps trying to register) and fails
here at the timeout; its whole process group is ended.
"""
from __future__ import annotations

import os
import signal
import subprocess

import pytest

from magna_common.ports import free_port
from tests.support import ros_nodes

TIMEOUT = 60.0  # s: a guard against a node that waits for a master, not a speed expectation


NODES = ros_nodes()


def test_the_nodes_are_found():
    assert ("magna_sim", "fly") in NODES and ("magna_viz", "scene") in NODES and len(NODES) >= 10


@pytest.mark.parametrize(("package", "node"), NODES, ids=[f"{p}/{n}" for p, n in NODES])
def test_node_help_prints_usage_without_a_master(package, node, tmp_path):
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}", ROS_HOME=str(tmp_path / "ros"),
               ROS_LOG_DIR=str(tmp_path / "log"))
    process = subprocess.Popen(["rosrun", package, node, "--help"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               stdin=subprocess.DEVNULL, text=True, env=env, cwd=tmp_path, start_new_session=True)
    try:
        out, err = process.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        out, err = process.communicate()
        pytest.fail(f"rosrun {package} {node} --help did not end within {TIMEOUT:g} s (does it start ROS before "
                    f"reading its arguments?):\n{out[-2000:]}\n{err[-2000:]}")
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 0, f"exit status {process.returncode}:\n{out[-2000:]}\n{err[-2000:]}"
    assert out.lstrip().lower().startswith("usage: "), out[:500]  # argparse: "usage:", the C++ node: "Usage:"
