"""The manager host node: the UAV managers of one machine in one process (rosrun magna_uav uav_manager_host)."""
from __future__ import annotations

import argparse

import rospy
from std_msgs.msg import UInt32MultiArray

from magna_common.ros_exit import leave_now
from magna_uav.host import ENDED_TOPIC, ManagerHost, host_ids, manager_node_name, private_params
from magna_uav.nai.orca_batch import OrcaBatcher
from magna_uav.ros_data import SwarmFeed
from magna_uav.ros_node import UavManagerNode
from magna_uav.settings import Settings, SettingsError, read_settings

HELP = """\
The UAV managers of one machine in one process, nodelet style: each runs in a thread of its own and keeps
the names, actions, services and heartbeat of the standalone manager (rosrun magna_uav uav_manager
--help), which it replaces. The ground station starts one for the UAVs whose manager runs on it.

Private parameters:
  ~ids (required)   the UAVs whose managers this host runs, e.g. _ids:=[1,2]
Each manager reads the private parameters of the standalone node it replaces, /uav_{id}_manager/...
(~id, ~mission_file, ~control_rate, ~data_dir, ~csv_stream, ...), as the ground station sets them.

Topics:   ~ended (std_msgs/UInt32MultiArray, latched): the ids of the managers that have ended (a die
          request, or an error), ascending; a manager's heartbeat stops when it ends
          /magna/sim/swarm_state: one subscription feeds every hosted manager's view of the simulated UAVs
Service:  /magna/orca3d/compute_velocity_many: the ORCA-3D steps of every hosted manager at one control
          tick go in one call (the same answers as one call per UAV)
A die request ends that manager only; once every manager has ended, the host exits (status 0).

Example: rosparam set /uav_1_manager/id 1; rosparam set /uav_2_manager/id 2;
         rosparam set /uav_1_manager/uav_ids [1,2]; rosparam set /uav_2_manager/uav_ids [1,2]
         rosrun magna_uav uav_manager_host _ids:=[1,2]
"""


def hosted_settings(ids: list[int]) -> dict[int, Settings]:
    """Each manager's settings from the private parameters of its standalone node; SettingsError names the node."""
    settings = {}
    for uav_id in ids:
        node = manager_node_name(uav_id)
        try:
            settings[uav_id] = read_settings(private_params(node, rospy.get_param))
        except SettingsError as error:
            raise SettingsError(f"/{node}: {error}") from None
        if settings[uav_id].uav_id != uav_id:
            raise SettingsError(f"/{node}/id is {settings[uav_id].uav_id}, not {uav_id}: the host's ~ids name "
                                f"UAV {uav_id}, so set /{node}/id to {uav_id}")
    return settings


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rosrun magna_uav uav_manager_host", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_known_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node("uav_manager_host")  # the ground station names it uav_manager_host too
    try:
        ids = host_ids(rospy.get_param("~ids", None))
        settings = hosted_settings(ids)
    except (ValueError, SettingsError) as error:
        rospy.logfatal(f"uav_manager_host: {error}")
        return 2
    swarm = SwarmFeed()  # one subscription feeds every manager's view of the simulated UAVs, its own included
    orca_batcher = OrcaBatcher()  # one ORCA-3D call per control tick for every manager flying with it
    ended_pub = rospy.Publisher(f"~{ENDED_TOPIC}", UInt32MultiArray, queue_size=1, latch=True)
    ended_pub.publish(UInt32MultiArray(data=[]))

    def run_manager(uav_id: int) -> None:
        try:
            node = UavManagerNode(settings[uav_id], swarm=swarm, orca_batcher=orca_batcher)
        except Exception as error:  # the UAL services never came, or a bad algorithm: this manager only
            rospy.logfatal(f"uav_manager {uav_id}: {error}")
            raise
        node.run()

    host = ManagerHost(ids, run_manager, on_ended=lambda ended: ended_pub.publish(UInt32MultiArray(data=ended)),
                       log_error=rospy.logerr).start()
    rospy.loginfo(f"uav_manager_host: managers of UAVs {ids} started, one thread each")
    while not host.wait(0.1):
        if rospy.is_shutdown():  # Ctrl-C or a kill: each manager sees it and ends; wait for them a while
            host.wait(5.0)
            return 0
    # Every manager has ended and closed what it opened (their CSV streams flushed and closed). Leave at once,
    # as a batch wants (rospy's shutdown would take a second joining its threads), after the rest is closed too.
    swarm.close()
    ended_pub.unregister()
    rospy.loginfo(f"uav_manager_host: the managers of UAVs {ids} have all ended; exiting")
    leave_now(0)
    return 0  # not reached
