"""Export: a trained run as the TorchScript file and JSON spec the NAI flies
(format: magna_uav.nai.neural).

The exported module takes raw inputs (m, m/s; depth in metres) and answers sel_vel in m/s:
the normalisation and its inverse are inside it, as buffers. After writing, the export is
checked: the file is loaded back with torch.jit.load and through the NAI's own loader, and
both must give the trained network's outputs on the test samples (within 1e-5 m/s); a
mismatch removes the files and raises.
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
from magna_uav.nai.inputs import input_names, input_size, output_names
from magna_uav.nai.neural import load_model, spec_path
from mlr.config import RunConfig
from mlr.preprocess import Normalizer, Prepared

TOLERANCE = 1e-5  # m/s: float32 round-off between the eager network and its TorchScript copy
CHECK_SAMPLES = 2000


def _buffer(values) -> torch.Tensor:
    return torch.as_tensor(np.asarray(values, dtype=np.float32))


def _register_norms(module: nn.Module, **norms: Normalizer) -> None:
    """Buffers `<name>_mean` and `<name>_scale` (float32) for each normaliser, e.g. x_norm -> x_mean, x_scale."""
    for name, norm in norms.items():
        prefix = name.removesuffix("_norm")
        module.register_buffer(f"{prefix}_mean", _buffer(norm.mean))
        module.register_buffer(f"{prefix}_scale", _buffer(norm.scale))


class VectorNetwork(nn.Module):
    """sel_vel = net((x - x_mean) / x_scale) * y_scale + y_mean."""

    if TYPE_CHECKING:  # the buffers _register_norms adds, declared for mypy only: TorchScript reads class
        # annotations, and cannot resolve postponed ones
        x_mean: torch.Tensor
        x_scale: torch.Tensor
        y_mean: torch.Tensor
        y_scale: torch.Tensor

    def __init__(self, net: nn.Module, x_norm: Normalizer, y_norm: Normalizer):
        super().__init__()
        self.net = net
        _register_norms(self, x_norm=x_norm, y_norm=y_norm)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net((x - self.x_mean) / self.x_scale) * self.y_scale + self.y_mean


class ImageNetwork(nn.Module):
    """The same for CNN+MLP networks: the depth image is normalised too (one mean and scale)."""

    if TYPE_CHECKING:  # the buffers _register_norms adds, declared for mypy only: TorchScript reads class
        # annotations, and cannot resolve postponed ones
        x_mean: torch.Tensor
        x_scale: torch.Tensor
        y_mean: torch.Tensor
        y_scale: torch.Tensor
        image_mean: torch.Tensor
        image_scale: torch.Tensor

    def __init__(self, net: nn.Module, x_norm: Normalizer, y_norm: Normalizer, image_norm: Normalizer):
        super().__init__()
        self.net = net
        _register_norms(self, x_norm=x_norm, y_norm=y_norm, image_norm=image_norm)

    def forward(self, image: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        image = (image - self.image_mean) / self.image_scale
        return self.net(image, (x - self.x_mean) / self.x_scale) * self.y_scale + self.y_mean


class FeatureNetwork(nn.Module):
    """`features: geometric` networks (mlr.features): sel_vel = preferred velocity + the change the network
    answers from the raw vector and its features, normalised together."""

    if TYPE_CHECKING:  # the buffers _register_norms adds, declared for mypy only (see VectorNetwork)
        x_mean: torch.Tensor
        x_scale: torch.Tensor
        y_mean: torch.Tensor
        y_scale: torch.Tensor

    def __init__(self, net: nn.Module, features: nn.Module, x_norm: Normalizer, y_norm: Normalizer):
        super().__init__()
        self.net = net
        self.features = features
        _register_norms(self, x_norm=x_norm, y_norm=y_norm)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        extra, preferred = self.features(x)
        z = torch.cat([x, extra], dim=1)
        return self.net((z - self.x_mean) / self.x_scale) * self.y_scale + self.y_mean + preferred


def wrap(net: nn.Module, prepared: Prepared, run: RunConfig | None = None) -> nn.Module:
    net.eval()
    if run is not None and run.features != "none":
        from mlr.features import build, one_max_speed

        features = build(run, one_max_speed(prepared.train.max_speed, "the training part")).float()
        return FeatureNetwork(net, features, prepared.x_norm, prepared.y_norm).eval()
    if prepared.image_norm is None:
        return VectorNetwork(net, prepared.x_norm, prepared.y_norm).eval()
    return ImageNetwork(net, prepared.x_norm, prepared.y_norm, prepared.image_norm).eval()


def spec_for(run: RunConfig, about: dict | None = None) -> dict:
    if run.features != "none":  # for people: the NAI gives the same vector either way
        about = {"features": run.features, **(about or {})}
    return {"role": run.role, "n_neighbors": run.n_neighbors, "n_obstacles": run.n_obstacles,
            "inputs": input_names(run.role, run.n_neighbors, run.n_obstacles), "outputs": output_names(),
            "image": {"height": run.image_size[0], "width": run.image_size[1]} if run.model == "cnn" else None,
            "neighbor_dist": run.neighbor_dist, "about": about or {}}


def _raw_test_inputs(prepared: Prepared, size: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The raw input vectors (their first `size` columns: features come after) and images of test samples."""
    part = prepared.test if len(prepared.test) else prepared.val
    x = prepared.x_norm.invert(part.x[:CHECK_SAMPLES])[:, :size].astype(np.float32)
    if part.images is None:
        return x, None
    assert prepared.image_norm is not None  # fitted whenever the samples have images (mlr.preprocess)
    return x, prepared.image_norm.invert(part.images[:CHECK_SAMPLES]).astype(np.float32)


def export(net: nn.Module, run: RunConfig, prepared: Prepared, path: str | Path, about: dict | None = None,
           overwrite: bool = False) -> Path:
    """Write `path` (.pt) and its spec (.json); check them (module docstring). Returns the .pt path."""
    path = Path(path)
    if path.suffix != ".pt":
        raise ValueError(f"{path}: an exported network is a .pt file (its spec goes beside it as .json)")
    spec_file = spec_path(path)
    if not overwrite:
        for target in (path, spec_file):
            if target.exists():
                raise FileExistsError(f"{target}: already exists; pass --force to replace it, or choose "
                                      "another path")
    module = wrap(net, prepared, run)
    try:
        with warnings.catch_warnings():  # torch 2.13 calls TorchScript deprecated; it is the format the NAI flies
            warnings.filterwarnings("ignore", category=DeprecationWarning)
            scripted = torch.jit.script(module)
            write_atomically(path, lambda out: torch.jit.save(scripted, out), overwrite=True, binary=True)
        write_text_atomically(spec_file, json.dumps(spec_for(run, about), indent=2) + "\n", overwrite=True)
        check_export(module, path, prepared, input_size(run.role, run.n_neighbors, run.n_obstacles))
    except BaseException:
        for leftover in (path, spec_file):  # a network without its spec, or one that failed its check
            leftover.unlink(missing_ok=True)
        raise
    return path


def check_export(module: nn.Module, path: Path, prepared: Prepared, size: int) -> float:
    """The largest difference (m/s) between the trained module and the exported file on raw input vectors of
    `size` values; raises above TOLERANCE."""
    x, images = _raw_test_inputs(prepared, size)
    with torch.no_grad():
        xt = torch.from_numpy(x)
        it = None if images is None else torch.from_numpy(images).unsqueeze(1)
        expected = (module(xt) if it is None else module(it, xt)).numpy()
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", category=DeprecationWarning)
            loaded = torch.jit.load(str(path))
        got = (loaded(xt) if it is None else loaded(it, xt)).numpy()
    worst = float(np.max(np.abs(got - expected))) if len(x) else 0.0
    nai = load_model(path)  # the loader the UAV managers use: spec checks and one zero run
    for k in range(min(len(x), 20)):
        one = nai.predict(x[k], None if images is None else images[k])
        worst = max(worst, float(np.max(np.abs(one - expected[k]))))
    if not worst <= TOLERANCE:
        raise RuntimeError(f"{path}: the exported network differs from the trained one by {worst:.3g} m/s "
                           f"(allowed {TOLERANCE:g}); not exported")
    return worst
