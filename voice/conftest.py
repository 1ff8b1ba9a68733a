"""voice's tests run in the workspace's environment: `scripts/with_env.sh python -m pytest voice`.

With another Python (pyenv's, the system's) they would fail one by one on imports; say so once.
"""
import importlib.util

import pytest

NEEDED = ("numpy", "pocketsphinx", "rospy", "magna_gs")


def pytest_configure(config):
    missing = [name for name in NEEDED if importlib.util.find_spec(name) is None]
    if missing:
        pytest.exit(f"voice's tests need the workspace's environment (this Python cannot import "
                    f"{', '.join(missing)}): run them as scripts/with_env.sh python -m pytest voice", returncode=2)
