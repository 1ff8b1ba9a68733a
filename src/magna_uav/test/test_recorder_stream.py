"""The recorder's stream: rows reach the CSV as they are final, so a manager killed mid-role leaves a readable
file with every row but the step in progress; save_csv to it rewrites it whole and streaming goes on."""
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from magna_uav.recorder import Recorder, read_csv
from magna_uav.world_view import AgentState, WorldView


def flying_view():
    view = WorldView(1, boundaries=[[-10, 10], [-10, 10], [0, 10]])
    view.update_agent(AgentState(1, [0, 0, 1], [0, 0, 0, 1], [1, 0, 0], ual_state=4, battery=0.9))
    return view


def step(recorder, view, t, outcome=""):
    return recorder.record(t, "path", "simple", [5, 0, 1], [0.5, 0, 0], view, outcome=outcome)


def test_a_row_reaches_the_file_when_the_next_one_starts_or_its_role_ends(tmp_path):
    path = tmp_path / "uav_1.csv"
    recorder = Recorder(1, [2])
    view = flying_view()
    step(recorder, view, 0.0)
    recorder.stream_to(path)
    assert read_csv(path)[1] == []  # the header; the first row is still the step in progress
    step(recorder, view, 0.1)
    assert [row["time"] for row in read_csv(path)[1]] == [0.0]
    recorder.set_outcome("succeeded")  # the role ended: its last row, with the outcome, is final
    columns, rows = read_csv(path)
    assert columns == recorder.columns and [(r["time"], r["outcome"]) for r in rows] == [(0.0, ""), (0.1, "succeeded")]


def test_save_csv_to_the_streamed_file_rewrites_it_and_streaming_goes_on(tmp_path):
    path = tmp_path / "uav_1.csv"
    recorder = Recorder(1, [])
    view = flying_view()
    recorder.stream_to(path)
    for t in (0.0, 0.1):
        step(recorder, view, t)
    recorder.set_outcome("preempted")
    recorder.save_csv(path, overwrite=True)
    for t in (0.2, 0.3):
        step(recorder, view, t)
    recorder.set_outcome("succeeded")
    assert [(r["time"], r["outcome"]) for r in read_csv(path)[1]] == [
        (0.0, ""), (0.1, "preempted"), (0.2, ""), (0.3, "succeeded")]
    saved = tmp_path / "saved.csv"
    recorder.save_csv(saved)
    assert saved.read_text() == path.read_text()  # streamed and saved whole: the same file


def test_an_existing_file_is_not_streamed_into_unless_asked(tmp_path):
    path = tmp_path / "uav_1.csv"
    path.write_text("precious\n")
    recorder = Recorder(1, [])
    with pytest.raises(FileExistsError, match="uav_1.csv"):
        recorder.stream_to(path)
    assert path.read_text() == "precious\n"
    recorder.stream_to(path, overwrite=True)
    assert read_csv(path)[1] == []


def test_the_file_honours_the_umask(tmp_path):
    previous = os.umask(0o027)
    try:
        Recorder(1, []).stream_to(tmp_path / "uav_1.csv")
    finally:
        os.umask(previous)
    assert (tmp_path / "uav_1.csv").stat().st_mode & 0o777 == 0o640


def test_a_process_killed_mid_role_leaves_every_final_row(tmp_path):
    """A real SIGKILL: the child records 50 steps, says so, and is killed while it waits in the next role step."""
    path = tmp_path / "uav_1.csv"
    child = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        sys.path[:0] = {sys.path!r}
        from magna_uav.recorder import Recorder
        from magna_uav.world_view import AgentState, WorldView
        view = WorldView(1, boundaries=[[-10, 10], [-10, 10], [0, 10]])
        view.update_agent(AgentState(1, [0, 0, 1], [0, 0, 0, 1], [1, 0, 0], ual_state=4, battery=0.9))
        recorder = Recorder(1, [2])
        recorder.stream_to({str(path)!r})
        for k in range(51):
            recorder.record(k / 10, "path", "simple", [5, 0, 1], [0.5, 0, 0], view)
        print("recorded", flush=True)
        time.sleep(60)
        """)], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "recorded"
        child.send_signal(signal.SIGKILL)
        assert child.wait(10) == -signal.SIGKILL
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(5)
        child.stdout.close()
    _, rows = read_csv(path)
    assert [row["time"] for row in rows] == [k / 10 for k in range(50)]  # all but the step in progress
