"""The hyperparameter file (YAML or JSON) and its sweep: one `RunConfig` per combination.

Every key is optional except the dataset's world, subworld, mission and submission (the
table in mlr/README.md lists them with their defaults). Any value may be a list to sweep:
for a key whose value is a number or a word, a list is a sweep (`learning_rate: [1e-3,
1e-2]`); for a key whose value is already a list (`datasets`, `hidden_layers`,
`image_size`, `split`), a list of lists is a sweep (`hidden_layers: [[10, 10], [20, 30,
20]]`). Every combination of the swept values is trained, in the file's key order.
"""
from __future__ import annotations

import itertools
import json
import math
import re
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Literal, NoReturn, get_args

from magna_common.storage_tree import StorageError, check_component
from mlr.pickler import LABELS, SOURCES, Label, Selection, Source, Teacher

# The words a config may give for each key with a fixed set of values; the files and RunConfig hold the words.
Role = Literal["path", "agent_ad", "agent_ap"]  # the roles the NAI has inputs for (magna_uav.nai.inputs)
Algorithm = Literal["orca3d", "simple", "neural_network"]
Model = Literal["mlp", "cnn"]
Optimizer = Literal["adam", "sgd"]
Activation = Literal["relu", "tanh"]
Padding = Literal["same", "valid"]
Pooling = Literal["max", "avg", "none"]
Schedule = Literal["constant", "cosine"]
Loss = Literal["mse", "l1", "norm"]
Augmentation = Literal["none", "yaw"]
Normalization = Literal["maxabs", "standard"]  # mlr.preprocess.NORMALIZATIONS
Features = Literal["none", "geometric"]  # mlr.features

ALGORITHM_ALIASES = {"orca3": "orca3d"}
# key -> the words it takes, in the order error messages list them
CHOICES: dict[str, tuple[str, ...]] = {
    "source": SOURCES, "label": LABELS, "role": get_args(Role), "algorithm": get_args(Algorithm),
    "model": get_args(Model),
    "optimizer": get_args(Optimizer), "activation": get_args(Activation), "padding": get_args(Padding),
    "pooling": get_args(Pooling), "lr_schedule": get_args(Schedule), "loss": get_args(Loss),
    "augment": get_args(Augmentation), "normalization": get_args(Normalization),
    "features": get_args(Features)}
LIST_KEYS = frozenset({"datasets", "hidden_layers", "image_size", "split"})
REQUIRED = ("world", "subworld", "mission", "submission")


class ConfigError(ValueError):
    """A config that cannot be trained; the message names the file, the key and the fix."""


@dataclass(frozen=True)
class RunConfig:
    """One combination of hyperparameters: everything one training run depends on."""

    # which simulations
    world: str
    subworld: str
    mission: str
    submission: str
    name: str = "default"
    datasets: tuple[int, ...] = (1,)
    data_root: str = "~/magna_data"
    source: Source = "csv"  # csv: the recorder CSVs; bag: rebuilt from simulation.bag
    # the teacher and the input vector
    role: Role = "path"
    algorithm: Algorithm = "orca3d"
    n_neighbors: int = 1
    n_obstacles: int = 0
    neighbor_dist: float = 6.0
    fvi: int = 0
    label: Label = "chosen"  # teacher: ORCA-3D's answer recorded while a network flew (DAgger's relabelled steps)
    # preprocessing
    normalization: Normalization = "maxabs"  # of the inputs: max |x - mean| (the thesis's), or standard deviation
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)
    seed: int = 0
    # the network
    features: Features = "none"  # geometric: distances, closing speeds, the preferred velocity... (mlr.features)
    model: Model = "mlp"
    hidden_layers: tuple[int, ...] = (20, 30, 20)
    activation: Activation = "relu"
    image_size: tuple[int, int] = (32, 32)
    conv_depth: int = 2  # convolutional layers
    conv_channels: int = 8  # filters of the first layer; each further layer doubles them
    patch_size: int = 5
    padding: Padding = "same"
    pooling: Pooling = "max"
    # training
    optimizer: Optimizer = "adam"
    learning_rate: float = 1e-3
    lr_schedule: Schedule = "constant"  # cosine: decays to 0 over the steps (finer final fit)
    loss: Loss = "mse"  # mse; l1; norm: mean Euclidean error of the (normalised) velocity, like accuracy's test
    augment: Augmentation = "none"  # yaw: each batch turned by random yaws about the vertical (mlr.augment)
    batch_size: int = 500
    steps: int = 20000
    eval_every: int = 1000
    threads: int = 1

    @property
    def selection(self) -> Selection:
        return Selection(Path(self.data_root).expanduser(), self.world, self.subworld, self.mission,
                         self.submission, self.name, tuple(self.datasets))

    @property
    def teacher(self) -> Teacher:
        return Teacher(self.role, self.algorithm, self.n_neighbors, self.n_obstacles, self.neighbor_dist, self.fvi,
                       (self.image_size[0], self.image_size[1]) if self.model == "cnn" else None, self.label)

    def as_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> RunConfig:
        """The inverse of `as_dict` (a config saved in a checkpoint or result.json)."""
        fields_: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**fields_)


@dataclass(frozen=True)
class Sweep:
    """A config file expanded: its runs, and which keys vary between them."""

    source: Path
    name: str  # the file's stem: names the output folder and the exported network
    runs: tuple[RunConfig, ...]
    swept: tuple[str, ...]

    def run_name(self, index: int) -> str:
        """`r03_hidden_layers=20-30-20_learning_rate=0.001`: the run's number and its swept values."""
        run = self.runs[index]
        parts = [f"{key}={_short(getattr(run, key))}" for key in self.swept]
        return re.sub(r"[^\w.=+-]", "_", "_".join([f"r{index:02d}", *parts]))[:120]


def _short(value) -> str:
    if isinstance(value, tuple | list):
        return "-".join(_short(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


_FIELDS = {f.name: f for f in fields(RunConfig)}


def read_mapping(path: Path, what: str = "a mapping of hyperparameters (world: Gym, ...)") -> dict:
    """A YAML or JSON file's top-level mapping; ConfigError naming the file otherwise (`what`: what to give)."""
    try:
        text = path.read_text()
    except OSError as err:
        raise ConfigError(f"{path}: cannot read the config: {err.strerror}") from None
    try:
        if path.suffix.lower() == ".json":
            raw = json.loads(text)
        else:
            import yaml

            raw = yaml.safe_load(text)
    except Exception as err:  # yaml.YAMLError / json.JSONDecodeError: say where
        raise ConfigError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'YAML'}: {err}") \
            from None
    if not isinstance(raw, dict):
        raise ConfigError(f"{path}: the top level must be {what}")
    return raw


def _is_sweep(key: str, value) -> bool:
    if key in LIST_KEYS:
        return isinstance(value, list) and bool(value) and all(isinstance(v, list) for v in value)
    return isinstance(value, list)


def _check(path: Path, key: str, value):
    """The value as RunConfig holds it; ConfigError names the file, the key and what to give."""
    where = f"{path}: {key}"

    def fail(what: str) -> NoReturn:
        raise ConfigError(f"{where} is {value!r}: give {what}")

    def whole(v, low=0):
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            fail(f"a whole number >= {low}")
        return v

    def positive(v):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
            fail("a positive number")
        return float(v)

    def word(v, choices=None):
        if not isinstance(v, str) or not v.strip():
            fail("a name" if choices is None else f"one of {', '.join(choices)}")
        v = v.strip()
        if choices is not None and v not in choices:
            fail(f"one of {', '.join(choices)}")
        return v

    if key in ("world", "subworld", "mission", "submission", "name"):
        try:  # each names one folder of the storage tree
            return check_component(word(value), key)
        except StorageError:
            fail("a plain name without '/' (one folder of the storage tree, as given to magna run)")
    if key == "data_root":
        return word(value)
    if key == "algorithm":
        value = ALGORITHM_ALIASES.get(value, value)
    if key in CHOICES:
        return word(value, CHOICES[key])
    if key in ("n_neighbors", "n_obstacles", "fvi", "seed"):
        return whole(value)
    if key in ("batch_size", "steps", "eval_every", "threads", "conv_depth", "conv_channels", "patch_size"):
        return whole(value, 1)
    if key in ("neighbor_dist", "learning_rate"):
        return positive(value)
    if key == "datasets":
        if not isinstance(value, list) or not value:
            fail("a list of dataset numbers, e.g. [1, 2]")
        return tuple(whole(v, 1) for v in value)
    if key == "hidden_layers":
        if not isinstance(value, list) or not value:
            fail("a list of layer widths, e.g. [20, 30, 20]")
        return tuple(whole(v, 1) for v in value)
    if key == "image_size":
        if not isinstance(value, list) or len(value) != 2:
            fail("[height, width] in pixels")
        return tuple(whole(v, 4) for v in value)
    if key == "split":
        if not isinstance(value, list) or len(value) != 3 or any(
                isinstance(v, bool) or not isinstance(v, int | float) or v < 0 for v in value) \
                or not math.isclose(sum(value), 1.0, abs_tol=1e-6) or value[0] <= 0 or value[2] <= 0:
            fail("[train, validation, test] shares that add up to 1, e.g. [0.7, 0.2, 0.1]")
        return tuple(float(v) for v in value)
    raise AssertionError(key)


def load_sweep(path: str | Path, overrides: dict | None = None) -> Sweep:
    """Read a config file (plus `overrides`, e.g. from the command line) into its runs."""
    path = Path(path)
    raw = read_mapping(path)
    raw.update(overrides or {})
    unknown = [key for key in raw if key not in _FIELDS]
    if unknown:
        raise ConfigError(f"{path}: unknown key {unknown[0]!r}: known keys are {', '.join(_FIELDS)} "
                          "(mlr/README.md, 'The config file')")
    missing = [key for key in REQUIRED if key not in raw]
    if missing:
        raise ConfigError(f"{path}: {missing[0]} is missing: say which simulations to learn from "
                          f"({', '.join(REQUIRED)}, as given to magna run)")
    choices: dict[str, list] = {}
    for key, value in raw.items():
        values = value if _is_sweep(key, value) else [value]
        if not values:
            raise ConfigError(f"{path}: {key} is an empty list: give a value, or a list of values to sweep")
        choices[key] = [_check(path, key, v) for v in values]
    swept = tuple(key for key, values in choices.items() if len(values) > 1)
    runs = []
    for combination in itertools.product(*choices.values()):
        values = dict(zip(choices, combination, strict=True))
        run = RunConfig(**values)
        try:
            run.teacher  # noqa: B018 - checks the teacher's counts and role
        except ValueError as err:
            raise ConfigError(f"{path}: {err}") from None
        if run.features != "none" and (run.model != "mlp" or run.augment != "none"):
            raise ConfigError(f"{path}: features {run.features} is for an mlp without augmentation (the features are "
                              "computed from the vector as recorded): use model mlp and augment none with it")
        if run.model == "cnn" and run.augment != "none":
            raise ConfigError(f"{path}: augment {run.augment} turns the vectors but not the depth image a cnn also "
                              "sees: use augment none with model cnn")
        if run.model == "cnn" and run.padding == "valid":
            side = min(run.image_size)
            for _ in range(run.conv_depth):
                side = side - run.patch_size + 1
                side = side // 2 if run.pooling != "none" else side
            if side < 1:
                raise ConfigError(f"{path}: image_size {list(run.image_size)} is too small for {run.conv_depth} "
                                  f"valid convolutions of patch {run.patch_size}: use padding same or a larger image")
        runs.append(run)
    return Sweep(path, path.stem, tuple(runs), swept)
