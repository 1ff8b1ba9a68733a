"""Which autopilot a HEARTBEAT comes from, and what its flight mode means for the UAL.

PX4 packs its mode into HEARTBEAT.custom_mode: the main mode in bits 16-23, the AUTO sub-mode in
bits 24-31 (px4_custom_mode.h). ArduPilot Copter uses custom_mode as a plain mode number. The UAL
flies its set-points in PX4's OFFBOARD and in ArduPilot Copter's GUIDED; any other mode is a pilot's.
"""
from __future__ import annotations

from dataclasses import dataclass

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1

PX4, ARDUPILOT = "px4", "ardupilot"
AUTOPILOTS = {MAV_AUTOPILOT_PX4: PX4, MAV_AUTOPILOT_ARDUPILOTMEGA: ARDUPILOT}

PX4_MAIN_MODES = {1: "MANUAL", 2: "ALTCTL", 3: "POSCTL", 4: "AUTO", 5: "ACRO", 6: "OFFBOARD", 7: "STABILIZED",
                  8: "RATTITUDE"}
PX4_AUTO_SUB_MODES = {1: "READY", 2: "TAKEOFF", 3: "LOITER", 4: "MISSION", 5: "RTL", 6: "LAND", 8: "FOLLOW_TARGET",
                      9: "PRECLAND"}
ARDUCOPTER_MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
                    7: "CIRCLE", 9: "LAND", 16: "POSHOLD", 17: "BRAKE", 20: "GUIDED_NOGPS", 21: "SMART_RTL"}
# The mode in which each autopilot follows a companion computer's set-points.
SET_POINT_MODE = {PX4: "OFFBOARD", ARDUPILOT: "GUIDED"}


class UnknownAutopilot(ValueError):
    """A HEARTBEAT from an autopilot the UAL cannot fly (neither PX4 nor ArduPilot)."""


@dataclass(frozen=True)
class Mode:
    autopilot: str
    name: str  # e.g. OFFBOARD, AUTO.LAND, GUIDED; "UNKNOWN(n)" for a number no table has
    armed: bool

    @property
    def follows_set_points(self) -> bool:
        """Whether the autopilot flies the UAL's set-points now (the UAL's FLYING_AUTO)."""
        return self.name == SET_POINT_MODE[self.autopilot]


def autopilot_of(heartbeat_autopilot: int) -> str:
    try:
        return AUTOPILOTS[heartbeat_autopilot]
    except KeyError:
        raise UnknownAutopilot(f"HEARTBEAT.autopilot {heartbeat_autopilot} is neither PX4 ({MAV_AUTOPILOT_PX4}) nor "
                               f"ArduPilot ({MAV_AUTOPILOT_ARDUPILOTMEGA}); the UAL over MAVLink flies only those"
                               ) from None


def decode_mode(heartbeat_autopilot: int, base_mode: int, custom_mode: int) -> Mode:
    """The flight mode and armed state a HEARTBEAT reports."""
    autopilot = autopilot_of(heartbeat_autopilot)
    armed = bool(base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
    if autopilot == PX4:
        main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
        name = PX4_MAIN_MODES.get(main, f"UNKNOWN({main})")
        if name == "AUTO":
            name = f"AUTO.{PX4_AUTO_SUB_MODES.get(sub, f'UNKNOWN({sub})')}"
    else:
        name = ARDUCOPTER_MODES.get(custom_mode, f"UNKNOWN({custom_mode})")
    return Mode(autopilot, name, armed)


def encode_mode(autopilot: str, name: str) -> tuple[int, int]:
    """(base_mode, custom_mode) for a MAV_CMD_DO_SET_MODE / SET_MODE that selects `name`."""
    if autopilot == PX4:
        main_name, _, sub_name = name.partition(".")
        main = _key(PX4_MAIN_MODES, main_name, name)
        sub = _key(PX4_AUTO_SUB_MODES, sub_name, name) if sub_name else 0
        return MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, (main << 16) | (sub << 24)
    return MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, _key(ARDUCOPTER_MODES, name, name)


def _key(table: dict[int, str], value: str, whole: str) -> int:
    for number, text in table.items():
        if text == value:
            return number
    raise ValueError(f"no flight mode {whole!r}; known: {', '.join(sorted(table.values()))}")
