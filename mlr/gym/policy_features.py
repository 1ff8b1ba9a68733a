"""The geometric features (mlr.features) as a stable-baselines3 features extractor, for RL config `features: geometric`.

A PPO policy on the raw input vector sees the other UAV's position and velocity in the map frame. To
avoid it, it must learn what the geometry of an encounter is (distance, line of sight, closing speed,
sideways velocity) from coordinates, and a map-frame reflex ("dodge towards +y") is what it learns first;
two UAVs with that reflex dodge the same way and meet anyway. These features give the policy the geometry
directly, as they give it to the supervised networks. The extractor feeds the policy [x, features(x)],
both divided by SCALE, from the raw vector: with it, VecNormalize leaves observations alone (rl.py), so
the exported module needs no statistics.
"""
from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from mlr.features import GeometricFeatures

SCALE = 3.0  # m and m/s: inputs run to 2 x neighbor_dist (the padding), velocities to max_speed


class GeometricExtractor(BaseFeaturesExtractor):
    def __init__(self, observation_space: gym.spaces.Box, n_neighbors: int, n_obstacles: int, neighbor_dist: float,
                 max_speed: float):
        geometry = GeometricFeatures("path", n_neighbors, n_obstacles, neighbor_dist, max_speed)
        super().__init__(observation_space, int(observation_space.shape[0]) + geometry.size)
        self.geometry = geometry
        self.scale = SCALE  # an attribute: TorchScript reads no module globals

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        features, _ = self.geometry(observations)
        return torch.cat([observations, features.to(observations.dtype)], dim=1) / self.scale
