"""Geometric features (config `features: geometric`): the input vector in a form a small network can use.

ORCA-3D starts from the preferred velocity (simple guidance towards the goal) and changes it only to
leave the velocity obstacles of its neighbours. Both depend on distances, directions and closing
speeds, which a network of ReLU layers can only approximate from raw coordinates scaled by their
largest values. This module computes them from the raw input vector (the thesis layout, unchanged:
the NAI and the spec see no difference), inside the network:

| feature | size | what |
|---|---|---|
| goal distance, goal direction | 1 + 3 | norm and unit vector of goal_pose_rel |
| preferred velocity | 3 | simple guidance's velocity (`magna_uav.nai.simple`), saturated |
| per neighbour: distance, direction, closing speed, sideways velocity, present | 1 + 3 + 1 + 3 + 1 | see below |
| per obstacle: the same with the obstacle still | 9 | |

Simple guidance flies towards the goal at max speed, slowing down linearly within the braking
distance, plus the followed UAV's velocity for the follower roles. A neighbour's distance and
direction are those of its relative position; its closing speed and sideways velocity are own
velocity − its velocity, along and across that direction; present is 0 for a padded slot.

With these features the network also answers the change ORCA-3D makes to the preferred velocity
(the residual), not the velocity itself: free flight is then the answer 0, and the network's
capacity goes to the avoidance. The exported module adds the preferred velocity back, so it still
answers sel_vel in m/s from the raw vector.

The preferred velocity uses the max speed of the training data (one airframe) and the NAI's default
braking distance (max speed x 1 s); a mission that sets another brakingDistance for simple guidance
shifts it.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from magna_uav.nai.inputs import PAD_FACTOR, input_names
from magna_uav.nai.simple import DEFAULT_BRAKING_TIME

FEATURES = ("none", "geometric")
PER_THING = 9  # distance, direction (3), closing speed, sideways velocity (3), present


def _block(names: list[str], name: str) -> list[int]:
    return [names.index(f"{name}.{axis}") for axis in "xyz"]


class GeometricFeatures(nn.Module):
    """raw input vectors [B, d] -> (features [B, 7 + 9 N + 9 M], preferred velocity [B, 3]) (module table)."""

    if TYPE_CHECKING:  # the index buffers, declared for mypy only: TorchScript reads class annotations
        own_vel: torch.Tensor
        goal: torch.Tensor
        goal_vel: torch.Tensor
        others_pos: torch.Tensor
        others_vel: torch.Tensor
        obstacles_pos: torch.Tensor

    def __init__(self, role: str, n_neighbors: int, n_obstacles: int, neighbor_dist: float, max_speed: float):
        super().__init__()
        names = input_names(role, n_neighbors, n_obstacles)

        def index(rows: list[list[int]]) -> torch.Tensor:
            return torch.tensor(rows, dtype=torch.long).reshape(len(rows), 3)

        # index tensors, not lists: TorchScript cannot type an empty list (no neighbours, no obstacles)
        self.register_buffer("own_vel", index([_block(names, "own_vel")])[0])
        self.register_buffer("goal", index([_block(names, "goal_pose_rel")])[0])
        follower = "goal_vel.x" in names
        self.register_buffer("goal_vel", index([_block(names, "goal_vel") if follower else [0, 0, 0]])[0])
        self.follower = follower
        self.register_buffer("others_pos", index([_block(names, f"others_pos_rel[{k}]") for k in range(n_neighbors)]))
        self.register_buffer("others_vel", index([_block(names, f"others_vel[{k}]") for k in range(n_neighbors)]))
        self.register_buffer("obstacles_pos", index([_block(names, f"obstacles_pos_rel[{k}]")
                                                     for k in range(n_obstacles)]))
        self.n_neighbors = n_neighbors
        self.n_obstacles = n_obstacles
        self.pad = float(PAD_FACTOR * neighbor_dist)
        self.max_speed = float(max_speed)
        self.braking_distance = float(max_speed * DEFAULT_BRAKING_TIME)
        self.size = 7 + PER_THING * (n_neighbors + n_obstacles)

    def _preferred(self, x: torch.Tensor, goal: torch.Tensor, distance: torch.Tensor) -> torch.Tensor:
        speed = self.max_speed * torch.clamp(distance / self.braking_distance, max=1.0)
        velocity = goal * (speed / torch.clamp(distance, min=1e-12))
        if self.follower:
            velocity = velocity + x[:, self.goal_vel]
        norm = torch.linalg.vector_norm(velocity, dim=1, keepdim=True)
        return velocity * torch.clamp(self.max_speed / torch.clamp(norm, min=1e-12), max=1.0)

    def _relative(self, position: torch.Tensor, velocity: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        distance = torch.linalg.vector_norm(position, dim=1, keepdim=True)
        direction = position / torch.clamp(distance, min=1e-6)
        closing = (velocity * direction).sum(dim=1, keepdim=True)
        sideways = velocity - closing * direction
        return torch.cat([distance, direction, closing, sideways, present], dim=1)

    def _absent(self, position: torch.Tensor) -> torch.Tensor:
        """1 where the slot holds the padding (2 D, 0, 0), else 0, as [B, 1]."""
        pad = torch.zeros_like(position)
        pad[:, 0] = self.pad
        return (torch.abs(position - pad).amax(dim=1, keepdim=True) < 1e-4).to(position.dtype)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        own = x[:, self.own_vel]
        goal = x[:, self.goal]
        distance = torch.linalg.vector_norm(goal, dim=1, keepdim=True)
        preferred = self._preferred(x, goal, distance)
        parts = [distance, goal / torch.clamp(distance, min=1e-6), preferred]
        for k in range(self.n_neighbors):
            position = x[:, self.others_pos[k]]
            parts.append(self._relative(position, own - x[:, self.others_vel[k]], 1.0 - self._absent(position)))
        for k in range(self.n_obstacles):
            position = x[:, self.obstacles_pos[k]]
            parts.append(self._relative(position, own, 1.0 - self._absent(position)))
        return torch.cat(parts, dim=1), preferred


def build(run, max_speed: float) -> GeometricFeatures:
    """The feature map of a RunConfig (features: geometric) for UAVs of `max_speed`."""
    return GeometricFeatures(run.role, run.n_neighbors, run.n_obstacles, run.neighbor_dist, max_speed)


def one_max_speed(max_speed: np.ndarray, where: str) -> float:
    speeds = np.unique(np.asarray(max_speed, dtype=float))
    if len(speeds) != 1:
        raise ValueError(f"{where}: features geometric needs the samples of one airframe (one max speed), got "
                         f"{speeds.tolist()} m/s: learn from one UAV model, or use features none")
    return float(speeds[0])


def expand(x: np.ndarray, y: np.ndarray, features: GeometricFeatures) -> tuple[np.ndarray, np.ndarray]:
    """(x with the features appended, y less the preferred velocity): what the network trains on."""
    with torch.no_grad():
        extra, preferred = features(torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64)))
    return np.concatenate([x, extra.numpy()], axis=1), y - preferred.numpy()


def transformed(samples, run):
    """`samples` (mlr.pickler.Samples) as a `features: geometric` network trains on them (`expand`)."""
    features = build(run, one_max_speed(samples.max_speed, "the samples"))
    x, y = expand(samples.x, samples.y, features)
    return dataclasses.replace(samples, x=x, y=y)
