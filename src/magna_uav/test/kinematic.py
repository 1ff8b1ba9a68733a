"""A kinematic stand-in for magna_sim behind the UAL commander interface, for tests of the
UAV manager's loop without ROS: velocities are followed exactly, waypoints are flown at
a fixed speed, take-off and landing change the UAL state as UAL does."""
from __future__ import annotations

import numpy as np

from magna_uav.roles import FLYING_AUTO, LANDED_ARMED, LANDING, TAKING_OFF
from magna_uav.world_view import AgentState, WorldView


class KinematicUav:
    """One UAV; also the commander the manager talks to."""

    def __init__(self, uav_id: int, position, safety_radius: float = 0.3, speed: float = 2.0):
        self.id, self.safety_radius, self.speed = uav_id, safety_radius, speed
        self.position = np.asarray(position, dtype=float)
        self.velocity = np.zeros(3)
        self.yaw, self.yaw_rate = 0.0, 0.0
        self.state = LANDED_ARMED
        self.mode, self.target, self.target_yaw = "hold", self.position.copy(), 0.0
        self.calls: list[str] = []

    # --- the commander interface (commanders.UalCommander) ---
    def take_off(self, height):
        self.calls.append("take_off")
        assert self.state == LANDED_ARMED, "take_off needs LANDED_ARMED"
        self.state, self.mode, self.target = TAKING_OFF, "goto", self.position + [0, 0, height]

    def land(self):
        self.calls.append("land")
        assert self.state == FLYING_AUTO, "land needs FLYING_AUTO"
        self.state, self.mode, self.target = LANDING, "goto", self.position * [1, 1, 0]

    def go_to_waypoint(self, position, yaw=0.0):
        self.calls.append("go_to_waypoint")
        self.mode, self.target, self.target_yaw = "goto", np.asarray(position, dtype=float), yaw

    def set_velocity(self, velocity, yaw_rate=0.0):
        self.calls.append("set_velocity")
        self.mode, self.velocity, self.yaw_rate = "velocity", np.asarray(velocity, dtype=float), yaw_rate

    def hold_pose(self, position, yaw):
        self.calls.append("hold_pose")
        self.mode, self.target, self.target_yaw = "hold", np.asarray(position, dtype=float), yaw

    # --- the physics ---
    def advance(self, dt: float) -> None:
        if self.mode in ("goto", "hold"):
            gap = self.target - self.position
            distance = float(np.linalg.norm(gap))
            move = min(distance, self.speed * dt)
            self.velocity = gap / distance * move / dt if distance > 1e-12 else np.zeros(3)
            turn = (self.target_yaw - self.yaw + np.pi) % (2 * np.pi) - np.pi
            self.yaw += float(np.clip(turn, -1.0 * dt, 1.0 * dt))
        else:
            self.yaw += self.yaw_rate * dt
        self.position = self.position + self.velocity * dt
        if self.state == TAKING_OFF and np.linalg.norm(self.target - self.position) < 1e-9:
            self.state = FLYING_AUTO
        if self.state == LANDING and self.position[2] <= 1e-9:
            self.state, self.mode, self.velocity = LANDED_ARMED, "hold", np.zeros(3)

    def agent_state(self, now: float) -> AgentState:
        return AgentState(self.id, self.position.copy(), [0, 0, np.sin(self.yaw / 2), np.cos(self.yaw / 2)],
                          self.velocity.copy(), self.yaw_rate, self.state, 0.8, now, self.safety_radius)


class KinematicWorld:
    """UAVs advanced together; `sleep` is the manager's clock step."""

    def __init__(self, view: WorldView, uavs, dt: float = 0.05, others_step=None):
        self.view, self.uavs, self.dt, self.t = view, {u.id: u for u in uavs}, dt, 0.0
        self.others_step = others_step  # called each step to move the UAVs no manager flies
        self.publish()

    def publish(self) -> None:
        for uav in self.uavs.values():
            self.view.update_agent(uav.agent_state(self.t))

    def now(self) -> float:
        return self.t

    def sleep(self) -> None:
        if self.others_step is not None:
            self.others_step(self)
        for uav in self.uavs.values():
            uav.advance(self.dt)
        self.t += self.dt
        self.publish()
