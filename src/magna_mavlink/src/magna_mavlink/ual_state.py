"""The UAL's State from what a MAVLink autopilot reports, as GRVC UAL's MAVROS backend derives it.

Order of precedence: no valid position yet -> UNINITIALIZED; a take_off or land call running ->
TAKING_OFF or LANDING; on the ground -> LANDED_ARMED or LANDED_DISARMED; in the air -> FLYING_AUTO
while the autopilot follows the UAL's set-points (OFFBOARD, GUIDED), FLYING_MANUAL otherwise, so a
pilot's take-over shows. An autopilot that does not report EXTENDED_SYS_STATE (landed state
UNDEFINED) counts as on the ground while disarmed and in the air while armed; but in the first
LANDED_STATE_WAIT seconds of a link, before any EXTENDED_SYS_STATE, the state is UNINITIALIZED: through
a lossy link the first one can be late, and a vehicle armed on its pad would otherwise read as flying
(a take-off would then count as done on the ground).
"""
from __future__ import annotations

# uav_abstraction_layer/State constants (the message's own numbers; no ROS import needed here).
UNINITIALIZED, LANDED_DISARMED, LANDED_ARMED, TAKING_OFF, FLYING_AUTO, FLYING_MANUAL, LANDING = range(7)
NAMES = ("UNINITIALIZED", "LANDED_DISARMED", "LANDED_ARMED", "TAKING_OFF", "FLYING_AUTO", "FLYING_MANUAL", "LANDING")

# MAV_LANDED_STATE
LANDED_UNDEFINED, ON_GROUND, IN_AIR, LANDED_TAKEOFF, LANDED_LANDING = range(5)

TAKE_OFF_CALL, LAND_CALL = "take_off", "land"
# s from the link's first message during which a missing landed state means "not heard yet", not "never sent":
# the bridge asks for EXTENDED_SYS_STATE at 5 Hz, so even one packet in five lost leaves 15 chances in 3 s.
LANDED_STATE_WAIT = 3.0


def ual_state(position_valid: bool, armed: bool, landed_state: int, follows_set_points: bool,
              call: str | None = None, landed_state_pending: bool = False) -> int:
    """The State to publish; `call` is the UAL service running now (take_off, land or None);
    `landed_state_pending`: no EXTENDED_SYS_STATE yet, within LANDED_STATE_WAIT of the link's start."""
    if not position_valid or (landed_state_pending and landed_state == LANDED_UNDEFINED):
        return UNINITIALIZED
    if call == TAKE_OFF_CALL:
        return TAKING_OFF
    if call == LAND_CALL:
        return LANDING
    on_ground = landed_state == ON_GROUND or (landed_state == LANDED_UNDEFINED and not armed)
    if on_ground:
        return LANDED_ARMED if armed else LANDED_DISARMED
    return FLYING_AUTO if follows_set_points else FLYING_MANUAL
