"""Warm starts: the command runs on a process prepared ahead, exactly as a cold start would run it."""
import json
import os
import sys
import textwrap

import pytest

from magna_common.processes import pid_alive
from magna_common.warm_start import WarmStarter
from tests.support import wait_until

# What the script reports: its argv, a variable of the environment it was given, where it runs, and whether a
# module it never imports itself was loaded (by the warm process beforehand).
SCRIPT = textwrap.dedent("""\
    import json, os, sys
    print(json.dumps({"argv": sys.argv[1:], "x": os.environ.get("MAGNA_WARM_X"), "cwd": os.getcwd(),
                      "preloaded": "magna_common.records" in sys.modules, "stdin": sys.stdin.read(),
                      "session": os.getsid(0) == os.getpid()}), flush=True)
    print("to stderr", file=sys.stderr, flush=True)
    sys.exit(int(sys.argv[1]))
""")


@pytest.fixture
def starter(tmp_path):
    script = tmp_path / "node.py"
    script.write_text(SCRIPT)
    made = WarmStarter(str(script), ["magna_common.records"])
    yield made
    made.close()


def run(starter, tmp_path, command, name, env=None):
    log = tmp_path / f"{name}.log"
    log.write_text("earlier line\n")  # appended to, never overwritten
    process = starter.start(command, log, env)
    assert process.wait(timeout=60) == int(command[2])
    lines = log.read_text().splitlines()
    return lines[0], json.loads(lines[1]), lines[2:]


def test_a_warm_start_runs_the_script_as_a_cold_one_would_with_its_modules_already_imported(starter, tmp_path,
                                                                                           monkeypatch):
    monkeypatch.chdir(tmp_path)
    starter.prepare()
    env = {**os.environ, "MAGNA_WARM_X": "given"}
    earlier, said, rest = run(starter, tmp_path, [sys.executable, starter.script, "3", "__name:=node"], "warm", env)
    assert earlier == "earlier line" and rest == ["to stderr"]
    assert said == {"argv": ["3", "__name:=node"], "x": "given", "cwd": str(tmp_path), "preloaded": True,
                    "stdin": "", "session": True}
    assert (starter.warm_starts, starter.cold_starts) == (1, 0)
    # nothing prepared: a cold start; prepared later, the next one is warm again
    _, cold, _ = run(starter, tmp_path, [sys.executable, starter.script, "0"], "cold", env)
    assert not cold["preloaded"] and (starter.warm_starts, starter.cold_starts) == (1, 1)
    starter.prepare_in(0.01)
    wait_until(lambda: starter.prepared is not None, "the preparation on its timer")
    _, again, _ = run(starter, tmp_path, [sys.executable, starter.script, "0"], "again", env)
    assert again["preloaded"] and (starter.warm_starts, starter.cold_starts) == (2, 1)


def test_a_command_for_another_script_or_a_dead_warm_process_starts_cold(starter, tmp_path):
    starter.prepare()
    other = tmp_path / "other.py"
    other.write_text(SCRIPT)
    _, said, _ = run(starter, tmp_path, [sys.executable, str(other), "0"], "other")
    assert not said["preloaded"] and (starter.warm_starts, starter.cold_starts) == (0, 1)
    starter.prepare()
    prepared = starter.prepared  # killed before it is used
    prepared.kill()
    prepared.wait()
    _, said, _ = run(starter, tmp_path, [sys.executable, starter.script, "0"], "dead")
    assert not said["preloaded"] and (starter.warm_starts, starter.cold_starts) == (0, 2)


def test_closing_ends_the_prepared_process_and_the_preparation_to_come(starter):
    starter.prepare()
    pid = starter.prepared.pid
    starter.close()
    assert not pid_alive(pid) and starter.prepared is None
    starter.prepare_in(30)
    starter.close()
    assert starter.prepared is None  # the timer was cancelled: nothing is started later


def test_a_warm_rospy_takes_the_remappings_of_the_command_not_those_of_its_import(tmp_path):
    # rospy reads __name:= and the other remappings at its import; a warm node must still get its own name
    script = tmp_path / "named.py"
    script.write_text("import rospy.names\nprint(rospy.names.get_mappings().get('__name'), flush=True)\n")
    starter = WarmStarter(str(script), ["rospy"])
    try:
        starter.prepare()
        log = tmp_path / "named.log"
        process = starter.start([sys.executable, str(script), "__name:=uav_manager_host_1"], log)
        assert process.wait(timeout=60) == 0 and starter.warm_starts == 1
        assert log.read_text().split() == ["uav_manager_host_1"]
    finally:
        starter.close()
