"""The optional depth observation: magna_sim's depth camera on each UAV, its image as the NAI gives it to networks.

`DepthObservation((width, height), fov)` renders with magna_sim's DepthCamera (the sim node's
`~depth_camera` model: forward-looking, pybullet's tiny renderer) and prepares the image with the NAI's
`prepare_depth`, so a network trained on it sees what it will see in flight: metres, (height, width)
float32, +inf (nothing within 20 m) read as 20 m. The environments that take `depth=(width, height)`
give a Dict observation {"vector": the NAI's input vector, "depth": this image}.
"""
from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from magna_uav.nai.neural import DEPTH_FAR, prepare_depth


class DepthObservation:
    def __init__(self, size: tuple[int, int], fov_deg: float = 90.0):
        width, height = (int(v) for v in size)
        if width < 1 or height < 1:
            raise ValueError(f"depth: {size!r} is (width, height) in pixels; give two whole numbers >= 1")
        self.width, self.height, self.fov_deg = width, height, float(fov_deg)
        self._camera: Any = None  # a magna_sim DepthCamera, made on the swarm's world at the first image

    def space(self) -> gym.spaces.Box:
        return gym.spaces.Box(0.0, DEPTH_FAR, (self.height, self.width), np.float32)

    def image(self, swarm, j: int, copy: int = 0) -> np.ndarray:
        if self._camera is None:
            from magna_sim.depth_camera import DepthCamera

            self._camera = DepthCamera(swarm.fleet.world.client, self.width, self.height, self.fov_deg)
        return prepare_depth(swarm.depth_image(j, self._camera, copy), self.height, self.width)


class SwarmObservation:
    """What UAV j of a swarm observes, and its space: the NAI's input vector, or with `depth=(width, height)`
    the Dict {"vector", "depth"}. The single-agent and PettingZoo environments share it."""

    def __init__(self, swarm, depth: tuple[int, int] | None = None, depth_fov: float = 90.0):
        self.swarm = swarm
        self.depth = DepthObservation(depth, depth_fov) if depth is not None else None
        vector = gym.spaces.Box(-np.inf, np.inf, (swarm.observation_size,), np.float32)
        self.space: gym.spaces.Space = (vector if self.depth is None
                                        else gym.spaces.Dict({"vector": vector, "depth": self.depth.space()}))

    def __call__(self, j: int, copy: int = 0):
        vector = self.swarm.observation(j, copy)
        return vector if self.depth is None else {"vector": vector, "depth": self.depth.image(self.swarm, j, copy)}
