"""voice's tests run in the workspace's environment: `scripts/with_env.sh python -m pytest voice`.

A test that speaks or phonemises through espeak-ng carries `@pytest.mark.espeak`: it is skipped
where espeak-ng is missing (`make setup` installs it; in CI a skip fails the run). Only those."""
import shutil

import pytest

from tests.support import exit_unless_in_workspace


def pytest_configure(config):
    exit_unless_in_workspace("voice", ("numpy", "pocketsphinx", "rospy", "magna_gs"))
    config.addinivalue_line("markers", "espeak: calls espeak-ng; skipped where it is not installed")


def pytest_runtest_setup(item):
    if item.get_closest_marker("espeak") and shutil.which("espeak-ng") is None:
        pytest.skip("espeak-ng not installed (make setup installs it)")
