#!/usr/bin/env python3
"""Run magna_sim's UAL behaviour cases (UalBehaviour in src/magna_sim/test/ual_api_rostest.py) against the UAL
servers of the UAV ids given, e.g. ual_mavlink bridges in front of magna_sim's MAVLink vehicles:

    python3 ual_behaviour_runner.py 1 2

The same cases magna_sim's rostest runs, not a copy: they are loaded from that file. Exit status 0 when all pass.
Started by test_live_ual_mavlink.py with ROS_MASTER_URI set to its master.
"""
import sys
import unittest
from pathlib import Path

from magna_common.workspace import find_root

sys.path.append(str(find_root()))  # tests/ sits at the repository root

from tests.support import load_module  # noqa: E402

CASES = Path(__file__).resolve().parents[2] / "magna_sim" / "test" / "ual_api_rostest.py"


def load_cases():
    return load_module(CASES, "magna_sim_ual_api_cases")


def main(argv) -> int:
    import rospy

    ids = tuple(int(arg) for arg in argv[1:])
    if not ids:
        print("usage: ual_behaviour_runner.py ID [ID ...]", file=sys.stderr)
        return 2
    cases = load_cases()
    behaviour = type("UalBehaviourOverMavlink", (cases.UalBehaviour,), {"ids": ids})
    rospy.init_node("ual_behaviour_runner", anonymous=True)
    suite = unittest.defaultTestLoader.loadTestsFromTestCase(behaviour)
    result = unittest.TextTestRunner(stream=sys.stdout, verbosity=2, failfast=True).run(suite)
    return 0 if result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
