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


def dict_space(vector: gym.spaces.Box, depth: DepthObservation) -> gym.spaces.Dict:
    return gym.spaces.Dict({"vector": vector, "depth": depth.space()})
