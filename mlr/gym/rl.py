"""`magna learn rl CONFIG`: PPO (stable-baselines3, CPU) on the gym, one shared policy for every UAV.

The config (YAML or JSON; mlr/gym/README.md has the table) names the world and mission, the gym's
settings and PPO's. The run writes into its output folder:
- `tensorboard/`: SB3's curves (episode return and length, losses), for `magna learn board`;
- `checkpoints/ppo_<steps>.zip` and `vecnormalize_<steps>.pkl` every `checkpoint_every` steps: the same
  command resumes from the latest one after an interruption;
- `policy.zip`, `vecnormalize.pkl`: the final model and observation statistics;
- `policy.pt` and `policy.json`: the policy exported for the NAI (mlr.gym.export);
- `rl.json`: the config, steps, wall time, the mean return of the first and last episodes, and the
  success rate (mlr.gym.evaluate: whole missions flown deterministically in the gym) at every checkpoint
  and at the end, with the training wall time it was reached at; TensorBoard has it as eval/success_rate,
  and `success.png` draws it against the training time.
"""
from __future__ import annotations

import dataclasses
import json
import math
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from magna_common.files import write_text_atomically
from mlr.config import ConfigError, read_mapping

HELP = "reinforcement learning: PPO on the gym (one policy for every UAV), with TensorBoard and checkpoints"
DESCRIPTION = __doc__
EXAMPLES = """\
examples:
  magna learn rl mlr/configs/rl_four_cylinders.yaml --search-path ../shared/ros_magna_corpus   # [long]
  magna learn rl mlr/configs/rl_four_cylinders.yaml --search-path ../shared/ros_magna_corpus \\
      --total-steps 20000 -o /tmp/rl_quick    # a short run [long]
"""

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


def latest_checkpoint(folder: Path) -> tuple[int, Path, Path] | None:
    """(steps, model, statistics) of the newest complete checkpoint in `folder`, or None."""
    found = []
    for model in folder.glob("ppo_*.zip"):
        match = re.fullmatch(r"ppo_(\d+)\.zip", model.name)
        stats = folder / f"vecnormalize_{match.group(1)}.pkl" if match else None
        if match and stats is not None and stats.is_file():
            found.append((int(match.group(1)), model, stats))
    return max(found) if found else None


def train(config: RlConfig, out: Path, search_path: list[Path], progress: bool = True) -> dict:
    """Train (or go on training from the latest checkpoint), export, and write rl.json; its numbers."""
    import numpy as np
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from mlr.gym.evaluate import evaluate
    from mlr.gym.export import export_policy, policy_module
    from mlr.gym.reward import RewardWeights
    from mlr.gym.scenario import load_scenario
    from mlr.gym.vector import SwarmVecEnv

    torch.set_num_threads(config.threads)
    scenario = load_scenario(config.world, config.mission, search_path)
    weights = RewardWeights(**config.reward)
    base = SwarmVecEnv(scenario, config.copies, config.n_neighbors, config.n_obstacles, config.neighbor_dist,
                       config.max_steps, weights, config.seed, config.encounters)
    checkpoints = out / "checkpoints"
    checkpoints.mkdir(parents=True, exist_ok=True)
    resumed = latest_checkpoint(checkpoints)
    if resumed is not None:
        venv = VecNormalize.load(str(resumed[2]), VecMonitor(base))
        model = PPO.load(str(resumed[1]), env=venv, device="cpu")
    else:
        ppo = dict(config.ppo)
        if config.features == "geometric":  # features from the raw vector: VecNormalize leaves observations alone
            from mlr.gym.policy_features import GeometricExtractor

            ppo["policy_kwargs"] = {**ppo.get("policy_kwargs", {}), "features_extractor_class": GeometricExtractor,
                                    "features_extractor_kwargs": {
                                        "n_neighbors": config.n_neighbors, "n_obstacles": config.n_obstacles,
                                        "neighbor_dist": config.neighbor_dist, "max_speed": base.max_speed}}
        venv = VecNormalize(VecMonitor(base), norm_obs=config.features == "none", norm_reward=True)
        model = PPO("MlpPolicy", venv, seed=config.seed, device="cpu", tensorboard_log=str(out / "tensorboard"),
                    **ppo)
    returns: list[float] = []
    history: list[dict] = []  # the success rate at each checkpoint
    started = time.monotonic()
    earlier = [e for e in _earlier_history(out) if resumed is not None and e["steps"] <= resumed[0]]

    def success(steps: int, log: bool = True) -> dict:
        module = policy_module(model, venv)

        def policy(inputs):
            with torch.no_grad():
                return module(torch.as_tensor(inputs, dtype=torch.float32)).numpy()

        found = evaluate(policy, scenario, config.eval_flights, n_neighbors=config.n_neighbors,
                         n_obstacles=config.n_obstacles, neighbor_dist=config.neighbor_dist,
                         goal_radius=weights.goal_radius)
        wall = (earlier[-1]["wall_seconds"] if earlier else 0.0) + time.monotonic() - started
        entry = {"steps": steps, "wall_seconds": wall, **found.as_dict()}
        history.append(entry)
        if log:  # only while learning: a run resumed at its last step has no logger
            model.logger.record("eval/success_rate", found.success_rate)
            model.logger.record("eval/min_gap", found.min_gap)
        return entry

    class Progress(BaseCallback):
        """Checkpoints, episode returns, and a progress bar (tqdm) over the agent-steps."""

        def _on_training_start(self) -> None:
            from tqdm import tqdm

            self.bar = tqdm(total=config.total_steps, initial=min(self.num_timesteps, config.total_steps), unit="step",
                            disable=not progress, desc=f"rl {config.name}", leave=False, mininterval=0.5)
            self.next_checkpoint = (self.num_timesteps // config.checkpoint_every + 1) * config.checkpoint_every

        def _on_step(self) -> bool:
            self.bar.update(max(0, min(self.training_env.num_envs, config.total_steps - self.bar.n)))
            returns.extend(info["episode"]["r"] for info in self.locals["infos"] if "episode" in info)
            if self.num_timesteps >= self.next_checkpoint:
                self._save(self.num_timesteps)
                self.next_checkpoint += config.checkpoint_every
            return True

        def _save(self, steps: int) -> None:
            # statistics first: a model without them is not a checkpoint (latest_checkpoint)
            venv.save(str(checkpoints / f"vecnormalize_{steps}.pkl"))
            model.save(str(checkpoints / f"ppo_{steps}.zip"))
            entry = success(steps)
            self.bar.set_postfix(success=f"{entry['succeeded']}/{entry['flights']}")
            _write_history(out, earlier + history)

        def _on_training_end(self) -> None:
            self.bar.close()

    left = config.total_steps - model.num_timesteps
    if left > 0:
        model.learn(left, callback=Progress(), reset_num_timesteps=resumed is None, tb_log_name="ppo")
    wall = time.monotonic() - started
    measured = history and history[-1]["steps"] == model.num_timesteps  # at a checkpoint that was the last step
    final = history[-1] if measured else success(int(model.num_timesteps), log=left > 0)
    _write_history(out, earlier + history)
    from mlr.gym.history_plot import draw_history

    draw_history(earlier + history, out / "success.png", config.name)
    model.save(str(out / "policy.zip"))
    venv.save(str(out / "vecnormalize.pkl"))
    export_policy(model, out / "policy.pt", config.n_neighbors, config.n_obstacles, config.neighbor_dist,
                  normalize=venv, about={"config": config.name, "steps": int(model.num_timesteps)},
                  overwrite=True)
    window = max(1, min(100, len(returns) // 4)) if returns else 1
    numbers = {"config": config.as_json(), "steps": int(model.num_timesteps), "wall_seconds": wall,
               "resumed_from": resumed[0] if resumed else None, "episodes": len(returns),
               "first_mean_return": float(np.mean(returns[:window])) if returns else None,
               "last_mean_return": float(np.mean(returns[-window:])) if returns else None,
               "success_rate": final["success_rate"], "evaluation": final, "history": earlier + history}
    write_text_atomically(out / "rl.json", json.dumps(numbers, indent=2) + "\n", overwrite=True)
    venv.close()
    return numbers


def _earlier_history(out: Path) -> list[dict]:
    """The success rates an interrupted run measured before the checkpoint it resumes from."""
    record = out / "history.json"
    return json.loads(record.read_text()) if record.is_file() else []


def _write_history(out: Path, history: list[dict]) -> None:
    write_text_atomically(out / "history.json", json.dumps(history, indent=2) + "\n", overwrite=True)


def prepare_output(config: RlConfig, out: Path, force: bool) -> None:
    """OUT/config.json names the config a folder's checkpoints belong to; another config is refused, unless
    `force`, which starts afresh (the old checkpoints and curves are removed)."""
    import shutil

    record = out / "config.json"
    mine = {k: v for k, v in config.as_json().items() if k not in ("path", "total_steps")}
    if record.is_file():
        theirs = json.loads(record.read_text())
        if theirs != mine and not force:
            changed = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
            raise RlError(f"{out}: holds a run of another config (differs in {', '.join(changed)}); give another "
                          "-o/--output, or --force to start afresh there")
        if theirs != mine:
            for name in ("checkpoints", "tensorboard"):
                shutil.rmtree(out / name, ignore_errors=True)
            (out / "history.json").unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomically(record, json.dumps(mine, indent=2) + "\n", overwrite=True)


def add_arguments(parser) -> None:
    from magna_common.cli_vocabulary import add_force, add_output, add_search_path

    parser.add_argument("config", type=Path, help="the RL config (YAML or JSON; mlr/gym/README.md)")
    add_search_path(parser, what="the world and mission files")
    add_output(parser, metavar="DIR", help="where the run goes (default ~/magna_data/mlr/rl/NAME)")
    parser.add_argument("--total-steps", type=int, metavar="N", help="agent-steps to train (default: the config's)")
    add_force(parser, help="start afresh in an output folder that holds a run of another config")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    import sys

    from magna_common.errors import UsageError
    from mlr.gym.scenario import ScenarioError

    try:
        config = load_config(args.config)
        if args.total_steps is not None:
            if args.total_steps < 1:
                raise RlError(f"--total-steps is {args.total_steps}: give a whole number >= 1")
            config = dataclasses.replace(config, total_steps=args.total_steps)
        out = Path(args.output).expanduser().resolve() if args.output is not None \
            else Path("~/magna_data/mlr/rl").expanduser() / config.name
        prepare_output(config, out, args.force)
        numbers = train(config, out, [Path(p) for p in args.search_path], progress=not args.quiet)
    except (RlError, ScenarioError) as err:
        raise UsageError(" ".join(str(err).split())) from None
    except KeyboardInterrupt:
        print("rl: interrupted; run the same command again to go on from the last checkpoint", file=sys.stderr)
        return 130
    print(f"rl: {numbers['steps']} steps in {numbers['wall_seconds'] / 60:.1f} min; mean return "
          f"{numbers['first_mean_return']} (first episodes) -> {numbers['last_mean_return']} (last)")
    final = numbers["evaluation"]
    print(f"rl: success rate {final['succeeded']}/{final['flights']} whole missions flown in the gym "
          f"({final['success_rate']:.0%}), minimum gap {final['min_gap']:.2f} m")
    print(f"rl: {out / 'policy.pt'}, {out / 'rl.json'}, TensorBoard: magna learn board {out / 'tensorboard'}")
    return 0
