"""The UAL over MAVLink (in progress): frame conventions between ROS and MAVLink so far."""
