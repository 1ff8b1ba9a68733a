#!/usr/bin/env python3
"""A stand-in for `roslaunch magna_gs simulation.launch`: plays the ground station's part for the batch tests.

    stand_in_gs.py --mode MODE --data-dir DIR --seed N [--sleep S] [--fail-seeds 2,5] [--report FILE] [...]

It records what it saw (hyperparameters, stale parameters, arguments, its pid and its
children's) in DIR/stand_in.json (or --report), then per MODE:

  ok        sleep --sleep (--long-sleep for the seed --sleep-seed), write world.json, mission.json,
            uav_1.csv, uav_2.csv (and simulation.bag when --bag true), call
            /magna/master/simulation_termination and exit; seeds in --fail-seeds
            report a collision (success false) with UAV 2's critical event at 4.5 simulated s
  linger    like ok, but stay alive after the call (the supervisor must end it)
  orphan    like ok, after starting a grandchild in a session of its own that sleeps for 10 minutes
  crash     sleep --sleep, then exit with status 3 without calling the service
  hang      never call; no /magna/gs/stop either
  stoppable never call by itself; serve /magna/gs/stop, and when it is called report 'preempted' and exit
  deaf      like hang, and ignore SIGINT and SIGTERM (only SIGKILL ends it)

--crash-seeds 3: those seeds crash (as mode crash) whatever the mode. --rendezvous DIR --rendezvous-seeds 1,2:
those seeds each leave a mark in DIR and wait (up to 60 s, then crash) until every one of them has: they pass
only when they run at the same time.
"""
import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--mode", default="ok")
    parser.add_argument("--data-dir", default="")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sleep", type=float, default=0.2)
    parser.add_argument("--fail-seeds", default="")
    parser.add_argument("--sleep-seed", type=int, default=None, help="this seed sleeps --long-sleep instead")
    parser.add_argument("--long-sleep", type=float, default=60.0)
    parser.add_argument("--report", default="")
    parser.add_argument("--bag", default="false")
    parser.add_argument("--save-data", default="false")
    parser.add_argument("--mission-file", default="")
    parser.add_argument("--world", default="")
    parser.add_argument("--subworld", default="")
    parser.add_argument("--worlds-path", default="")
    parser.add_argument("--rtf", default="")
    parser.add_argument("--crash-seeds", default="")
    parser.add_argument("--rendezvous", default="")
    parser.add_argument("--rendezvous-seeds", default="")
    args = parser.parse_args()

    if args.mode == "deaf":
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)

    import rospy
    from magna_msgs.msg import CriticalEvent
    from magna_msgs.srv import SimulationTermination
    from std_srvs.srv import Trigger, TriggerResponse

    rospy.init_node("ground_station", disable_signals=args.mode == "deaf")
    data_dir = Path(args.data_dir) if args.data_dir else None
    report_path = Path(args.report) if args.report else (data_dir / "stand_in.json" if data_dir else None)
    seen = {
        "pid": os.getpid(),
        "argv": sys.argv[1:],
        "hyperparameters": rospy.get_param("/magna/hyperparameters", None),
        "stale_ual_ids": rospy.has_param("/ual_ids"),
        "stale_marker": rospy.has_param("/stand_in/marker"),
        "master_uri": os.environ.get("ROS_MASTER_URI"),
        "children": [],
    }
    # Leave state behind on this master: the next simulation must not see it.
    rospy.set_param("/ual_ids", [1, 2])
    rospy.set_param("/stand_in/marker", True)

    if args.mode == "orphan":
        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"], start_new_session=True)
        seen["children"].append(child.pid)

    def report():
        if report_path is not None:
            report_path.parent.mkdir(parents=True, exist_ok=True)
            report_path.write_text(json.dumps(seen))

    report()
    terminate = rospy.ServiceProxy("/magna/master/simulation_termination", SimulationTermination)
    rospy.wait_for_service("/magna/master/simulation_termination", timeout=20)

    def nap(seconds):
        """Sleep like a node: leave when rospy shuts down (SIGINT, SIGTERM), as rospy.spin() would."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if rospy.is_shutdown() and args.mode != "deaf":
                sys.exit(0)
            time.sleep(0.05)

    if args.mode in ("hang", "deaf"):
        nap(float("inf"))
    if args.mode == "stoppable":
        stopped = threading.Event()

        def on_stop(_request):
            stopped.set()
            return TriggerResponse(success=True, message="stopping")

        rospy.Service("/magna/gs/stop", Trigger, on_stop)
        while not stopped.wait(0.05):
            if rospy.is_shutdown():
                return 0
        seen["stopped"] = True
        report()
        terminate(success=False, outcome="preempted", message="stopped by the Master", sim_duration=3.0, collisions=0)
        return 0

    meeting = {int(s) for s in args.rendezvous_seeds.split(",") if s.strip()}
    if args.rendezvous and args.seed in meeting:
        place = Path(args.rendezvous)
        place.mkdir(parents=True, exist_ok=True)
        (place / f"seed_{args.seed}").touch()
        deadline = time.monotonic() + 60
        while {int(p.name.split("_")[1]) for p in place.glob("seed_*")} < meeting:
            if time.monotonic() > deadline:
                print(f"stand-in: seeds {sorted(meeting)} never ran at the same time", flush=True)
                return 4
            nap(0.05)
        seen["met"] = sorted(meeting)
        report()
    nap(args.long_sleep if args.seed == args.sleep_seed else args.sleep)
    if args.mode == "crash" or args.seed in {int(s) for s in args.crash_seeds.split(",") if s.strip()}:
        print("stand-in: something broke", flush=True)
        return 3

    if data_dir is not None and args.save_data == "true":
        (data_dir / "world.json").write_text(json.dumps({"world": args.world, "subworld": args.subworld}))
        (data_dir / "mission.json").write_text(Path(args.mission_file).read_text() if args.mission_file else "{}")
        for uav in (1, 2):
            (data_dir / f"uav_{uav}.csv").write_text("time,x,y,z\n0.0,0,0,0\n")
        if args.bag == "true":
            (data_dir / "simulation.bag").write_bytes(b"#ROSBAG V2.0\n")
    failing = {int(s) for s in args.fail_seeds.split(",") if s.strip()}
    if args.seed in failing:
        response = terminate(success=False, outcome="collision", message="collision between 1 and 2",
                             sim_duration=10.0 + args.seed, collisions=1,
                             critical_events=[CriticalEvent(uav_id=2, event="collision", sim_time=4.5, detail="UAV 1")])
    else:
        response = terminate(success=True, outcome="succeeded", message="mission completed",
                             sim_duration=10.0 + args.seed, collisions=0)
    seen["acknowledged"] = response.acknowledged
    report()
    if args.mode == "linger":
        nap(float("inf"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
