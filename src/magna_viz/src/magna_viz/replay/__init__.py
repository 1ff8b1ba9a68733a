"""`magna replay`: a simulation's bag played into rviz (replay_cli is the command line).

    plan.py       the options and everything checked before anything starts (make_plan)
    processes.py  the private master, Xvfb, rviz, the scene node and rosbag play (Replay)
    media.py      a headless replay's GIF and MP4
    errors.py     ReplayError (bad input, nothing started) and ReplayFailure (a process failed)
"""
