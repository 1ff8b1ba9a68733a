"""RosMaster: a private master on a free port that ends exactly what it started."""
import os
import subprocess
import sys
import time
import xmlrpc.client

import pytest

from magna_common.ports import free_port
from magna_common.ros_master import RosMaster, RosMasterError


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie still answers kill(0); it is dead for our purpose.
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


def _wait_dead(pid, timeout=5.0):
    deadline = time.monotonic() + timeout
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not _alive(pid)


def test_two_masters_run_side_by_side_on_different_ports(tmp_path):
    with RosMaster(log_dir=tmp_path / "a") as first, RosMaster(log_dir=tmp_path / "b") as second:
        assert first.port != second.port
        for master in (first, second):
            code, _, _ = xmlrpc.client.ServerProxy(master.uri).getPid("/probe")
            assert code == 1
        # Each answers with its own parameters.
        xmlrpc.client.ServerProxy(first.uri).setParam("/probe", "/who", "first")
        code, _, _ = xmlrpc.client.ServerProxy(second.uri).getParam("/probe", "/who")
        assert code != 1


def test_stop_ends_the_master_and_every_spawned_process_tree(tmp_path):
    master = RosMaster(log_dir=tmp_path).start()
    master_pid = master._master.pid
    # A child that itself starts a grandchild, like roslaunch does.
    script = "import subprocess,sys,time; p=subprocess.Popen([sys.executable,'-c','import time; time.sleep(600)']);" \
             "print(p.pid, flush=True); time.sleep(600)"
    child = master.spawn([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    grandchild_pid = int(child.stdout.readline())
    assert _alive(child.pid) and _alive(grandchild_pid)
    master.stop()
    child.stdout.close()
    assert _wait_dead(master_pid)
    assert _wait_dead(child.pid)
    assert _wait_dead(grandchild_pid)
    assert not master.running


def test_spawned_processes_see_the_private_master(tmp_path):
    with RosMaster(log_dir=tmp_path) as master:
        out = master.spawn([sys.executable, "-c", "import os; print(os.environ['ROS_MASTER_URI'])"],
                           stdout=subprocess.PIPE, text=True)
        assert out.communicate(timeout=10)[0].strip() == master.uri


def test_a_master_can_be_started_and_stopped_again(tmp_path):
    master = RosMaster(log_dir=tmp_path)
    for _ in range(2):
        master.start()
        assert master.running
        master.stop()
        assert not master.running


def test_a_taken_port_is_a_clear_error(tmp_path):
    with RosMaster(log_dir=tmp_path / "a") as first:
        second = RosMaster(port=first.port, start_timeout=3, log_dir=tmp_path / "b")
        try:
            with pytest.raises(RosMasterError, match=f"port {first.port}"):
                second.start()
        finally:
            second.stop()  # should the code regress, leave no master behind
        assert not second.running


def test_spawn_before_start_is_refused():
    with pytest.raises(RosMasterError, match="start the master"):
        RosMaster().spawn(["true"])


def test_free_port_is_bindable():
    import socket

    port = free_port()
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", port))
