"""The `magna learn rl` config: its keys, their defaults and checks (mlr/gym/README.md has the table)."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mlr.config import ConfigError, read_mapping

KEYS: dict[str, tuple[Any, str]] = {
    "world": (None, "the world as magna run takes it, e.g. Gym/Empty_4_Cylinders"),
    "mission": (None, "a mission with a spawn_agents state and follow_path paths, e.g. Gym/2UAVs_2paths_4_Cylinders"),
    "copies": (8, "copies of the scenario flown together, 1..64 (each UAV of each is a sub-environment)"),
    "n_neighbors": (1, "UAVs in the observation, 0..10"),
    "n_obstacles": (2, "obstacles in the observation, 0..10"),
    "neighbor_dist": (6.0, "metres within which UAVs and obstacles are seen, > 0"),
    "max_steps": (300, "control steps (10 Hz) before an episode is truncated, >= 1"),
    "total_steps": (200_000, "agent-steps to train, >= 1"),
    "checkpoint_every": (50_000, "agent-steps between checkpoints, >= 1"),
    "seed": (0, "a whole number"),
    "threads": (1, "torch threads, >= 1"),
    "ppo": ({}, "stable-baselines3 PPO keyword arguments, e.g. {n_steps: 256, batch_size: 1024}"),
    "reward": ({}, "RewardWeights fields to change, e.g. {collision_penalty: 20}"),
    "encounters": (0.0, "share of episodes started with two UAVs on a collision course, 0..1 (mlr/gym/README.md)"),
    "features": ("none", "none (the raw input vector) or geometric (mlr/gym/policy_features.py)"),
    "eval_flights": (32, "whole missions flown to measure the success rate at each checkpoint, >= 1"),
}
WHOLE_RANGES = {"copies": (1, 64), "n_neighbors": (0, 10), "n_obstacles": (0, 10), "max_steps": (1, None),
                "total_steps": (1, None), "checkpoint_every": (1, None), "seed": (None, None), "threads": (1, None),
                "eval_flights": (1, None)}
DEFAULT_PPO = {"n_steps": 256, "batch_size": 1024}


class RlError(ValueError):
    """Bad config or output folder: printed as `mlr: <message>`, exit status 2."""


@dataclass(frozen=True)
class RlConfig:
    path: Path
    world: str
    mission: str
    copies: int
    n_neighbors: int
    n_obstacles: int
    neighbor_dist: float
    max_steps: int
    total_steps: int
    checkpoint_every: int
    seed: int
    threads: int
    ppo: dict
    reward: dict
    eval_flights: int
    encounters: float
    features: str

    @property
    def name(self) -> str:
        return self.path.stem

    def as_json(self) -> dict:
        return {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(self).items()}


def load_config(path: str | Path) -> RlConfig:
    from mlr.gym.reward import RewardWeights

    path = Path(path)
    try:
        raw = read_mapping(path, "a mapping (world: ..., mission: ..., total_steps: ...)")
    except ConfigError as err:
        raise RlError(str(err)) from None
    unknown = [key for key in raw if key not in KEYS]
    if unknown:
        raise RlError(f"{path}: unknown key {unknown[0]!r}: known keys are {', '.join(KEYS)}")
    values = {key: raw.get(key, default) for key, (default, _) in KEYS.items()}
    for key in ("world", "mission"):
        if not isinstance(values[key], str) or "/" not in values[key]:
            raise RlError(f"{path}: {key} is {values[key]!r}: give {KEYS[key][1]}")
    for key, (low, high) in WHOLE_RANGES.items():
        value = values[key]
        if isinstance(value, bool) or not isinstance(value, int) or (low is not None and value < low) \
                or (high is not None and value > high):
            raise RlError(f"{path}: {key} is {value!r}: give {KEYS[key][1]}")
    dist = values["neighbor_dist"]
    if isinstance(dist, bool) or not isinstance(dist, int | float) or not math.isfinite(dist) or dist <= 0:
        raise RlError(f"{path}: neighbor_dist is {dist!r}: give {KEYS['neighbor_dist'][1]}")
    share = values["encounters"]
    if isinstance(share, bool) or not isinstance(share, int | float) or not 0.0 <= share <= 1.0:
        raise RlError(f"{path}: encounters is {share!r}: give {KEYS['encounters'][1]}")
    if values["features"] not in ("none", "geometric"):
        raise RlError(f"{path}: features is {values['features']!r}: give {KEYS['features'][1]}")
    for key in ("ppo", "reward"):
        if not isinstance(values[key], dict):
            raise RlError(f"{path}: {key} is {values[key]!r}: give {KEYS[key][1]}")
    fields = {f.name for f in dataclasses.fields(RewardWeights)}
    wrong = [k for k in values["reward"] if k not in fields]
    if wrong:
        raise RlError(f"{path}: reward.{wrong[0]} is not a reward weight; they are {', '.join(sorted(fields))}")
    return RlConfig(path, values["world"], values["mission"], values["copies"], values["n_neighbors"],
                    values["n_obstacles"], float(dist), values["max_steps"], values["total_steps"],
                    values["checkpoint_every"], values["seed"], values["threads"],
                    {**DEFAULT_PPO, **values["ppo"]}, dict(values["reward"]), values["eval_flights"],
                    float(values["encounters"]), values["features"])
