"""A trained PPO policy as the TorchScript file and JSON spec the NAI flies (format: magna_uav.nai.neural).

The module takes the NAI's raw input vector and answers the velocity command, as every exported MAGNA
network does. Inside it, in order, is what stable-baselines3 does to an observation at prediction time:
- VecNormalize's observation scaling, (x - mean) / sqrt(var + epsilon) clipped to ±clip_obs, when the
  policy was trained under it;
- the policy's features extractor (SB3's flatten, the identity here, or mlr.gym.policy_features);
- the actor network and its action head, the Gaussian's mean (deterministic actions);
- the clip to the action space, ±max_speed per axis.
The NAI then saturates the command to max_speed, as for any algorithm. After writing, the file is
loaded back through the NAI's loader and must give stable-baselines3's deterministic actions to 1e-5
m/s; otherwise both files are removed and the export fails.
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from magna_common.files import write_atomically, write_text_atomically
from magna_uav.nai.inputs import input_names, output_names
from magna_uav.nai.neural import load_model, spec_path

if TYPE_CHECKING:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

ROLE = "path"
TOLERANCE = 1e-5  # m/s


class PolicyNetwork(nn.Module):
    """velocity = clip(action_net(actor(features(clip((x - mean) / scale, ±clip_obs)))), low, high)."""

    if TYPE_CHECKING:  # buffers, declared for mypy only (TorchScript reads class annotations)
        mean: torch.Tensor
        scale: torch.Tensor
        low: torch.Tensor
        high: torch.Tensor

    def __init__(self, features: nn.Module, actor: nn.Module, action_net: nn.Module, mean: np.ndarray,
                 scale: np.ndarray, clip_obs: float, low: np.ndarray, high: np.ndarray):
        super().__init__()
        self.features = features
        self.actor = actor
        self.action_net = action_net
        self.clip_obs = float(clip_obs)
        for name, value in (("mean", mean), ("scale", scale), ("low", low), ("high", high)):
            self.register_buffer(name, torch.as_tensor(np.asarray(value, dtype=np.float32)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = torch.clamp((x - self.mean) / self.scale, -self.clip_obs, self.clip_obs)
        return torch.maximum(torch.minimum(self.action_net(self.actor(self.features(z))), self.high), self.low)


def policy_module(model: PPO, normalize: VecNormalize | None = None) -> PolicyNetwork:
    """The PPO policy (and VecNormalize's observation statistics, when given) as one module on raw inputs."""
    import copy

    from stable_baselines3.common.running_mean_std import RunningMeanStd

    policy = model.policy
    size = _box(model.observation_space, "observation").shape[0]
    if normalize is not None and normalize.norm_obs:
        stats = normalize.obs_rms
        if not isinstance(stats, RunningMeanStd):
            raise ValueError("VecNormalize holds statistics per key of a Dict observation; the NAI gives one vector")
        mean, scale, clip_obs = stats.mean, np.sqrt(stats.var + normalize.epsilon), normalize.clip_obs
    else:
        mean, scale, clip_obs = np.zeros(size), np.ones(size), float("inf")
    space = _box(model.action_space, "action")
    features = copy.deepcopy(policy.pi_features_extractor).cpu().eval()
    actor = copy.deepcopy(policy.mlp_extractor.policy_net).cpu().eval()
    head = copy.deepcopy(policy.action_net).cpu().eval()
    return PolicyNetwork(features, actor, head, mean, scale, clip_obs, space.low, space.high).eval()


def export_policy(model: PPO, path: str | Path, n_neighbors: int, n_obstacles: int, neighbor_dist: float,
                  normalize: VecNormalize | None = None, about: dict | None = None, overwrite: bool = False) -> Path:
    """Write `path` (.pt) and its spec (.json) for the NAI; check them against `model` (module docstring)."""
    path = Path(path)
    if path.suffix != ".pt":
        raise ValueError(f"{path}: an exported policy is a .pt file (its spec goes beside it as .json)")
    spec_file = spec_path(path)
    if not overwrite:
        for target in (path, spec_file):
            if target.exists():
                raise FileExistsError(f"{target}: already exists; pass --force to replace it, or choose another "
                                      "path")
    names = input_names(ROLE, n_neighbors, n_obstacles)
    if len(names) != _box(model.observation_space, "observation").shape[0]:
        raise ValueError(f"the policy takes {model.observation_space.shape} observations; the path role with "
                         f"{n_neighbors} neighbour(s) and {n_obstacles} obstacle(s) has {len(names)} inputs")
    module = policy_module(model, normalize)
    spec = {"role": ROLE, "n_neighbors": n_neighbors, "n_obstacles": n_obstacles, "inputs": names,
            "outputs": output_names(), "image": None, "neighbor_dist": neighbor_dist,
            "about": {"trained_by": "reinforcement learning (PPO, stable-baselines3)", **(about or {})}}
    try:
        with warnings.catch_warnings():  # torch calls TorchScript deprecated; it is the format the NAI flies
            warnings.filterwarnings("ignore", category=DeprecationWarning)
            scripted = torch.jit.script(module)
            write_atomically(path, lambda out: torch.jit.save(scripted, out), overwrite=True, binary=True)
        write_text_atomically(spec_file, json.dumps(spec, indent=2) + "\n", overwrite=True)
        _check(model, normalize, path, len(names))
    except BaseException:
        for leftover in (path, spec_file):
            leftover.unlink(missing_ok=True)
        raise
    return path


def _box(space, what: str):
    """`space` as the gymnasium Box of one vector it must be."""
    import gymnasium as gym

    if not (isinstance(space, gym.spaces.Box) and len(space.shape) == 1):
        raise ValueError(f"the policy's {what} space is {space}; the NAI flies policies of one vector in, one out")
    return space


def _check(model: PPO, normalize: VecNormalize | None, path: Path, size: int) -> None:
    """The NAI's loader must give SB3's deterministic actions on varied raw inputs."""
    rng = np.random.default_rng(0)
    raw = rng.normal(0.0, 3.0, (50, size)).astype(np.float32)
    seen = normalize.normalize_obs(raw) if normalize is not None else raw
    expected, _ = model.predict(seen, deterministic=True)
    nai = load_model(path)
    worst = max(float(np.max(np.abs(nai.predict(x, None) - e))) for x, e in zip(raw, expected, strict=True))
    if not worst <= TOLERANCE:
        raise RuntimeError(f"{path}: the exported policy differs from the trained one by {worst:.3g} m/s "
                           f"(allowed {TOLERANCE:g}); not exported")
