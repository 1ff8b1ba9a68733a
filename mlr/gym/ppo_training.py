"""PPO training for `magna learn rl`: the model (new or resumed), the success rate at each checkpoint, the run.

`train` builds the vectorised gym and PPO (or loads the latest checkpoint of an interrupted run), learns,
measures the success rate (mlr.gym.evaluate) at every checkpoint and at the end, and writes the outputs
mlr.gym.rl lists. stable-baselines3 and torch are imported here, not by the CLI module, so `--help` stays fast.
"""
from __future__ import annotations

import json
import re
import time
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize
from tqdm import tqdm

from magna_common.files import write_text_atomically
from mlr.gym.evaluate import evaluate
from mlr.gym.export import export_policy, policy_module
from mlr.gym.history_plot import draw_history
from mlr.gym.reward import RewardWeights
from mlr.gym.rl_config import RlConfig
from mlr.gym.scenario import Scenario, load_scenario
from mlr.gym.vector import SwarmVecEnv


def latest_checkpoint(folder: Path) -> tuple[int, Path, Path] | None:
    """(steps, model, statistics) of the newest complete checkpoint in `folder`, or None."""
    found = []
    for model in folder.glob("ppo_*.zip"):
        match = re.fullmatch(r"ppo_(\d+)\.zip", model.name)
        stats = folder / f"vecnormalize_{match.group(1)}.pkl" if match else None
        if match and stats is not None and stats.is_file():
            found.append((int(match.group(1)), model, stats))
    return max(found) if found else None


def earlier_history(out: Path) -> list[dict]:
    """The success rates an interrupted run measured before the checkpoint it resumes from."""
    record = out / "history.json"
    return json.loads(record.read_text()) if record.is_file() else []


def write_history(out: Path, history: list[dict]) -> None:
    write_text_atomically(out / "history.json", json.dumps(history, indent=2) + "\n", overwrite=True)


def make_model(config: RlConfig, base: SwarmVecEnv, out: Path,
               resumed: tuple[int, Path, Path] | None) -> tuple[PPO, VecNormalize]:
    """PPO on `base` with VecNormalize: loaded from the `resumed` checkpoint, or new from the config."""
    if resumed is not None:
        venv = VecNormalize.load(str(resumed[2]), VecMonitor(base))
        return PPO.load(str(resumed[1]), env=venv, device="cpu"), venv
    ppo = dict(config.ppo)
    if config.features == "geometric":  # features from the raw vector: VecNormalize leaves observations alone
        from mlr.gym.policy_features import GeometricExtractor

        ppo["policy_kwargs"] = {**ppo.get("policy_kwargs", {}), "features_extractor_class": GeometricExtractor,
                                "features_extractor_kwargs": {
                                    "n_neighbors": config.n_neighbors, "n_obstacles": config.n_obstacles,
                                    "neighbor_dist": config.neighbor_dist, "max_speed": base.max_speed}}
    venv = VecNormalize(VecMonitor(base), norm_obs=config.features == "none", norm_reward=True)
    model = PPO("MlpPolicy", venv, seed=config.seed, device="cpu", tensorboard_log=str(out / "tensorboard"), **ppo)
    return model, venv


class SuccessMeter:
    """Measures the policy's success rate on whole gym missions, and keeps the history of the measures; the
    training time of an earlier, interrupted run (`earlier`) counts in their wall time."""

    def __init__(self, model: PPO, venv: VecNormalize, scenario: Scenario, config: RlConfig, goal_radius: float,
                 earlier: list[dict]):
        self.model, self.venv, self.scenario, self.config = model, venv, scenario, config
        self.goal_radius, self.earlier = goal_radius, earlier
        self.history: list[dict] = []
        self.started = time.monotonic()

    def measure(self, steps: int, log: bool = True) -> dict:
        """The success rate now, added to the history; with `log`, also to TensorBoard (only while learning:
        a run resumed at its last step has no logger)."""
        module = policy_module(self.model, self.venv)

        def policy(inputs):
            with torch.no_grad():
                return module(torch.as_tensor(inputs, dtype=torch.float32)).numpy()

        config = self.config
        found = evaluate(policy, self.scenario, config.eval_flights, n_neighbors=config.n_neighbors,
                         n_obstacles=config.n_obstacles, neighbor_dist=config.neighbor_dist,
                         goal_radius=self.goal_radius)
        wall = (self.earlier[-1]["wall_seconds"] if self.earlier else 0.0) + time.monotonic() - self.started
        entry = {"steps": steps, "wall_seconds": wall, **found.as_dict()}
        self.history.append(entry)
        if log:
            self.model.logger.record("eval/success_rate", found.success_rate)
            self.model.logger.record("eval/min_gap", found.min_gap)
        return entry

    def whole_history(self) -> list[dict]:
        return self.earlier + self.history


class CheckpointProgress(BaseCallback):
    """Checkpoints with their success rate, the episode returns, and a progress bar (tqdm) over the agent-steps."""

    def __init__(self, config: RlConfig, out: Path, meter: SuccessMeter, show: bool):
        super().__init__()
        self.config, self.out, self.meter, self.show = config, out, meter, show
        self.returns: list[float] = []

    def _on_training_start(self) -> None:
        total, every = self.config.total_steps, self.config.checkpoint_every
        self.bar = tqdm(total=total, initial=min(self.num_timesteps, total), unit="step", disable=not self.show,
                        desc=f"rl {self.config.name}", leave=False, mininterval=0.5)
        self.next_checkpoint = (self.num_timesteps // every + 1) * every

    def _on_step(self) -> bool:
        self.bar.update(max(0, min(self.training_env.num_envs, self.config.total_steps - self.bar.n)))
        self.returns.extend(info["episode"]["r"] for info in self.locals["infos"] if "episode" in info)
        if self.num_timesteps >= self.next_checkpoint:
            self._save(self.num_timesteps)
            self.next_checkpoint += self.config.checkpoint_every
        return True

    def _save(self, steps: int) -> None:
        checkpoints = self.out / "checkpoints"
        # statistics first: a model without them is not a checkpoint (latest_checkpoint)
        self.meter.venv.save(str(checkpoints / f"vecnormalize_{steps}.pkl"))
        self.meter.model.save(str(checkpoints / f"ppo_{steps}.zip"))
        entry = self.meter.measure(steps)
        self.bar.set_postfix(success=f"{entry['succeeded']}/{entry['flights']}")
        write_history(self.out, self.meter.whole_history())

    def _on_training_end(self) -> None:
        self.bar.close()


def train(config: RlConfig, out: Path, search_path: list[Path], progress: bool = True) -> dict:
    """Train (or go on training from the latest checkpoint), export, and write rl.json; its numbers."""
    torch.set_num_threads(config.threads)
    scenario = load_scenario(config.world, config.mission, search_path)
    weights = RewardWeights(**config.reward)
    base = SwarmVecEnv(scenario, config.copies, config.n_neighbors, config.n_obstacles, config.neighbor_dist,
                       config.max_steps, weights, config.seed, config.encounters)
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    resumed = latest_checkpoint(out / "checkpoints")
    model, venv = make_model(config, base, out, resumed)
    earlier = [e for e in earlier_history(out) if resumed is not None and e["steps"] <= resumed[0]]
    meter = SuccessMeter(model, venv, scenario, config, weights.goal_radius, earlier)
    callback = CheckpointProgress(config, out, meter, progress)
    left = config.total_steps - model.num_timesteps
    if left > 0:
        model.learn(left, callback=callback, reset_num_timesteps=resumed is None, tb_log_name="ppo")
    wall = time.monotonic() - meter.started
    history = meter.history
    measured = history and history[-1]["steps"] == model.num_timesteps  # at a checkpoint that was the last step
    final = history[-1] if measured else meter.measure(int(model.num_timesteps), log=left > 0)
    write_history(out, meter.whole_history())
    draw_history(meter.whole_history(), out / "success.png", config.name)
    model.save(str(out / "policy.zip"))
    venv.save(str(out / "vecnormalize.pkl"))
    export_policy(model, out / "policy.pt", config.n_neighbors, config.n_obstacles, config.neighbor_dist,
                  normalize=venv, about={"config": config.name, "steps": int(model.num_timesteps)},
                  overwrite=True)
    returns = callback.returns
    window = max(1, min(100, len(returns) // 4)) if returns else 1
    numbers = {"config": config.as_json(), "steps": int(model.num_timesteps), "wall_seconds": wall,
               "resumed_from": resumed[0] if resumed else None, "episodes": len(returns),
               "first_mean_return": float(np.mean(returns[:window])) if returns else None,
               "last_mean_return": float(np.mean(returns[-window:])) if returns else None,
               "success_rate": final["success_rate"], "evaluation": final, "history": meter.whole_history()}
    write_text_atomically(out / "rl.json", json.dumps(numbers, indent=2) + "\n", overwrite=True)
    venv.close()
    return numbers
