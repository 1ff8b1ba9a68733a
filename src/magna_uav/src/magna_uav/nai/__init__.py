"""The navigation algorithms interface (NAI): simple guidance, ORCA-3D and neural networks behind one call.

    nai = NavigationInterface(max_speed=2.0, safety_radius=0.3)
    nai.control("orca3", "set", ["N_neighbors_aware"], [1])      # a mission's algorithm_control
    command = nai.velocity(world_view, Goal([10, 0, 5]))          # Command(velocity, yaw_rate, ...)

Modules: goal (Goal, roles), simple (guidance, speed profile), inputs (the neural networks'
input vector, shared with mlr), orca (ORCA-3D agents and solver), neural (TorchScript
models and their JSON spec), interface (algorithm_control and commands).
"""
from magna_uav.nai.goal import ROLES, Goal
from magna_uav.nai.interface import ALGORITHMS, Command, NavigationInterface
from magna_uav.nai.simple import simple_velocity

__all__ = ["ALGORITHMS", "ROLES", "Command", "Goal", "NavigationInterface", "simple_velocity"]
