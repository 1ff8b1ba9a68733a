"""Trainer: one run = one RunConfig on prepared data, with TensorBoard logs and checkpoints.

Loss, on the normalised labels: mean squared error (`mse`), mean absolute error (`l1`), or the
mean Euclidean norm of the error (`norm`, closest to accuracy's within-a-radius test). Every
`eval_every` steps the validation part is measured (loss and accuracy, mlr.metrics) and weight
and bias histograms are logged; the best validation accuracy (ties: lower validation loss) is
kept in `checkpoint.pt`. At the end the best weights are restored and measured on the test part.

A run directory holds:
    tb/               TensorBoard: loss/train, loss/val, accuracy/val, accuracy/test, histograms,
                      the graph, and the hyperparameters with the final metrics (HPARAMS tab)
    checkpoint.pt     {"model": state_dict, "step", "val_accuracy", "val_loss", "config"}
    result.json       the run's metrics and its config
"""
from __future__ import annotations

import functools
import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TypedDict

import numpy as np
import torch
from torch import nn

from magna_common.files import write_atomically, write_text_atomically
from mlr.config import RunConfig
from mlr.metrics import accuracy
from mlr.models import build_model, parameter_count
from mlr.preprocess import Part, Prepared

EVAL_BATCH = 8192
LOG_EVERY = 100  # steps between training-loss points in TensorBoard


@dataclass
class RunResult:
    name: str
    directory: str
    steps: int
    best_step: int
    train_loss: float  # mean of the last logged training losses
    val_loss: float
    val_accuracy: float
    test_loss: float
    test_accuracy: float
    parameters: int
    wall_seconds: float
    steps_per_second: float

    def metrics(self) -> dict[str, float]:
        return {"loss/val": self.val_loss, "accuracy/val": self.val_accuracy, "loss/test": self.test_loss,
                "accuracy/test": self.test_accuracy}


def _norm_loss(out: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    return torch.linalg.vector_norm(out - target, dim=1).mean()


LOSSES: dict[str, Callable[[torch.Tensor, torch.Tensor], torch.Tensor]] = {
    "mse": nn.functional.mse_loss, "l1": nn.functional.l1_loss, "norm": _norm_loss}


class _Best(TypedDict):
    """The best validation so far (also saved into checkpoint.pt)."""

    val_accuracy: float
    val_loss: float
    step: int


def _tensors(part: Part) -> tuple[torch.Tensor, ...]:
    x = torch.from_numpy(np.ascontiguousarray(part.x, dtype=np.float32))
    y = torch.from_numpy(np.ascontiguousarray(part.y, dtype=np.float32))
    if part.images is None:
        return x, y
    images = torch.from_numpy(np.ascontiguousarray(part.images, dtype=np.float32)).unsqueeze(1)
    return x, y, images


def _forward(model: nn.Module, x: torch.Tensor, images: torch.Tensor | None) -> torch.Tensor:
    return model(x) if images is None else model(images, x)


def evaluate(model: nn.Module, part: Part, prepared: Prepared) -> tuple[float, float, np.ndarray]:
    """(loss on normalised labels, accuracy in m/s, predictions in m/s) of `model` on `part`."""
    if len(part) == 0:
        return math.nan, math.nan, np.zeros((0, 3))
    tensors = _tensors(part)
    model.eval()
    outputs = []
    with torch.no_grad():
        for start in range(0, len(part), EVAL_BATCH):
            images = tensors[2][start:start + EVAL_BATCH] if len(tensors) == 3 else None
            outputs.append(_forward(model, tensors[0][start:start + EVAL_BATCH], images))
    model.train()
    out = torch.cat(outputs)
    loss = float(nn.functional.mse_loss(out, tensors[1]))
    predicted = prepared.y_norm.invert(out.numpy())
    return loss, accuracy(predicted, part.y_raw, part.max_speed), predicted


def _optimizer(run: RunConfig, model: nn.Module) -> torch.optim.Optimizer:
    if run.optimizer == "adam":
        return torch.optim.Adam(model.parameters(), lr=run.learning_rate)
    return torch.optim.SGD(model.parameters(), lr=run.learning_rate)


def _hparams(run: RunConfig) -> dict:
    """TensorBoard takes numbers, strings and bools: lists become strings."""
    return {k: ("-".join(map(str, v)) if isinstance(v, list) else v) for k, v in run.as_dict().items()}


def train_run(run: RunConfig, prepared: Prepared, run_dir: Path, name: str, progress: bool = True) -> RunResult:
    """Train one network (module docstring); returns its metrics, also written to run_dir/result.json."""
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(run.threads)
    torch.manual_seed(run.seed)
    train = _tensors(prepared.train)
    n = len(prepared.train)
    if n == 0:
        raise ValueError(f"run {name}: the training part is empty")
    batch = min(run.batch_size, n)
    model = build_model(run, prepared.train.x.shape[1])
    optimizer = _optimizer(run, model)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, run.steps) if run.lr_schedule == "cosine" \
        else None
    loss_fn = LOSSES[run.loss]
    writer = SummaryWriter(log_dir=str(run_dir / "tb"))
    example = (train[2][:1], train[0][:1]) if len(train) == 3 else train[0][:1]
    try:
        writer.add_graph(model, example)
    except Exception as err:  # the graph is a nicety; never lose a run over it
        writer.add_text("graph", f"not drawn: {err}")
    augmenter = None
    if run.augment == "yaw":
        from mlr.augment import YawAugmenter

        augmenter = YawAugmenter(run.role, run.n_neighbors, run.n_obstacles, run.neighbor_dist)
        norms = [torch.as_tensor(np.asarray(v, dtype=np.float32)) for v in
                 (prepared.x_norm.mean, prepared.x_norm.scale, prepared.y_norm.mean, prepared.y_norm.scale)]
    best: _Best = {"val_accuracy": -1.0, "val_loss": math.inf, "step": 0}
    recent: list[float] = []
    generator = torch.Generator().manual_seed(run.seed)
    order, position = None, n
    started = time.monotonic()
    bar = tqdm(total=run.steps, desc=name, unit="step", disable=not progress, leave=False, mininterval=0.5,
               smoothing=0.05)
    shuffled: tuple[torch.Tensor, ...] = ()
    for step in range(1, run.steps + 1):
        if position + batch > n:  # a new epoch: one shuffle, then contiguous slices (cheaper than gathers)
            order = torch.randperm(n, generator=generator)
            shuffled = tuple(t[order] for t in train)
            position = 0
        xb, yb = shuffled[0][position:position + batch], shuffled[1][position:position + batch]
        images = shuffled[2][position:position + batch] if len(shuffled) == 3 else None
        position += batch
        if augmenter is not None:  # turn the raw scene, then normalise again
            x_raw, y_raw = augmenter(xb * norms[1] + norms[0], yb * norms[3] + norms[2], generator)
            xb, yb = (x_raw - norms[0]) / norms[1], (y_raw - norms[2]) / norms[3]
        loss = loss_fn(_forward(model, xb, images), yb)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        if schedule is not None:
            schedule.step()
        if step % LOG_EVERY == 0 or step == run.steps:
            value = loss.item()
            if not math.isfinite(value):
                bar.close()
                writer.close()
                raise FloatingPointError(f"run {name}: the training loss became {value} at step {step}: lower "
                                         f"learning_rate ({run.learning_rate:g})")
            writer.add_scalar("loss/train", value, step)
            recent = (recent + [value])[-10:]
            bar.update(step - bar.n)
            bar.set_postfix(loss=f"{value:.4g}", val_acc=f"{best['val_accuracy']:.3f}", refresh=False)
        if step % run.eval_every == 0 or step == run.steps:
            val_loss, val_acc, _ = evaluate(model, prepared.val, prepared)
            writer.add_scalar("loss/val", val_loss, step)
            writer.add_scalar("accuracy/val", val_acc, step)
            for param_name, param in model.named_parameters():
                writer.add_histogram(param_name.replace(".", "/"), param.detach(), step)
            if (val_acc, -val_loss) > (best["val_accuracy"], -best["val_loss"]):
                best = {"val_accuracy": val_acc, "val_loss": val_loss, "step": step}
                checkpoint = {"model": model.state_dict(), "config": run.as_dict(), **best}
                write_atomically(run_dir / "checkpoint.pt", functools.partial(torch.save, checkpoint), overwrite=True,
                                 binary=True)
    bar.close()
    wall = time.monotonic() - started
    model.load_state_dict(torch.load(run_dir / "checkpoint.pt", weights_only=True)["model"])
    test_loss, test_acc, _ = evaluate(model, prepared.test, prepared)
    writer.add_scalar("accuracy/test", test_acc, best["step"])
    writer.add_scalar("loss/test", test_loss, best["step"])
    result = RunResult(name, str(run_dir), run.steps, best["step"], float(np.mean(recent)) if recent else math.nan,
                       best["val_loss"], best["val_accuracy"], test_loss, test_acc, parameter_count(model), wall,
                       run.steps / wall if wall > 0 else math.inf)
    writer.add_hparams(_hparams(run), result.metrics(), run_name=".")
    writer.close()
    sizes = {name: len(prepared.part(name)) for name in ("train", "val", "test")}
    write_text_atomically(run_dir / "result.json", json.dumps({"result": asdict(result), "config": run.as_dict(),
                                                              "samples": sizes}, indent=2) + "\n", overwrite=True)
    return result


def trained_config(run_dir: Path) -> RunConfig:
    """The config a run was trained with, from its checkpoint."""
    return RunConfig.from_dict(torch.load(Path(run_dir) / "checkpoint.pt", weights_only=True)["config"])


def load_trained(run_dir: Path, size_in: int) -> tuple[nn.Module, RunConfig]:
    """The best weights of a finished run, in its network."""
    checkpoint = torch.load(Path(run_dir) / "checkpoint.pt", weights_only=True)
    run = RunConfig.from_dict(checkpoint["config"])
    model = build_model(run, size_in)
    model.load_state_dict(checkpoint["model"])
    model.eval()
    return model, run
