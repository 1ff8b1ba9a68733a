"""The ROS names of MAGNA's runtime contract, in one place.

Every node, test and tool that publishes, subscribes, calls or sets one of these takes the name
from here, so a rename is one edit. Names a node declares for itself in a launch file (`~pub_rate`)
stay with that node. Per-UAV names are functions of the UAV id.

The layout follows the GRVC UAL (`/uav_{id}/ual/...`) for the UAL API and `/magna/...` for the
rest; `/ual_ids` is the UAL's registry of the ids served.
"""
from __future__ import annotations

# --- the UAL API, one namespace per UAV --------------------------------------------------------------------

UAL_IDS = "/ual_ids"  # every UAL server adds its id, and refuses one already there
UAL_TOPICS = ("pose", "velocity", "odom", "state")  # published by a UAL server
UAL_SETPOINTS = ("set_pose", "set_velocity")  # subscribed by a UAL server
UAL_SERVICES = ("take_off", "land", "go_to_waypoint", "go_to_waypoint_geo", "set_home", "recover_from_manual")


def uav_namespace(uav_id: int | str) -> str:
    """`/uav_{id}`: the namespace of one UAV's UAL and sensors."""
    return f"/uav_{uav_id}"


def ual(uav_id: int | str, name: str = "") -> str:
    """`/uav_{id}/ual/{name}` (or the namespace itself when `name` is empty)."""
    return f"/uav_{uav_id}/ual/{name}" if name else f"/uav_{uav_id}/ual"


def mavlink_link(uav_id: int | str) -> str:
    """The link state `ual_mavlink` publishes for one UAV."""
    return f"/uav_{uav_id}/ual_mavlink/link"


def battery(uav_id: int | str) -> str:
    """The battery state (sensor_msgs/BatteryState) on the topic PX4's mavros uses."""
    return f"/uav_{uav_id}/mavros/battery"


def depth_camera(uav_id: int | str, name: str = "") -> str:
    """`/uav_{id}/camera/depth/{name}`: one UAV's depth camera (`image_raw`, `camera_info`)."""
    return f"/uav_{uav_id}/camera/depth/{name}" if name else f"/uav_{uav_id}/camera/depth"


# --- MAGNA --------------------------------------------------------------------------------------------------

HYPERPARAMETERS = "/magna/hyperparameters"  # the parameter the Master sets before each simulation
MASTER_TERMINATION = "/magna/master/simulation_termination"

GS_COMMAND = "/magna/gs/command"
GS_STOP = "/magna/gs/stop"
GS_CONTINUE = "/magna/gs/continue"
GS_CRITICAL_EVENT = "/magna/gs/critical_event"
GS_CRITICAL_EVENTS = "/magna/gs/critical_events"  # magna_msgs/CriticalEvent: each one the ground station records
GS_STATE_ACTUALIZATION = "/magna/gs/state_actualization"

SIM_SPAWN_MODEL = "/magna/sim/spawn_model"
SIM_DELETE_MODEL = "/magna/sim/delete_model"
SIM_PAUSE = "/magna/sim/pause"
SIM_COLLISIONS = "/magna/sim/collisions"
SIM_RESET = "/magna/sim/reset"
SIM_SWARM_STATE = "/magna/sim/swarm_state"

WORLD = "/magna/world"
WORLD_MARKERS = "/magna/world/markers"
WORLD_ADD = "/magna/world/add"
WORLD_DELETE = "/magna/world/delete"
WORLD_GET_FSPSET = "/magna/world/get_fspset"
WORLD_BOUNDARIES = "/magna/world/boundaries"
WORLD_ORIGIN_GEO = "/magna/world/origin_geo"
WORLD_RESET = "/magna/world/reset"

ORCA_COMPUTE_VELOCITY = "/magna/orca3d/compute_velocity"
ORCA_COMPUTE_VELOCITIES = "/magna/orca3d/compute_velocities"
ORCA_COMPUTE_VELOCITY_MANY = "/magna/orca3d/compute_velocity_many"

UTM_FLIGHT_PLANS = "/magna/utm/flight_plans"


def utm_flight_plan(uav_id: int | str) -> str:
    """The UTM's flight plan of one UAV (nav_msgs/Path, latched)."""
    return f"/magna/utm/flight_plan/{uav_id}"


def utm_conflict_path(number: int | str) -> str:
    """The UTM's `number`-th conflicting path (nav_msgs/Path), drawn for rviz."""
    return f"/magna/utm/conflict_path/{number}"


SM_ROOT = "/magna/sm"
VIZ_SCENE = "/magna/viz/scene"
VIZ_BAG_WORLD = "/magna/viz/bag_world"

# The actions a UAV manager serves (SimpleAction), one per mission step kind.
UAV_ACTIONS = ("take_off", "land", "basic_move", "follow_path", "follow_agent_ad", "follow_agent_ap", "save_csv")


def manager(uav_id: int | str, name: str = "") -> str:
    """`/magna/uav_{id}/{name}`: a UAV manager's actions, topics and services."""
    return f"/magna/uav_{uav_id}/{name}" if name else f"/magna/uav_{uav_id}"


def manager_alive(uav_id: int | str) -> str:
    """`/magna/uav_{id}/alive` (std_msgs/Float64): a manager's heartbeat, its simulated time (magna_common.liveness)."""
    return manager(uav_id, "alive")


def sm_topic(machine: str, kind: str) -> str:
    """`/magna/sm/{machine}/{status|structure}`: a state machine's introspection topics."""
    return f"{SM_ROOT}/{machine}/{kind}"


# Patterns (regular expressions) for names read back from bags, with the UAV id as group 1.
UAL_TOPIC_PATTERN = r"/uav_(\d+)/ual/(pose|velocity)"
MANAGER_TOPIC_PATTERN = r"/magna/uav_(\d+)/(navigation|goal|path/raw|path/smoothed)"
SM_TOPIC_PATTERN = r"/magna/sm/([^/]+)/(status|structure)"
