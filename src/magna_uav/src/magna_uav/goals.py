"""Action goals from the ground station -> roles, one builder per action server."""
from __future__ import annotations

import json
import math

from magna_uav.config import UavConfig
from magna_uav.roles import (
    BasicMoveRole,
    FollowAgentAtDistanceRole,
    FollowAgentAtPositionRole,
    FollowPathRole,
    LandRole,
    OnBoardMissionRole,
    Role,
    TakeOffRole,
)

# Action servers that fly a role (save_csv is handled apart).
ROLE_ACTIONS = ("take_off", "land", "basic_move", "follow_path", "follow_agent_ad", "follow_agent_ap", "set_mission")
MISSION_KEYS = ("path", "include_takeoff", "include_land", "height", "smooth_path_mode", "dynamic")


def role_from_goal(action: str, goal, config: UavConfig) -> Role:
    """The role one goal asks for; ValueError naming the goal field when it is unusable."""
    if action == "take_off":
        return TakeOffRole(goal.height)
    if action == "land":
        return LandRole()
    if action == "basic_move":
        move_type = goal.move_type or "translation"
        if move_type == "takeoff":
            return TakeOffRole(goal.value, duration=goal.duration)
        if move_type == "land":
            return LandRole(duration=goal.duration)
        # The original compared move_type == ("translation" or "rotation"), so rotation never ran.
        # A short move needs a tighter arrival than a path's waypoints: a fifth of the move, at least 0.1 m.
        accepted = min(config.accepted_target_radius, max(0.1, 0.2 * abs(goal.value)))
        if config.airframe.is_fixed_wing:  # a plane cannot stop: it circles the goal, beyond a short move's radius
            accepted = config.accepted_target_radius
        return BasicMoveRole(move_type, goal.direction, goal.value, goal.dynamic or "position", goal.duration,
                             accepted_radius=accepted)
    if action == "follow_path":
        waypoints = [(p.pose.position.x, p.pose.position.y, p.pose.position.z) for p in goal.path]
        return FollowPathRole(waypoints, config.accepted_target_radius, goal.smooth_path_mode,
                              goal.dynamic or "velocity", goal.duration)
    if action == "follow_agent_ad":
        if goal.distance <= 0:
            raise ValueError(f"follow_agent_ad distance is {goal.distance}: give a positive distance in metres")
        return FollowAgentAtDistanceRole(goal.target_id, goal.distance, goal.duration)
    if action == "follow_agent_ap":
        return FollowAgentAtPositionRole(goal.target_id, (goal.pos.x, goal.pos.y, goal.pos.z), goal.duration)
    if action == "set_mission":
        return mission_role(goal.mission_json, config)
    raise ValueError(f"action {action!r} flies no role; known: {', '.join(ROLE_ACTIONS)}")


def mission_role(mission_json: str, config: UavConfig) -> OnBoardMissionRole:
    """An on-board mission (set_mission): take off (optional), fly a path, land (optional).

    mission_json: {"path": [[x, y, z], ...] (map frame), "include_takeoff": false,
    "include_land": false, "height": 2.0 (take-off, m), "smooth_path_mode": 0,
    "dynamic": "velocity"}, as the original's set_mission state gives them.
    """
    try:
        data = json.loads(mission_json or "{}")
    except json.JSONDecodeError as error:
        raise ValueError(f"set_mission mission_json is not JSON: {error.msg} at column {error.colno}") from None
    if not isinstance(data, dict):
        raise ValueError("set_mission mission_json must be an object with a path")
    unknown = sorted(set(data) - set(MISSION_KEYS))
    if unknown:
        raise ValueError(f"set_mission mission_json.{unknown[0]} is unknown; known: {', '.join(MISSION_KEYS)}")
    path = data.get("path") or []
    if not isinstance(path, list) or not all(isinstance(p, list) and len(p) == 3 and
                                             all(isinstance(v, int | float) and math.isfinite(v) for v in p)
                                             for p in path):
        raise ValueError("set_mission mission_json.path must be a list of [x, y, z] points in metres")
    roles: list[Role] = []
    if data.get("include_takeoff", False):
        roles.append(TakeOffRole(float(data.get("height", 2.0))))
    if path:
        roles.append(FollowPathRole(path, config.accepted_target_radius, int(data.get("smooth_path_mode", 0)),
                                    str(data.get("dynamic", "velocity"))))
    if data.get("include_land", False):
        roles.append(LandRole())
    return OnBoardMissionRole(roles)
