"""The networks, built from a RunConfig: an MLP on the input vector, and a CNN+MLP that also
looks at the depth image. Both take and give normalised values (mlr.preprocess); the
exported module (mlr.export) wraps them with the normalisation and its inverse.
"""
from __future__ import annotations

import torch
from torch import nn

from mlr.config import RunConfig

_ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh}


def _mlp(size_in: int, hidden: tuple[int, ...], activation: str, size_out: int = 3) -> nn.Sequential:
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(size_in, width), _ACTIVATIONS[activation]()]
        size_in = width
    layers.append(nn.Linear(size_in, size_out))
    return nn.Sequential(*layers)


class MLP(nn.Module):
    """Fully connected layers of the given widths, then 3 outputs (sel_vel)."""

    def __init__(self, size_in: int, hidden: tuple[int, ...], activation: str = "relu"):
        super().__init__()
        self.layers = _mlp(size_in, hidden, activation)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.layers(x)


class CNNMLP(nn.Module):
    """Convolutions over the depth image [B, 1, H, W]; their features join the input vector in an MLP."""

    def __init__(self, size_in: int, hidden: tuple[int, ...], image_size: tuple[int, int], conv_depth: int,
                 conv_channels: int, patch_size: int, padding: str, pooling: str, activation: str = "relu"):
        super().__init__()
        layers: list[nn.Module] = []
        channels = 1
        for k in range(conv_depth):
            out = conv_channels * 2 ** k
            layers += [nn.Conv2d(channels, out, patch_size, padding=patch_size // 2 if padding == "same" else 0),
                       _ACTIVATIONS[activation]()]
            if pooling == "max":
                layers.append(nn.MaxPool2d(2))
            elif pooling == "avg":
                layers.append(nn.AvgPool2d(2))
            channels = out
        layers.append(nn.Flatten())
        self.conv = nn.Sequential(*layers)
        with torch.no_grad():
            features = self.conv(torch.zeros(1, 1, *image_size)).shape[1]
        self.head = _mlp(features + size_in, hidden, activation)

    def forward(self, image: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        return self.head(torch.cat([self.conv(image), x], dim=1))


def build_model(run: RunConfig, size_in: int) -> nn.Module:
    if run.model == "mlp":
        return MLP(size_in, run.hidden_layers, run.activation)
    return CNNMLP(size_in, run.hidden_layers, run.image_size, run.conv_depth, run.conv_channels, run.patch_size,
                  run.padding, run.pooling, run.activation)


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
