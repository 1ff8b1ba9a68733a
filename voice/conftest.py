"""voice's tests run in the workspace's environment: `scripts/with_env.sh python -m pytest voice`."""
from tests.support import exit_unless_in_workspace


def pytest_configure(config):
    exit_unless_in_workspace("voice", ("numpy", "pocketsphinx", "rospy", "magna_gs"))
