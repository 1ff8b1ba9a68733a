"""Data augmentation by the teacher's symmetry: a random rotation about the vertical axis.

ORCA-3D and the simple guidance see only relative geometry, so turning the whole scene about
the z axis turns the chosen velocity by the same angle: (R x, R y) is as good a sample as (x, y).
Each training batch is turned by a random yaw per sample, which shows the network every heading
of an encounter that the missions flew in a few. Padding slots (the filler of a missing
neighbour or obstacle, `magna_uav.nai.inputs.pad_position`) stay where they are, exactly as
the NAI pads a turned scene; scalars (the `distance` input) are left alone.
"""
from __future__ import annotations

import math

import torch

from magna_uav.nai.inputs import PAD_FACTOR, input_names


class YawAugmenter:
    """Turns raw (not normalised) input vectors and labels by one random yaw per sample."""

    def __init__(self, role: str, n_neighbors: int, n_obstacles: int, neighbor_dist: float):
        names = input_names(role, n_neighbors, n_obstacles)
        triples = [i for i, name in enumerate(names) if name.endswith(".x")]
        for i in triples:
            assert names[i + 1].endswith(".y") and names[i + 2].endswith(".z"), names[i:i + 3]
        self.x_columns = torch.tensor(triples, dtype=torch.long)
        # for each triple: the position triple whose padding exempts it (itself, or the neighbour's position
        # for its velocity), -1 for blocks that are never padded
        position_of = []
        for i in triples:
            name = names[i]
            if name.startswith(("others_pos_rel[", "obstacles_pos_rel[")):
                position_of.append(i)
            elif name.startswith("others_vel["):
                position_of.append(names.index(name.replace("others_vel", "others_pos_rel")))
            else:
                position_of.append(-1)
        self.position_of = torch.tensor(position_of, dtype=torch.long)
        self.pad = torch.tensor([PAD_FACTOR * neighbor_dist, 0.0, 0.0])

    def _padded(self, x: torch.Tensor) -> torch.Tensor:
        """[B, T] bool: triple t of sample b is (or belongs to) a padding slot."""
        padded = torch.zeros(x.shape[0], len(self.x_columns), dtype=torch.bool)
        for t, p in enumerate(self.position_of.tolist()):
            if p >= 0:
                # after the float32 normalisation round trip the filler is equal only to within rounding
                padded[:, t] = torch.isclose(x[:, p:p + 3], self.pad.to(x.dtype), atol=1e-3).all(dim=1)
        return padded

    def __call__(self, x: torch.Tensor, y: torch.Tensor, generator: torch.Generator | None = None):
        """(turned x, turned y): x [B, D] raw inputs, y [B, 3] raw labels; new tensors."""
        angle = torch.rand(x.shape[0], generator=generator) * (2 * math.pi)
        cos, sin = torch.cos(angle).unsqueeze(1), torch.sin(angle).unsqueeze(1)
        x = x.clone()
        keep = self._padded(x)
        columns = self.x_columns
        xs, ys = x[:, columns], x[:, columns + 1]
        turned_x, turned_y = cos * xs - sin * ys, sin * xs + cos * ys
        x[:, columns] = torch.where(keep, xs, turned_x)
        x[:, columns + 1] = torch.where(keep, ys, turned_y)
        y = torch.stack([cos[:, 0] * y[:, 0] - sin[:, 0] * y[:, 1], sin[:, 0] * y[:, 0] + cos[:, 0] * y[:, 1],
                         y[:, 2]], dim=1)
        return x, y
