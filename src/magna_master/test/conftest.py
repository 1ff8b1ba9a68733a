"""Fixtures of the batch tests: the corpus pair, a stand-in ground station and a leak check."""
import os
import signal
import sys
import time
import uuid
from pathlib import Path

import pytest

from tests.support import CORPUS

HERE = Path(__file__).resolve().parent
STAND_IN = HERE / "stand_in_gs.py"
WORLD = "Gym/1Obs_Central_Cylinder"  # the original's default pair (corpus README)
MISSION = "Gym/2UAVs_2paths_Central_Cylinder"
LEAK_ENV = "MAGNA_MASTER_TEST_TOKEN"


def stand_in_command(mode: str = "ok", sleep: float = 0.2, fail_seeds: str = "", extra=()) -> list[str]:
    """A launch command that runs the stand-in ground station with the batch's placeholders."""
    return [sys.executable, str(STAND_IN), "--mode", mode, "--sleep", str(sleep), "--fail-seeds", fail_seeds,
            "--data-dir", "{data_dir}", "--seed", "{seed}", "--bag", "{bag}", "--save-data", "{save_data}",
            "--mission-file", "{mission_file}", "--world", "{world}", "--subworld", "{subworld}",
            "--worlds-path", "{worlds_path}", "--rtf", "{rtf}", *extra]


def tagged(token: str) -> list[tuple[int, str]]:
    from magna_common.processes import tagged_processes

    return tagged_processes(LEAK_ENV, token, exclude={os.getpid()})


@pytest.fixture
def stand_in():
    """stand_in_command, as a fixture (test modules cannot import this conftest under importlib mode)."""
    return stand_in_command


@pytest.fixture
def corpus():
    # A missing corpus fails these tests, as everywhere else in the suite: a skip would hide them.
    assert (CORPUS / "Worlds").is_dir(), f"no corpus at {CORPUS}; set MAGNA_CORPUS to ros_magna_corpus"
    return CORPUS


@pytest.fixture
def leak_token(monkeypatch):
    """Every process started during the test carries this token; none may be alive at its end."""
    token = uuid.uuid4().hex
    monkeypatch.setenv(LEAK_ENV, token)
    yield token
    deadline = time.monotonic() + 5
    left = tagged(token)
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        left = tagged(token)
    for pid, _command in left:  # do not leak into the rest of the session, whatever the assertion says
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not left, f"processes left behind: {left}"


@pytest.fixture
def batch_inputs(corpus):
    from magna_gs.inputs import resolve_inputs

    return resolve_inputs(WORLD, MISSION, [corpus])


@pytest.fixture
def make_config(batch_inputs, tmp_path):
    """BatchConfig with the stand-in, short budgets and a data root in tmp_path."""
    from magna_master.batch_config import BatchConfig

    def make(mode="ok", n_iter=2, **overrides):
        command = overrides.pop("launch_command", None) or stand_in_command(
            mode, sleep=overrides.pop("sleep", 0.2), fail_seeds=overrides.pop("fail_seeds", ""),
            extra=overrides.pop("stand_in_extra", ()))
        values = dict(inputs=batch_inputs, n_iter=n_iter, data_root=tmp_path / "data", launch_command=command,
                      time_limit=20.0, stop_grace=2.0, settle=2.0, shutdown_timeout=2.0)
        values.update(overrides)
        return BatchConfig(**values)
    return make
