"""mlr's tests run in the workspace's environment: `scripts/with_env.sh python -m pytest mlr`."""
from tests.support import exit_unless_in_workspace


def pytest_configure(config):
    exit_unless_in_workspace("mlr", ("numpy", "torch", "rospy", "magna_uav", "magna_gs"))
