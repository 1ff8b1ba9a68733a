"""Preprocessor: mean removal and scaling by the largest absolute value, a seeded shuffle and a
70/20/10 split (train / validation / test).

The statistics come from the training part only (the validation and test parts must not leak
into what the network sees as "normal"), and are kept so that the exported network can undo
them: x' = (x - mean) / scale, x = x' * scale + mean, with scale = max |x - mean| per column
(1 where a column is constant, so it maps to 0 instead of NaN). `normalization="standard"`
scales the inputs by their standard deviation instead (labels keep max-abs): an input whose
extreme values are rare outliers (the padding of absent neighbours) then keeps its spread.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mlr.pickler import Samples

PARTS = ("train", "val", "test")
NORMALIZATIONS = ("maxabs", "standard")


@dataclass(frozen=True)
class Normalizer:
    mean: np.ndarray
    scale: np.ndarray

    @staticmethod
    def fit(values: np.ndarray, per_column: bool = True, kind: str = "maxabs") -> Normalizer:
        values = np.asarray(values, dtype=float)
        if len(values) == 0:
            raise ValueError("no samples to take the mean of: the training part is empty")
        if kind not in NORMALIZATIONS:
            raise ValueError(f"normalization is {kind!r}: give one of {', '.join(NORMALIZATIONS)}")
        axis = 0 if per_column else None
        mean = values.mean(axis=axis)
        scale = np.abs(values - mean).max(axis=axis) if kind == "maxabs" else values.std(axis=axis)
        scale = np.where(scale > 0, scale, 1.0)
        return Normalizer(np.asarray(mean, dtype=float), np.asarray(scale, dtype=float))

    def apply(self, values: np.ndarray) -> np.ndarray:
        return (np.asarray(values, dtype=float) - self.mean) / self.scale

    def invert(self, values: np.ndarray) -> np.ndarray:
        return np.asarray(values, dtype=float) * self.scale + self.mean


@dataclass
class Part:
    """One part of the split: raw and normalised inputs and labels."""

    x: np.ndarray  # normalised inputs, float32
    y: np.ndarray  # normalised labels, float32
    y_raw: np.ndarray  # labels in m/s (accuracy is measured on them)
    max_speed: np.ndarray  # (k,)
    images: np.ndarray | None = None  # normalised depth images, float32

    def __len__(self) -> int:
        return len(self.x)


@dataclass
class Prepared:
    train: Part
    val: Part
    test: Part
    x_norm: Normalizer
    y_norm: Normalizer
    image_norm: Normalizer | None = None

    def part(self, name: str) -> Part:
        return getattr(self, name)


def split_indices(n: int, shares: tuple[float, float, float], seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shuffled indices of the train, validation and test parts (the same for the same n, shares, seed)."""
    order = np.random.default_rng(seed).permutation(n)
    n_train = int(round(shares[0] * n))
    n_val = int(round(shares[1] * n))
    return order[:n_train], order[n_train:n_train + n_val], order[n_train + n_val:]


def prepare(samples: Samples, shares: tuple[float, float, float] = (0.7, 0.2, 0.1), seed: int = 0,
            normalization: str = "maxabs") -> Prepared:
    if len(samples) < 10:
        raise ValueError(f"only {len(samples)} samples: too few to split into train, validation and test "
                         "(record more simulations, or check role, algorithm and datasets in the config)")
    train, val, test = split_indices(len(samples), shares, seed)
    x_norm, y_norm = Normalizer.fit(samples.x[train], kind=normalization), Normalizer.fit(samples.y[train])
    images = samples.images
    image_norm = Normalizer.fit(images[train], per_column=False) if images is not None else None

    def part(idx: np.ndarray) -> Part:
        return Part(x_norm.apply(samples.x[idx]).astype(np.float32), y_norm.apply(samples.y[idx]).astype(np.float32),
                    samples.y[idx].astype(float), samples.max_speed[idx].astype(float),
                    None if images is None or image_norm is None else image_norm.apply(images[idx]).astype(np.float32))

    return Prepared(part(train), part(val), part(test), x_norm, y_norm, image_norm)


def save_prepared(prepared: Prepared, out) -> None:
    arrays = {"x_mean": prepared.x_norm.mean, "x_scale": prepared.x_norm.scale,
              "y_mean": prepared.y_norm.mean, "y_scale": prepared.y_norm.scale}
    if prepared.image_norm is not None:
        arrays |= {"image_mean": prepared.image_norm.mean, "image_scale": prepared.image_norm.scale}
    for name in PARTS:
        part = prepared.part(name)
        arrays |= {f"{name}_x": part.x, f"{name}_y": part.y, f"{name}_y_raw": part.y_raw,
                   f"{name}_max_speed": part.max_speed}
        if part.images is not None:
            arrays[f"{name}_images"] = part.images
    np.savez(out, **arrays)  # type: ignore[arg-type]  # numpy's stub: a key could be allow_pickle (none is)


def load_prepared(path) -> Prepared:
    with np.load(path) as data:
        image_norm = Normalizer(data["image_mean"], data["image_scale"]) if "image_mean" in data else None
        train, val, test = (Part(data[f"{n}_x"], data[f"{n}_y"], data[f"{n}_y_raw"], data[f"{n}_max_speed"],
                                 data[f"{n}_images"] if f"{n}_images" in data else None) for n in PARTS)
        return Prepared(train, val, test, Normalizer(data["x_mean"], data["x_scale"]),
                        Normalizer(data["y_mean"], data["y_scale"]), image_norm)
