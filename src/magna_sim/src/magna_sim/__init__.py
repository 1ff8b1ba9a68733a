"""MAGNA's pybullet world: UAVs and obstacles in one headless physics world, served as the GRVC UAL API.

The library has no ROS import outside `ros_*` modules and `node`, so every part
of the physics, the flight models and the UAL state logic is unit-testable.
"""
