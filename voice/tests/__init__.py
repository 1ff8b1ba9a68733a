"""Unit tests of the voice assistant (no ROS master, no audio hardware needed)."""
