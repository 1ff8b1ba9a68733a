"""Action goals from the ground station -> roles, one builder per action server."""
from __future__ import annotations

from magna_uav.config import UavConfig
from magna_uav.roles import (
    BasicMoveRole,
    FollowAgentAtDistanceRole,
    FollowAgentAtPositionRole,
    FollowPathRole,
    LandRole,
    Role,
    TakeOffRole,
)

# Action servers that fly a role (save_csv and set_mission are handled apart).
ROLE_ACTIONS = ("take_off", "land", "basic_move", "follow_path", "follow_agent_ad", "follow_agent_ap")


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
        return BasicMoveRole(move_type, goal.direction, goal.value, goal.dynamic or "position", goal.duration,
                             accepted_radius=config.accepted_target_radius)
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
    raise ValueError(f"action {action!r} flies no role; known: {', '.join(ROLE_ACTIONS)}")
