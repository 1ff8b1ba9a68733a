"""Neural-network navigation: a TorchScript model and the JSON input spec beside it.

Files (mlr's export writes both):

    <dir>/<stem>.pt    TorchScript (torch.jit.save of a scripted or traced module)
    <dir>/<stem>.json  {"role": "path" | "agent_ad" | "agent_ap",
                        "n_neighbors": N, "n_obstacles": M,
                        "inputs": [input_names(role, N, M)...],      # exactly, in order
                        "outputs": ["sel_vel.x", "sel_vel.y", "sel_vel.z"],
                        "image": null | {"height": H, "width": W},
                        "neighbor_dist": D,                          # optional, m
                        "about": {...}}                              # optional, free

The spec's `inputs` must equal `magna_uav.nai.inputs.input_names(role, N, M)`: a model
trained on another order is refused, naming the file and the first differing input.
Other keys are refused too, so a typo cannot pass silently. `neighbor_dist` is the
neighbour distance the network was trained with (it decides which neighbours count and where
the padding sits): when present the NAI selects and pads with it and ignores its own
`neighborDist` parameter, so a network always sees inputs shaped like its training data.
`about` is for people (what it was trained on, its metrics); the NAI does not read it.

Call signature (CPU, inside torch.no_grad, float32 tensors):

    vector model:  out = model(vector)              vector: [1, input_size]
    image model:   out = model(image, vector)       image:  [1, 1, H, W] depth in metres

`out` must hold 3 numbers (any shape, e.g. [1, 3]): sel_vel, the velocity in m/s in the
map frame (the NAI then saturates it to the UAV's max speed). Any normalisation belongs
inside the module. The depth image (`AgentState.depth`) is prepared by `prepare_depth`:
+inf (nothing seen) and NaN become `DEPTH_FAR` (20 m, the simulated camera's far
plane), values are clipped to [0, DEPTH_FAR], and the image is resized to H x W by
nearest neighbour exactly as torch.nn.functional.interpolate(mode="nearest") does
(source index = floor(destination index * in / out)).

Loading runs the model once on zeros, so a model that fails or answers the wrong number
of values is refused at load time, not in flight. torch is imported on first use.
"""
from __future__ import annotations

import json
import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import (
    DEFAULT_NEIGHBOR_DIST,
    INPUT_ROLES,
    OUTPUT_SIZE,
    Neighbors,
    build_inputs,
    input_names,
    output_names,
    select_neighbors,
)
from magna_uav.world_view import WorldView

SPEC_KEYS = ("role", "n_neighbors", "n_obstacles", "inputs", "outputs", "image")
OPTIONAL_SPEC_KEYS = ("neighbor_dist", "about")
DEPTH_FAR = 20.0  # m: what +inf / NaN depth pixels read as, and the clip


class NeuralModelError(ValueError):
    """A model or spec file that cannot be flown; the message names the file and the fix."""


@dataclass(frozen=True)
class ImageSpec:
    height: int
    width: int


@dataclass(frozen=True)
class ModelSpec:
    source: Path
    role: str
    n_neighbors: int
    n_obstacles: int
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    image: ImageSpec | None
    neighbor_dist: float | None = None  # m: the distance it was trained with, when the spec says


def spec_path(model_path: str | Path) -> Path:
    """The JSON spec beside a model: same directory and stem, suffix .json."""
    return Path(model_path).with_suffix(".json")


def _count(raw: dict, key: str, source: Path) -> int:
    value = raw[key]
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise NeuralModelError(f"{source}: {key} is {value!r}: give a whole number >= 0")
    return value


def _first_difference(got: list, want: list, role: str, n: int, m: int, source: Path) -> str:
    what = f"role {role!r} with {n} neighbours and {m} obstacles"
    for i, (g, w) in enumerate(zip(got, want, strict=False)):
        if g != w:
            return f"{source}: inputs[{i}] is {g!r} but {what} expects {w!r}"
    if len(got) < len(want):
        return f"{source}: inputs ends after {len(got)} names but {what} expects {len(want)}; the first missing " \
               f"is {want[len(got)]!r}"
    return f"{source}: inputs[{len(want)}] is {got[len(want)]!r} but {what} expects only {len(want)} inputs"


def parse_spec(raw, source: Path) -> ModelSpec:
    """Validate a spec's JSON value against the input definition (magna_uav.nai.inputs)."""
    if not isinstance(raw, dict):
        raise NeuralModelError(f"{source}: the top level must be a JSON object with {', '.join(SPEC_KEYS)}")
    for key in SPEC_KEYS:
        if key not in raw:
            raise NeuralModelError(f"{source}: {key} is missing (a spec has {', '.join(SPEC_KEYS)})")
    unknown = sorted(set(raw) - set(SPEC_KEYS) - set(OPTIONAL_SPEC_KEYS))
    if unknown:
        raise NeuralModelError(f"{source}: unknown key {unknown[0]!r}: a spec has only "
                               f"{', '.join(SPEC_KEYS + OPTIONAL_SPEC_KEYS)}")
    role = raw["role"]
    if role not in INPUT_ROLES:
        raise NeuralModelError(f"{source}: role is {role!r}: give one of {', '.join(INPUT_ROLES)}")
    n, m = _count(raw, "n_neighbors", source), _count(raw, "n_obstacles", source)
    for key in ("inputs", "outputs"):
        if not isinstance(raw[key], list) or not all(isinstance(name, str) for name in raw[key]):
            raise NeuralModelError(f"{source}: {key} must be a list of names such as 'own_vel.x'")
    want = input_names(role, n, m)
    if raw["inputs"] != want:
        raise NeuralModelError(_first_difference(raw["inputs"], want, role, n, m, source)
                               + " (the order is defined in magna_uav.nai.inputs; export the model again)")
    if raw["outputs"] != output_names():
        raise NeuralModelError(f"{source}: outputs is {raw['outputs']}: give {output_names()}")
    image = raw["image"]
    if image is not None:
        if not isinstance(image, dict) or set(image) != {"height", "width"}:
            raise NeuralModelError(f"{source}: image is {image!r}: give null or {{\"height\": H, \"width\": W}}")
        for key in ("height", "width"):
            if isinstance(image[key], bool) or not isinstance(image[key], int) or image[key] < 1:
                raise NeuralModelError(f"{source}: image.{key} is {image[key]!r}: give a whole number of pixels >= 1")
        image = ImageSpec(image["height"], image["width"])
    neighbor_dist = raw.get("neighbor_dist")
    if neighbor_dist is not None:
        if isinstance(neighbor_dist, bool) or not isinstance(neighbor_dist, int | float) \
                or not math.isfinite(neighbor_dist) or neighbor_dist <= 0:
            raise NeuralModelError(f"{source}: neighbor_dist is {neighbor_dist!r}: give the positive distance in "
                                   "metres the network was trained with, or leave the key out")
        neighbor_dist = float(neighbor_dist)
    return ModelSpec(source, role, n, m, tuple(raw["inputs"]), tuple(raw["outputs"]), image, neighbor_dist)


def load_spec(path: str | Path) -> ModelSpec:
    path = Path(path)
    if not path.is_file():
        raise NeuralModelError(f"{path}: no such input spec; a model needs the JSON written beside it "
                               "(same name, .json) by mlr's export")
    try:
        raw = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise NeuralModelError(f"{path}: not a readable JSON file: {err}") from None
    return parse_spec(raw, path)


def _nearest_indices(size_in: int, size_out: int) -> np.ndarray:
    return np.minimum(np.floor(np.arange(size_out) * (size_in / size_out)).astype(int), size_in - 1)


def prepare_depth(depth: np.ndarray, height: int, width: int) -> np.ndarray:
    """A depth image (metres) as the models see it: (height, width) float32 (module docstring)."""
    depth = np.asarray(depth, dtype=float)
    if depth.ndim == 3 and depth.shape[-1] == 1:
        depth = depth[..., 0]
    if depth.ndim != 2 or depth.size == 0:
        raise ValueError(f"depth image has shape {depth.shape}: give a (height, width) image in metres")
    depth = np.clip(np.nan_to_num(depth, nan=DEPTH_FAR, posinf=DEPTH_FAR, neginf=0.0), 0.0, DEPTH_FAR)
    rows = _nearest_indices(depth.shape[0], height)
    cols = _nearest_indices(depth.shape[1], width)
    return depth[np.ix_(rows, cols)].astype(np.float32)


def _last_line(err: Exception) -> str:
    """TorchScript errors carry a traceback; its last line says what went wrong."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    text = lines[-1] if lines else ""
    return text if re.match(r"[\w.]*(Error|Exception)\b", text) else f"{type(err).__name__}: {text}"


class NeuralModel:
    """A loaded, checked model; `predict` maps an input vector (and depth image) to sel_vel."""

    def __init__(self, path: str | Path):
        import torch  # lazily: a second or so to import, only models need it

        self._torch = torch
        self.path = Path(path)
        if not self.path.is_file():
            raise NeuralModelError(f"{self.path}: no such TorchScript model file")
        self.spec = load_spec(spec_path(self.path))
        try:
            with warnings.catch_warnings():  # torch 2.13 calls TorchScript deprecated; it is the format we fly
                warnings.filterwarnings("ignore", r"`torch\.jit\.load` is deprecated", DeprecationWarning)
                self.module = torch.jit.load(str(self.path), map_location="cpu")
        except Exception as err:  # torch raises RuntimeError, ValueError, zipfile errors...
            raise NeuralModelError(f"{self.path}: not a TorchScript model (torch.jit.load: {_last_line(err)})") \
                from None
        self.module.eval()
        self.input_size = len(self.spec.inputs)
        zeros_image = None if self.spec.image is None else np.zeros((self.spec.image.height, self.spec.image.width))
        try:
            self.predict(np.zeros(self.input_size), zeros_image)
        except NeuralModelError:
            raise
        except Exception as err:
            shape = "" if self.spec.image is None else f" and image [1, 1, {self.spec.image.height}, " \
                                                       f"{self.spec.image.width}]"
            raise NeuralModelError(f"{self.path}: the model fails on a zero vector [1, {self.input_size}]{shape} "
                                   f"as its spec {self.spec.source.name} describes: {_last_line(err)}") from None

    @property
    def role(self) -> str:
        return self.spec.role

    def predict(self, vector: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray:
        """sel_vel (3,) float64 for one input vector; `depth` is required by image models."""
        torch = self._torch
        vector = np.asarray(vector, dtype=np.float32).reshape(-1)
        if vector.size != self.input_size:
            raise ValueError(f"input vector has {vector.size} values: {self.path.name} takes {self.input_size}")
        with torch.no_grad():
            x = torch.from_numpy(vector).reshape(1, -1)
            if self.spec.image is None:
                out = self.module(x)
            else:
                if depth is None:
                    raise ValueError(f"{self.path.name} needs a depth image and none was received "
                                     "(is the UAV's depth camera on?)")
                image = prepare_depth(depth, self.spec.image.height, self.spec.image.width)
                out = self.module(torch.from_numpy(image).reshape(1, 1, *image.shape), x)
        if not isinstance(out, torch.Tensor) or out.numel() != OUTPUT_SIZE:
            got = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
            raise NeuralModelError(f"{self.path}: the model answered {got}: it must give {OUTPUT_SIZE} values "
                                   f"({', '.join(output_names())})")
        return out.detach().to(torch.float64).reshape(OUTPUT_SIZE).numpy().copy()

    def velocity(self, view: WorldView, goal: Goal, neighbor_dist: float = DEFAULT_NEIGHBOR_DIST,
                 neighbors: Neighbors | None = None) -> tuple[np.ndarray, Neighbors]:
        """(sel_vel, the neighbours fed in) for the UAV `view.own` and `goal`.

        `neighbor_dist` is used only when the spec does not carry the trained one."""
        spec = self.spec
        if spec.neighbor_dist is not None:
            neighbor_dist = spec.neighbor_dist
        if neighbors is None:
            neighbors = select_neighbors(view, spec.n_neighbors, spec.n_obstacles, neighbor_dist)
        vector = build_inputs(view, goal, spec.role, spec.n_neighbors, spec.n_obstacles, neighbor_dist, neighbors)
        return self.predict(vector, view.own.depth), neighbors


def load_model(path: str | Path) -> NeuralModel:
    """Load `path` and its spec (`spec_path(path)`); NeuralModelError names the file and what is wrong."""
    return NeuralModel(path)

