"""Pickling and preprocessing run only when their inputs changed.

Each product is stored under `<data_root>/mlr/cache/` in a file named by a hash of what it
depends on:
- pickled samples: the selection, the teacher, the source, every file read (path, size and
  modification time of each simulation's CSVs or bag, result.json, mission.json), and the
  source code that turns files into vectors (pickler, bags, steps, magna_common.simulation_bag,
  magna_uav.nai.inputs);
- prepared data: the pickled samples' key, the split and its seed, and the preprocessor's code.
Files are written under a temporary name and renamed, so an interrupted run leaves no half file.
"""
from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Iterable
from dataclasses import asdict
from pathlib import Path

import numpy as np

from magna_common import simulation_bag
from magna_common.files import write_atomically
from magna_common.storage_tree import BAG_FILE, MISSION_FILE, RESULT_FILE, WORLD_FILE
from mlr import pickler, preprocess
from mlr.pickler import Samples, Selection, Simulation, Source, Teacher
from mlr.preprocess import Prepared

_MLR = Path(__file__).resolve().parent
# the source files whose code decides each product (hashed as files: no need to import rosbags)
CODE_FILES = {"pickled": ("pickler.py", "steps.py", "bags.py"), "prepared": ("preprocess.py", "features.py")}


def _code_hash(kind: str) -> str:
    from magna_uav.nai import inputs

    readers = [Path(inputs.__file__), Path(simulation_bag.__file__)] if kind == "pickled" else []
    files = [_MLR / name for name in CODE_FILES[kind]] + readers
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.read_bytes() if path.is_file() else b"")
    return digest.hexdigest()


def _files_of(sim: Simulation, source: Source) -> list[Path]:
    found = [sim.directory / n for n in (RESULT_FILE, MISSION_FILE, WORLD_FILE)]
    if source == "bag":
        found.append(sim.directory / BAG_FILE)
    else:
        found += sorted(sim.directory.glob("uav_*.csv")) + sorted(sim.directory.glob("uav_*_depth.npz"))
    return found


def fingerprint(sims: Iterable[Simulation], source: Source) -> list:
    out = []
    for sim in sims:
        for path in _files_of(sim, source):
            if path.exists():
                stat = path.stat()
                out.append([str(path), stat.st_size, stat.st_mtime_ns])
    return out


def _key(payload: dict) -> str:
    return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:20]


def pickled_key(selection: Selection, teacher: Teacher, source: Source, sims: list[Simulation]) -> str:
    return _key({"selection": asdict(selection) | {"data_root": str(selection.data_root)},
                 "teacher": asdict(teacher), "source": source, "files": fingerprint(sims, source),
                 "code": _code_hash("pickled")})


def prepared_key(pickled: str, split: tuple[float, float, float], seed: int, normalization: str = "maxabs",
                 features: str = "none") -> str:
    return _key({"pickled": pickled, "split": list(split), "seed": seed, "normalization": normalization,
                 "features": features, "code": _code_hash("prepared")})


def cache_dir(data_root: Path) -> Path:
    return Path(data_root).expanduser() / "mlr" / "cache"


def save_samples(samples: Samples, path: Path) -> None:
    arrays = {"x": samples.x, "y": samples.y, "max_speed": samples.max_speed, "origin": samples.origin,
              "step": samples.step, "sources": np.asarray(samples.sources, dtype=str)}
    if samples.images is not None:
        arrays["images"] = samples.images
    # numpy's stub: a key of `arrays` could be allow_pickle (none is)
    write_atomically(path, lambda out: np.savez(out, **arrays), overwrite=True, binary=True)  # type: ignore[arg-type]


def load_samples(path: Path) -> Samples:
    with np.load(path) as data:
        return Samples(data["x"], data["y"], data["max_speed"], data["origin"], data["step"],
                       [str(s) for s in data["sources"]], data["images"] if "images" in data else None)


def cached_samples(selection: Selection, teacher: Teacher, source: Source, sims: list[Simulation],
                   progress: Callable = lambda it: it, force: bool = False) -> tuple[Samples, str, bool]:
    """(samples, their key, whether they came from the cache)."""
    key = pickled_key(selection, teacher, source, sims)
    path = cache_dir(selection.data_root) / f"pickled_{key}.npz"
    if path.is_file() and not force:
        return load_samples(path), key, True
    samples = pickler.pickle_simulations(sims, teacher, source, progress)
    save_samples(samples, path)
    return samples, key, False


def cached_prepared(samples: Samples, key: str, data_root: Path, split, seed: int,
                    force: bool = False, normalization: str = "maxabs", run=None) -> tuple[Prepared, bool]:
    """Prepared data; with `run` (a RunConfig) its normalization and features apply."""
    features = "none" if run is None else run.features
    if run is not None:
        normalization = run.normalization
    path = cache_dir(data_root) / f"prepared_{prepared_key(key, tuple(split), seed, normalization, features)}.npz"
    if path.is_file() and not force:
        return preprocess.load_prepared(path), True
    if features != "none":
        from mlr.features import transformed

        samples = transformed(samples, run)
    prepared = preprocess.prepare(samples, tuple(split), seed, normalization)
    write_atomically(path, lambda out: preprocess.save_prepared(prepared, out), overwrite=True, binary=True)
    return prepared, False
