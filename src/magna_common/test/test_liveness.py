"""The managers' watchdog: silence in simulated time, then the process decides; a running one also needs wall
silence. Real processes (a `sleep`) stand for the managers where the process is looked at."""
import signal
import subprocess

import pytest

from magna_common.liveness import BEAT_PERIOD, CHECK_PERIOD, SILENCE_LIMIT, LivenessWatchdog, describe_process
from magna_common.processes import process_state


@pytest.fixture
def sleeper():
    process = subprocess.Popen(["sleep", "60"], start_new_session=True)
    yield process
    if process.poll() is None:
        process.kill()
        process.wait(5)


def test_the_contract_notices_a_silent_manager_well_within_two_simulated_seconds():
    assert BEAT_PERIOD < SILENCE_LIMIT
    # worst case: killed just after a beat, noticed at the first check past the limit
    assert BEAT_PERIOD + SILENCE_LIMIT + CHECK_PERIOD <= 1.0


def test_a_killed_process_is_lost_at_the_first_check_past_the_silence(sleeper):
    watchdog = LivenessWatchdog(lambda uav_id: describe_process(sleeper))
    watchdog.watch(2, sim_now=10.0, wall_now=100.0)
    watchdog.heard(2, 10.4, wall_now=100.0)
    sleeper.send_signal(signal.SIGKILL)
    sleeper.wait(5)
    assert watchdog.check(sim_now=10.4 + SILENCE_LIMIT - 0.01, wall_now=100.0) == []
    [lost] = watchdog.check(sim_now=10.4 + SILENCE_LIMIT + 0.01, wall_now=100.0)  # no wall time needed
    assert (lost.uav_id, lost.last_heard, lost.cause) == (2, 10.4, "killed by SIGKILL")
    assert lost.noticed_at == pytest.approx(10.4 + SILENCE_LIMIT + 0.01)
    assert "UAV 2's manager lost at 11.01 s (silent since 10.40 s): killed by SIGKILL" == lost.describe()
    assert watchdog.check(sim_now=20.0, wall_now=200.0) == []  # reported once
    assert watchdog.lost(2) == lost


def test_a_stopped_process_is_lost_and_a_running_one_only_after_wall_silence_too(sleeper):
    running = {"state": None}
    watchdog = LivenessWatchdog(lambda uav_id: describe_process(sleeper) if uav_id == 1 else running["state"],
                                wall_guard=2.0)
    for uav_id in (1, 2):
        watchdog.watch(uav_id, sim_now=0.0, wall_now=0.0)
    # both silent in simulated time (a loaded machine at high rtf), both processes running: nobody is lost
    assert watchdog.check(sim_now=5.0, wall_now=0.5) == []
    sleeper.send_signal(signal.SIGSTOP)
    try:
        for _ in range(200):  # the stop is asynchronous
            if process_state(sleeper.pid) == "T":
                break
        [lost] = watchdog.check(sim_now=5.1, wall_now=0.6)
        assert lost.uav_id == 1 and lost.cause.startswith("stopped")
    finally:
        sleeper.send_signal(signal.SIGCONT)
    # UAV 2 runs but has been silent for 2 wall s as well: lost, saying so
    [lost] = watchdog.check(sim_now=5.2, wall_now=2.0)
    assert lost.uav_id == 2 and "although its process runs" in lost.cause


def test_beats_keep_a_manager_alive_and_stop_ends_the_watch():
    watchdog = LivenessWatchdog(lambda uav_id: "gone")
    watchdog.watch(1, sim_now=0.0, wall_now=0.0)
    for step in range(1, 50):
        now = step * BEAT_PERIOD
        watchdog.heard(1, now, wall_now=now)
        assert watchdog.check(sim_now=now + CHECK_PERIOD, wall_now=now) == []
    watchdog.heard(1, float("nan"), wall_now=99.0)  # a bad stamp is no beat
    watchdog.heard(1, 1.0, wall_now=99.0)  # nor one older than the last
    [lost] = watchdog.check(sim_now=49 * BEAT_PERIOD + SILENCE_LIMIT + 0.01, wall_now=0.0)
    assert lost.last_heard == 49 * BEAT_PERIOD
    watchdog.watch(3, sim_now=0.0, wall_now=0.0)
    watchdog.stop()  # the end of the mission: the managers stop on purpose
    assert watchdog.check(sim_now=100.0, wall_now=100.0) == []


def test_describe_process_names_exits_and_signals():
    done = subprocess.Popen(["sh", "-c", "exit 3"])
    done.wait(5)
    assert describe_process(done) == "exited with status 3"
    assert LivenessWatchdog(lambda uav_id: None).lost(1) is None
    with pytest.raises(ValueError, match="silence_limit"):
        LivenessWatchdog(lambda uav_id: None, silence_limit=0)
