"""The UAL over MAVLink (in progress): frames, autopilot modes and the UAL state they give."""
