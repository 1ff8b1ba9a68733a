"""SupervisorCore without ROS: reports, crashes, time limits, interruptions and the processes it ends."""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from magna_common.records import SimulationResult
from magna_common.ros_names import GS_STOP, MASTER_TERMINATION
from magna_master import supervisor as sv
from magna_master.supervisor import SupervisorCore, Termination
from tests.support import WAIT, wait_until

SLEEPER = [sys.executable, "-c", "import time; time.sleep(600)"]


def core_for(tmp_path, command, **kwargs):
    kwargs.setdefault("shutdown_timeout", 2.0)
    kwargs.setdefault("settle", 0.5)
    return SupervisorCore(command, tmp_path / "result.json", tmp_path / "logs" / "launch.log",
                          data_dir=tmp_path, known=SimulationResult(id=4, seed=9), **kwargs)


def later(seconds, action):
    timer = threading.Timer(seconds, action)
    timer.start()
    return timer


def written(tmp_path):
    return SimulationResult.read(tmp_path / "result.json")


def in_background(core):
    """Run `core` in a thread; its result lands in the returned dict under "result"."""
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.setdefault("result", core.run()), daemon=True)
    thread.start()
    return thread, outcome


def launch_log_says(tmp_path, text):
    log = tmp_path / "logs" / "launch.log"
    return log.is_file() and text in log.read_text()


def test_the_ground_station_report_is_the_result(tmp_path, leak_token):
    core = core_for(tmp_path, SLEEPER)
    acknowledged, moments = [], {}

    def report():
        wait_until(lambda: core.launch is not None, "the launch to start")
        moments["launched"] = time.monotonic()  # the run's clock started before this
        time.sleep(0.5)  # the scenario, not a synchronisation: the ground station reports half a second in
        moments["reporting"] = time.monotonic()
        acknowledged.append(core.on_termination(Termination(True, "succeeded", "all good", 42.5, 0)))
        moments["reported"] = time.monotonic()
        # Recorded before it is acknowledged: result.json exists already, marked not final.
        acknowledged.append(written(tmp_path).final)

    threading.Thread(target=report, daemon=True).start()
    moments["run"] = time.monotonic()  # the run's clock starts after this
    result = core.run()
    moments["returned"] = time.monotonic()
    assert acknowledged == [True, False]
    assert result == written(tmp_path)
    assert result.termination == sv.GROUND_STATION and result.final is True
    assert (result.success, result.outcome, result.message) == (True, "succeeded", "all good")
    assert (result.sim_duration, result.collisions, result.id, result.seed) == (42.5, 0, 4, 9)
    # The wall time runs from the launch to the report (rounded to ms), not to the end of the shutdown that
    # followed: the settle time alone, waited for a launch that does not end, comes after the report.
    rounding = 0.0005
    assert moments["reporting"] - moments["launched"] - rounding <= result.wall_time
    assert result.wall_time <= moments["reported"] - moments["run"] + rounding
    assert moments["returned"] - moments["reporting"] >= core.settle
    assert result.launch_exit_code is not None and not sv.pid_alive(result.launch_pid)


def test_a_second_report_does_not_replace_the_first(tmp_path, leak_token):
    core = core_for(tmp_path, SLEEPER)
    later(0.3, lambda: (core.on_termination(Termination(True, "succeeded", "first", 1.0, 0)),
                        core.on_termination(Termination(False, "aborted", "second", 2.0, 3))))
    result = core.run()
    assert (result.outcome, result.message) == ("succeeded", "first")


def test_a_launch_that_ends_by_itself_after_reporting_is_not_killed(tmp_path, leak_token):
    reported = tmp_path / "reported"
    # The launch ends by itself once the report is in (as roslaunch does when the ground station exits).
    launch = [sys.executable, "-c", f"import os, time\nwhile not os.path.exists({str(reported)!r}): time.sleep(0.01)"]
    core = core_for(tmp_path, launch, settle=600.0)  # forcing it would take the whole settle time

    def report():
        wait_until(lambda: core.launch is not None, "the launch to start")
        core.on_termination(Termination(True, "succeeded", "", 1.0, 0))
        reported.touch()

    threading.Thread(target=report, daemon=True).start()
    thread, outcome = in_background(core)
    wait_until(lambda: not thread.is_alive(), "the run to end once the launch ended by itself", timeout=5 * WAIT)
    result = outcome["result"]
    assert result.termination == sv.GROUND_STATION
    assert result.launch_exit_code == 0  # it exited on its own within the settle time, not by a signal


def test_a_launch_that_exits_without_reporting_crashed(tmp_path, leak_token):
    command = [sys.executable, "-c", "print('node [magna_sim] died: pybullet error', flush=True); raise SystemExit(3)"]
    result = core_for(tmp_path, command).run()
    assert result.termination == sv.CRASHED and result.outcome == "crashed" and not result.success
    assert result.launch_exit_code == 3
    assert "status 3" in result.message and MASTER_TERMINATION in result.message
    assert "pybullet error" in result.message  # the tail of launch.log says why


def test_the_time_limit_asks_the_ground_station_to_stop_then_ends_it(tmp_path, leak_token):
    asked = []
    core = core_for(tmp_path, SLEEPER, time_limit=0.5, stop_grace=0.5,
                    stop_ground_station=lambda: asked.append(time.monotonic()) or True)
    started = time.monotonic()
    result = core.run()
    assert len(asked) == 1 and asked[0] - started >= 0.5
    assert result.termination == sv.TIME_LIMIT and result.outcome == "time_limit" and result.timed_out
    assert result.gs_stop_called and f"{GS_STOP} was called" in result.message
    assert not result.success and not sv.pid_alive(result.launch_pid)


def test_a_ground_station_that_reports_when_stopped_keeps_its_outcome(tmp_path, leak_token):
    # A grace period no test could wait out: the run ends only if the report ends the grace period early.
    core = core_for(tmp_path, SLEEPER, time_limit=0.3, stop_grace=600.0)
    core.stop_ground_station = lambda: core.on_termination(Termination(False, "preempted", "stopped", 7.0, 0))
    thread, outcome = in_background(core)
    wait_until(lambda: not thread.is_alive(), "the report to end the grace period", timeout=5 * WAIT)
    result = outcome["result"]
    assert (result.termination, result.outcome, result.sim_duration) == (sv.TIME_LIMIT, "preempted", 7.0)
    assert "stopped" in result.message and not result.success


def test_a_ground_station_still_starting_is_asked_again_until_its_stop_service_answers(tmp_path, leak_token):
    asked = []

    def stop_service_up_at_the_third_call():
        asked.append(time.monotonic())
        return len(asked) >= 3  # not served yet twice: the ground station was still starting

    core = core_for(tmp_path, SLEEPER, time_limit=0.3, stop_grace=5.0,
                    stop_ground_station=stop_service_up_at_the_third_call)
    result = core.run()
    assert len(asked) == 3 and result.gs_stop_called
    assert asked[1] - asked[0] >= sv.STOP_RETRY * 0.9


def test_without_a_stop_service_the_message_says_so(tmp_path, leak_token):
    result = core_for(tmp_path, SLEEPER, time_limit=0.3, stop_grace=0.2).run()
    assert not result.gs_stop_called and "is not served" in result.message


def test_a_stop_request_interrupts(tmp_path, leak_token):
    core = core_for(tmp_path, SLEEPER)
    later(0.3, core.request_stop)
    result = core.run()
    assert (result.termination, result.outcome, result.success) == (sv.INTERRUPTED, "interrupted", False)
    assert not sv.pid_alive(result.launch_pid)


def test_a_launch_that_ignores_sigint_and_sigterm_is_killed(tmp_path, leak_token):
    deaf = [sys.executable, "-c", "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
            "signal.signal(signal.SIGTERM, signal.SIG_IGN); print('deaf', flush=True); time.sleep(600)"]
    core = core_for(tmp_path, deaf, shutdown_timeout=0.5)

    def stop_once_deaf():  # a stop before the handlers are in would end it by SIGINT, proving nothing
        wait_until(lambda: launch_log_says(tmp_path, "deaf"), "the launch to ignore SIGINT and SIGTERM")
        core.request_stop()

    threading.Thread(target=stop_once_deaf, daemon=True).start()
    result = core.run()
    assert result.launch_exit_code == -signal.SIGKILL


def test_processes_in_sessions_of_their_own_are_found_by_the_token(tmp_path, leak_token, monkeypatch):
    """roslaunch puts every node in a session of its own: ending its group is not enough."""
    token = "sim-token-for-this-test"
    monkeypatch.setenv(sv.TOKEN_ENV, token)
    script = ("import subprocess, sys, time; p = subprocess.Popen([sys.executable, '-c', 'import time; "
              "time.sleep(600)'], start_new_session=True); print(p.pid, flush=True); time.sleep(600)")
    core = core_for(tmp_path, [sys.executable, "-c", script], token=token)

    def report_once_the_child_runs():  # its pid in the log: the child exists
        wait_until(lambda: launch_log_says(tmp_path, "\n"), "the launch to start its child")
        core.on_termination(Termination(True, "succeeded", "", 1.0, 0))

    threading.Thread(target=report_once_the_child_runs, daemon=True).start()
    result = core.run()
    orphan = int((tmp_path / "logs" / "launch.log").read_text().split()[0])
    assert not sv.pid_alive(orphan)
    assert any(entry.startswith(f"{orphan} ") for entry in result.leftover_processes_killed)


def test_a_command_that_cannot_start_is_reported(tmp_path):
    result = core_for(tmp_path, ["/nonexistent/roslaunch"]).run()
    assert result.termination == sv.START_FAILED and "cannot start '/nonexistent/roslaunch'" in result.message
    assert written(tmp_path).termination == sv.START_FAILED


def test_the_result_lists_the_ground_station_files(tmp_path, leak_token):
    (tmp_path / "uav_1.csv").write_text("x")
    (tmp_path / "simulation.bag").write_text("x")
    result = core_for(tmp_path, [sys.executable, "-c", "pass"]).run()
    assert list(result.files) == ["simulation.bag", "uav_1.csv"]  # not result.json, not logs/


def test_kill_tagged_ends_exactly_the_tagged_processes(leak_token):
    env = {**os.environ, sv.TOKEN_ENV: "victim"}
    tagged = subprocess.Popen(SLEEPER, env=env, start_new_session=True)
    other = subprocess.Popen(SLEEPER, env={**os.environ, sv.TOKEN_ENV: "bystander"}, start_new_session=True)
    try:
        killed = sv.kill_tagged("victim")
        assert tagged.wait(timeout=5) == -signal.SIGKILL
        assert [entry.split()[0] for entry in killed] == [str(tagged.pid)]
        assert other.poll() is None
    finally:
        for process in (tagged, other):
            process.kill()
            process.wait()


def test_log_tail_is_one_short_line(tmp_path):
    log = tmp_path / "launch.log"
    log.write_text("\n".join(f"line {i}" for i in range(100)) + "\n\n")
    assert sv.log_tail(log, lines=3) == "line 97 | line 98 | line 99"
    assert sv.log_tail(tmp_path / "missing.log") == ""


def test_the_command_line_needs_a_command():
    with pytest.raises(SystemExit):
        sv.parse_args(["--result", "r.json", "--log", "l.log"])
    args = sv.parse_args(["--result", "r.json", "--log", "l.log", "--extra", '{"id": 3}', "--", "roslaunch", "x"])
    assert args.command == ["roslaunch", "x"] and args.extra == {"id": 3}
