"""bench/process_usage.py: the processes of a tree are found through /proc's parent pids, down to grandchildren,
put in their kind by command line (as `magna run`'s processes read), and their CPU and resident memory counted."""
import subprocess
import sys
import textwrap

import pytest

from tests.support import ROOT, load_module

MB = 1_000_000


@pytest.fixture(scope="module")
def usage_module():
    return load_module(ROOT / "bench" / "process_usage.py", "bench_process_usage")


@pytest.mark.parametrize("cmdline, kind", [
    ("/usr/bin/python3 /usr/bin/rosmaster --core -p 46363 -w 3", "master"),
    ("/work/main/.venv/bin/python -m magna_master.stack_server --rtf max", "supervisor / stack server"),
    ("/work/main/.venv/bin/python -m magna_master.supervisor --result r.json -- roslaunch magna_gs simulation.launch",
     "supervisor / stack server"),
    ("/usr/bin/python3 /usr/bin/roslaunch --sigint-timeout=5 magna_gs stack.launch rtf:=max", "roslaunch"),
    ("/usr/bin/python3 /work/main/devel/lib/magna_sim/sim __name:=magna_sim __log:=/tmp/l.log", "sim"),
    ("/usr/bin/python3 /work/main/devel/lib/magna_worlds/world __name:=magna_world __log:=/tmp/l.log", "world"),
    ("/work/main/devel/lib/magna_orca_cpp/orca3d_server __name:=orca3d_server", "orca"),
    ("/work/main/.venv/bin/python /work/main/devel/lib/magna_gs/ground_station __name:=ground_station",
     "ground station"),
    ("/usr/bin/python3 /work/main/devel/lib/magna_uav/uav_manager_host __name:=uav_manager_host",
     "managers (host or processes)"),
    ("/usr/bin/python3 /work/main/devel/lib/magna_uav/uav_manager __name:=uav_2_manager _id:=2",
     "managers (host or processes)"),
    ("/work/main/.venv/bin/python -m magna_common.warm_start magna_gs.ros_node", "ground station"),
    ("/work/main/.venv/bin/python -m magna_common.warm_start magna_uav.host_node", "managers (host or processes)"),
    ("/usr/lib/rosbag/record --quiet -O /d/simulation.bag /tf /tf_static", "rosbag"),
    ("bash /usr/bin/rosrun magna_uav uav_manager_host __name:=uav_manager_host", "rosrun start-up"),
    ("/usr/bin/python3 /usr/bin/catkin_find --without-underlays --libexec --share magna_uav", "rosrun start-up"),
    ("dot -Tpng", "reports (graphviz)"),
    ("/usr/bin/python3 /tmp/hog.py --size 3", "other (hog.py)"),
    ("", "other"),
])
def test_kinds_by_command_line(usage_module, cmdline, kind):
    assert usage_module.kind_of(cmdline) == kind


def test_a_grandchild_is_found_and_its_cpu_and_memory_counted(usage_module, tmp_path):
    hog = tmp_path / "hog.py"
    hog.write_text(textwrap.dedent("""
        import sys, time
        held = bytearray(80_000_000)  # resident once touched
        for i in range(0, len(held), 4096):
            held[i] = 1
        while time.process_time() < 0.3:
            pass
        print("ready", time.process_time(), flush=True)
        sys.stdin.read()  # holds until the test closes its end
    """))
    # bash -> a subshell -> python: the trailing `true`s keep bash from exec'ing the next one in its place
    root = subprocess.Popen(["bash", "-c", f"( {sys.executable} {hog}; true ); true"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        cpu_before_ready = float(root.stdout.readline().split()[1])
        sampler = usage_module.ProcessSampler(root.pid)
        sampler.sample()
    finally:
        root.stdin.close()
        root.wait(timeout=60)
    usage = sampler.usage()
    kind = "other (hog.py)"
    assert usage.processes[kind] == 1
    assert usage.processes[usage_module.ROOT_KIND] == 1
    assert usage.cpu_s[kind] >= cpu_before_ready - 0.02  # whole clock ticks
    assert usage.peak.rss[kind] >= 80 * MB
    assert usage_module.ROOT_KIND not in usage.peak.rss  # the root's memory is not the simulation's
