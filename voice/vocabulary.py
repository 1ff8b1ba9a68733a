"""The command vocabulary: every phrase the assistant understands and what it means.

One table per WIT-style entity (action, direction, unit, parameter, algorithm, ...), phrase ->
canonical value. The parser reads these tables and the speech model's corpus is generated from
them (voice.corpus), so adding a synonym here teaches both the parser and the recogniser.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

# Canonical actions are the ground station's (magna_msgs/GroundStationCommand.action).
ACTIONS = {
    "take off": "take_off", "takeoff": "take_off", "lift off": "take_off", "liftoff": "take_off",
    "launch": "take_off", "get airborne": "take_off", "airborne": "take_off", "off the ground": "take_off",
    "in the air": "take_off", "into the air": "take_off",
    "land": "land", "landing": "land", "landed": "land", "back on the ground": "land", "down on the ground": "land",
    "touch down": "land", "touchdown": "land", "set down": "land",
    "go": "move", "move": "move", "fly": "move", "head": "move", "travel": "move", "shift": "move",
    "translate": "move", "climb": "move", "rise": "move", "ascend": "move", "raise": "move",
    "descend": "move", "lower": "move", "drop": "move", "sink": "move", "come": "move", "step": "move",
    "gain": "move", "lose": "move", "advance": "move", "retreat": "move", "slide": "move", "drift": "move",
    "strafe": "move", "bring": "move", "put": "move", "push": "move", "pull": "move", "nudge": "move",
    "turn": "turn", "rotate": "turn", "yaw": "turn", "spin": "turn", "do a": "turn",
    "follow": "follow", "following": "follow", "trail": "follow", "track": "follow", "chase": "follow",
    "tail": "follow", "shadow": "follow", "stick with": "follow",
    "escort": "follow", "stay behind": "follow", "keep behind": "follow", "behind": "follow",
    "what": "get", "how": "get", "tell": "get", "report": "get", "give me": "get", "check": "get",
    "show": "get",
    "set": "set", "use": "set", "switch": "set", "change": "set", "select": "set", "enable": "set",
    "activate": "set", "navigate with": "set", "fly with": "set",
    "pause": "standby", "hold": "standby", "hover": "standby", "stand by": "standby", "standby": "standby",
    "wait": "standby", "freeze": "standby", "halt": "standby", "stop": "standby", "suspend": "standby",
    "resume": "resume", "continue": "resume", "go on": "resume", "carry on": "resume", "proceed": "resume",
    "unpause": "resume", "keep going": "resume", "going again": "resume", "restart": "resume",
}
# Verbs that carry a direction of their own ("climb five meters").
ACTION_DIRECTIONS = {"climb": "up", "rise": "up", "ascend": "up", "raise": "up", "gain": "up", "descend": "down",
                     "lower": "down", "drop": "down", "sink": "down", "lose": "down", "advance": "forward",
                     "retreat": "backward"}
# After these the next UAV named is the one to follow, not the one commanded.
FOLLOW_TARGET_MARKERS = {"follow", "following", "trail", "stick with", "track", "chase", "tail", "shadow", "escort",
                         "stay behind", "keep behind", "behind", "after"}

INTENT_OF_ACTION = {"take_off": "basic_action", "land": "basic_action", "move": "basic_action",
                    "turn": "basic_action", "follow": "basic_action", "get": "parameters", "set": "algorithms",
                    "standby": "mission", "resume": "mission"}

DIRECTIONS = {
    "up": "up", "upward": "up", "upwards": "up", "higher": "up", "above": "up",
    "down": "down", "downward": "down", "downwards": "down", "lower": "down", "below": "down",
    "left": "left", "leftward": "left", "leftwards": "left", "port": "left",
    "right": "right", "rightward": "right", "rightwards": "right", "starboard": "right",
    "forward": "forward", "forwards": "forward", "ahead": "forward", "front": "forward", "onward": "forward",
    "backward": "backward", "backwards": "backward", "back": "backward", "rearward": "backward",
    "reverse": "backward",
    "x": "x", "x axis": "x", "ex": "x", "y": "y", "y axis": "y", "why": "y", "z": "z", "z axis": "z",
    "zed": "z", "zee": "z",
}
AXES = ("x", "y", "z")
TURN_SIDES = ("left", "right")

# unit phrase -> (canonical name, the ground station's unit, factor to it)
UNITS = {
    "meters": ("meters", "m", 1.0), "meter": ("meters", "m", 1.0), "metres": ("meters", "m", 1.0),
    "metre": ("meters", "m", 1.0), "m": ("meters", "m", 1.0),
    "centimeters": ("centimeters", "m", 0.01), "centimeter": ("centimeters", "m", 0.01),
    "centimetres": ("centimeters", "m", 0.01), "centimetre": ("centimeters", "m", 0.01),
    "cm": ("centimeters", "m", 0.01),
    "millimeters": ("millimeters", "m", 0.001), "millimetres": ("millimeters", "m", 0.001),
    "mm": ("millimeters", "m", 0.001),
    "feet": ("feet", "m", 0.3048), "foot": ("feet", "m", 0.3048), "ft": ("feet", "m", 0.3048),
    "degrees": ("degrees", "deg", 1.0), "degree": ("degrees", "deg", 1.0), "deg": ("degrees", "deg", 1.0),
    "radians": ("radians", "deg", 180.0 / math.pi), "radian": ("radians", "deg", 180.0 / math.pi),
    "rad": ("radians", "deg", 180.0 / math.pi),
}

PARAMETERS = {
    "battery": "battery", "battery level": "battery", "battery status": "battery", "charge": "battery",
    "power": "battery", "batteries": "battery", "juice": "battery",
    "state": "state", "status": "state", "doing": "state", "mode": "state",
    "position": "position", "location": "position", "where": "position", "coordinates": "position",
}

ALGORITHMS = {
    "orca": "orca3d", "orca3d": "orca3d", "orca 3d": "orca3d", "orca three d": "orca3d", "orca3": "orca3d",
    "collision avoidance": "orca3d",
    "simple": "simple", "simple guidance": "simple", "guidance": "simple", "direct": "simple",
    "neural network": "neural_network", "neural": "neural_network", "network": "neural_network",
    "nn": "neural_network", "learned policy": "neural_network", "neural net": "neural_network",
}

MISSION_COMPONENTS = {"mission": "mission", "operation": "mission", "plan": "mission", "task": "mission"}

# Names of one UAV ("drone two", "uav 2", "number two") and of all of them.
UAV_NOUNS = ("drone", "drones", "uav", "uavs", "quad", "quadcopter", "copter", "number", "vehicle", "aircraft",
             "robot", "agent", "unit")
ALL_PHRASES = ("all drones", "all uavs", "all the drones", "all the uavs", "all of you", "all vehicles",
               "all robots", "all agents", "all units", "all quads", "all", "everyone", "everybody", "every drone",
               "every uav", "each drone", "each uav", "both drones", "both uavs", "both", "the swarm", "swarm",
               "the fleet", "fleet", "every one of you")

# Words that carry no meaning for a command; they are skipped without lowering the confidence.
FILLERS = frozenset(
    "please okay ok uh um er erm hmm hey now then right just so well could can would will you your i i'd want "
    "like to the a an of at by and it its is are be please thanks thank kindly let me us lets let's "
    "quickly slowly immediately straight some more another again also yeah yes alright there that this for "
    "in on with distance do does me my our we of away time after along stay keep remain start "
    "height altitude over initiate still direction here".split())
# A sentence opening with these asks yes or no about a UAV ("is drone two airborne?"): its state.
YES_NO_OPENERS = ("is", "are", "has", "did")
NEGATIVE_WORDS = ("minus", "negative")
# Numbers after these words belong to the identity ("drone number two"), not to a distance.
ID_LINKERS = ("number",)


def all_phrases() -> dict[str, dict[str, str]]:
    """Every table by entity name, for the parser and the corpus."""
    return {"action": ACTIONS, "direction": DIRECTIONS, "parameter": PARAMETERS, "algorithm": ALGORITHMS,
            "mission_component": MISSION_COMPONENTS}


def phrase_tables() -> list[Mapping[str, object]]:
    """Every table, units included, for what needs only the phrases (phrase -> value)."""
    return [*all_phrases().values(), UNITS]
