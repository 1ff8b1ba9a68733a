"""HEARTBEAT modes of PX4 and ArduPilot Copter, and the UAL State derived from an autopilot's report."""
import pytest

from magna_mavlink import autopilot, ual_state
from magna_mavlink.ual_state import (
    FLYING_AUTO,
    FLYING_MANUAL,
    IN_AIR,
    LANDED_ARMED,
    LANDED_DISARMED,
    LANDED_UNDEFINED,
    LANDING,
    ON_GROUND,
    TAKING_OFF,
    UNINITIALIZED,
)

ARMED = autopilot.MAV_MODE_FLAG_SAFETY_ARMED


@pytest.mark.parametrize(("custom_mode", "name"), [
    (6 << 16, "OFFBOARD"),
    (3 << 16, "POSCTL"),
    ((4 << 16) | (6 << 24), "AUTO.LAND"),
    ((4 << 16) | (3 << 24), "AUTO.LOITER"),
    (42 << 16, "UNKNOWN(42)"),
])
def test_px4_modes(custom_mode, name):
    mode = autopilot.decode_mode(autopilot.MAV_AUTOPILOT_PX4, ARMED | 1, custom_mode)
    assert (mode.autopilot, mode.name, mode.armed) == ("px4", name, True)
    assert mode.follows_set_points == (name == "OFFBOARD")
    if not name.startswith("UNKNOWN"):
        assert autopilot.encode_mode("px4", name)[1] == custom_mode


@pytest.mark.parametrize(("custom_mode", "name"), [(4, "GUIDED"), (5, "LOITER"), (9, "LAND"), (0, "STABILIZE")])
def test_ardupilot_copter_modes(custom_mode, name):
    mode = autopilot.decode_mode(autopilot.MAV_AUTOPILOT_ARDUPILOTMEGA, 1, custom_mode)
    assert (mode.autopilot, mode.name, mode.armed) == ("ardupilot", name, False)
    assert mode.follows_set_points == (name == "GUIDED")
    assert autopilot.encode_mode("ardupilot", name) == (autopilot.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom_mode)


def test_other_autopilots_and_modes_are_refused_with_what_is_known():
    with pytest.raises(autopilot.UnknownAutopilot, match="HEARTBEAT.autopilot 8 is neither PX4"):
        autopilot.decode_mode(8, 0, 0)
    with pytest.raises(ValueError, match="no flight mode 'AUTO.DANCE'"):
        autopilot.encode_mode("px4", "AUTO.DANCE")


@pytest.mark.parametrize(("position_valid", "armed", "landed", "auto", "call", "state"), [
    (False, True, IN_AIR, True, None, UNINITIALIZED),          # nothing before a valid position
    (True, False, ON_GROUND, False, None, LANDED_DISARMED),
    (True, True, ON_GROUND, False, None, LANDED_ARMED),
    (True, True, ON_GROUND, True, "take_off", TAKING_OFF),     # the call decides while it runs
    (True, True, IN_AIR, True, "land", LANDING),
    (True, True, IN_AIR, True, None, FLYING_AUTO),             # OFFBOARD / GUIDED
    (True, True, IN_AIR, False, None, FLYING_MANUAL),          # a pilot took over
    (True, False, LANDED_UNDEFINED, False, None, LANDED_DISARMED),  # no EXTENDED_SYS_STATE: disarmed is landed
    (True, True, LANDED_UNDEFINED, True, None, FLYING_AUTO),         # ... and armed is flying
])
def test_ual_state(position_valid, armed, landed, auto, call, state):
    assert ual_state.ual_state(position_valid, armed, landed, auto, call) == state, ual_state.NAMES[state]


@pytest.mark.parametrize("armed", [True, False])
def test_a_landed_state_not_heard_yet_is_not_read_as_flying(armed):
    """Early in a lossy link, before the first EXTENDED_SYS_STATE, an armed vehicle on its pad is not FLYING_AUTO:
    its state is not known yet. Once heard, or once the wait is over without one, the usual rules apply."""
    pending = ual_state.ual_state(True, armed, LANDED_UNDEFINED, True, None, landed_state_pending=True)
    assert pending == UNINITIALIZED
    heard = ual_state.ual_state(True, armed, ON_GROUND, True, None, landed_state_pending=True)
    assert heard == (LANDED_ARMED if armed else LANDED_DISARMED)
    never_sent = ual_state.ual_state(True, armed, LANDED_UNDEFINED, True, None, landed_state_pending=False)
    assert never_sent == (FLYING_AUTO if armed else LANDED_DISARMED)
