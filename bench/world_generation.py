"""How fast magna_worlds lays out worlds: pose sets per shape, inside tests, and whole world files.

1. Layout: `resolve_world` on a tiny in-memory world holding one geometry with one
   set of about 10,000 poses: a matrix by dimension (100 x 100 x 1 cells) and 10,000
   random poses in a cube, sphere, cylinder, torus and a rotated non-convex prism,
   a zigzag sweep over that prism, and 10,000 random obstacles with drawn sizes and yaw.
2. `shapes.contains` on 10,000 points of each shape's bounding box.
3. Load + resolve (seed 0) of every world file of the ROS-MAGNA corpus and of worlds/,
   in ms per file ("poses" counts its poses and obstacles).
Each figure is the best of --repeats runs (time.perf_counter). Prints one table
with, for 1 and 2, the time per 10,000 poses (points) and its share of the 1 s
budget ("well under a second"); never fails on a time.

    python bench/world_generation.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/world_generation.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "magna_worlds"))

ROOT = Path(__file__).resolve().parent.parent
_DEVEL = ROOT / "devel" / "lib" / "python3" / "dist-packages"
if _DEVEL.is_dir() and str(_DEVEL) not in sys.path:
    sys.path.insert(0, str(_DEVEL))

BUDGET_S = 1.0  # seconds for 10,000 poses
PER = 10_000
CORPUS = ROOT.parent / "shared" / "ros_magna_corpus" / "Worlds"

# An arrow-shaped (non-convex) base polygon, 100 m across, for the prism cases.
ARROW = [[0, 0, 0], [100, 0, 0], [100, 60, 0], [50, 30, 0], [0, 60, 0]]

SOLIDS = {  # name -> (shape, dimensions, origin rpy)
    "cube": ("cube", [20.0, 10.0, 5.0], [0, 0, 0]),
    "sphere": ("sphere", [10.0, 10.0, 10.0], [0, 0, 0]),
    "cylinder": ("cylinder", [10.0, 10.0, 4.0], [0, 0, 0]),
    "torus": ("torus", [12.0, 16.0, 4.0], [0, 0, 0]),
    "prism (rotated, non-convex)": ("prism", [10.0, ARROW], [0, 0, 0.6]),
}


def one_set_world(shape: str, dimensions, rpy, pose_set: dict):
    from magna_worlds.loader import world_from_data

    geometry = {"name": "G", "prefix": "g", "shape": shape, "id": 0, "origin": [[0, 0, 0], rpy],
                "dimensions": dimensions, "color": [0, 0, 0], "alpha": 1.0, "poses_sets": [pose_set]}
    return world_from_data({"scenario": {"world_boundaries": [[-1e4, 1e4]] * 3, "volumes": [
        {"name": "V", "prefix": "v", "origin": [[0, 0, 0], [0, 0, 0]], "permits": "", "geometries": [geometry]}]}},
        "bench")


def best_of(repeats: int, fn) -> float:
    """Seconds of the fastest of `repeats` calls (after one warm-up call)."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def layout_cases():
    """(label, world) pairs, each world with one set of about 10,000 poses or obstacles."""
    cases = []
    for name, (shape, dims, rpy) in SOLIDS.items():
        grid = [100, 100, 1]
        if shape == "prism":  # the matrix keeps the cells over the polygon: size the box so ~10,000 remain
            grid = [180, 120, 1]
        matrix = {"type": "matrix", "matrix_type": "dimension", "use": "poses", "dimensions": grid, "density": 1,
                  "poses_orientation": [0, 0, 0], "set_orientation": [0, 0, 0.3 if shape == "prism" else 0]}
        random = {"type": "random", "use": "poses", "quantity": PER, "poses_orientation": "random_yaw"}
        cases.append((f"{name}, matrix by dimension", one_set_world(shape, dims, rpy, matrix)))
        cases.append((f"{name}, random", one_set_world(shape, dims, rpy, random)))
    shape, dims, rpy = SOLIDS["prism (rotated, non-convex)"]
    zigzag = {"type": "zigzag", "use": "poses", "height": 5.0, "spacing": [2.0, 2.0], "sweep_angle": 0.4,
              "margins": [0.5, 0.5], "initial_sense": "left", "orientation": [0, 0, 0]}
    big = [dims[0], [[3 * x, 3 * y, z] for x, y, z in dims[1]]]  # 300 m across: ~10,000 waypoints 2 m apart
    cases.append(("prism (rotated, non-convex), zigzag", one_set_world(shape, big, rpy, zigzag)))
    obstacles = {"type": "random", "use": "obstacles", "quantity": PER, "poses_orientation": "random_yaw",
                 "obstacles_shape": ["cube", "cylinder", "sphere"],
                 "obstacles_dimensions": [[0.2, 1.0], [0.2, 1.0], [0.5, 2.0]]}
    cases.append(("cube, random obstacles (sizes drawn, random yaw)", one_set_world("cube", [200.0, 200.0, 10.0],
                                                                                   [0, 0, 0], obstacles)))
    return cases


def layout_rows(repeats: int) -> list[tuple[str, int, float]]:
    from magna_worlds.generate import resolve_world

    rows = []
    for label, world in layout_cases():
        resolved = resolve_world(world, 0)
        count = resolved.pose_count() + len(resolved.obstacles())
        rows.append((f"layout: {label}", count, best_of(repeats, lambda w=world: resolve_world(w, 0))))
    return rows


def contains_rows(repeats: int) -> list[tuple[str, int, float]]:
    import numpy as np

    from magna_worlds.shapes import contains, half_extents, parse_shape

    rows = []
    rng = np.random.default_rng(0)
    for name, (shape, dims, _) in SOLIDS.items():
        spec = parse_shape(shape, dims)
        low, high = half_extents(spec)
        points = low + rng.random((PER, 3)) * (high - low)
        rows.append((f"contains: {name}", PER, best_of(repeats, lambda s=spec, p=points: contains(s, p))))
    return rows


def file_rows(repeats: int) -> list[tuple[str, int, float]]:
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import load_world

    files = sorted(CORPUS.glob("*/*.json")) + sorted((ROOT / "worlds").glob("*/*.json"))
    rows = []
    for path in files:
        resolved = resolve_world(load_world(path), 0)
        count = resolved.pose_count() + len(resolved.obstacles())
        label = f"corpus {path.parent.name}/{path.name}" if CORPUS in path.parents else \
            f"worlds/{path.parent.name}/{path.name}"
        rows.append((f"load+resolve: {label}", count, best_of(repeats, lambda p=path: resolve_world(load_world(p), 0))))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="runs per figure, the best is kept (default: 5)")
    args = parser.parse_args()

    rows = layout_rows(args.repeats) + contains_rows(args.repeats) + file_rows(args.repeats)
    width = max(len(label) for label, _, _ in rows)
    print(f"{'measurement':{width}} {'poses':>7} {'best ms':>9} {'ms / 10k':>9} {'of 1 s budget':>14}")
    worst = 0.0
    for label, count, seconds in rows:
        if label.startswith("load+resolve"):  # a whole file: its time, not a rate (fixed costs dominate small files)
            print(f"{label:{width}} {count:7d} {seconds * 1e3:9.2f}")
            continue
        per_10k = seconds / max(count, 1) * PER
        share = per_10k / BUDGET_S
        if label.startswith("layout"):
            worst = max(worst, share)
        print(f"{label:{width}} {count:7d} {seconds * 1e3:9.2f} {per_10k * 1e3:9.2f} {share:14.4f}")
    print(f"slowest layout of 10,000 poses: {worst * BUDGET_S * 1e3:.1f} ms, {worst:.4f} of the 1 s budget "
          f"({1 / worst:.0f}x under)" if worst else "no layout measured")
    return 0


if __name__ == "__main__":
    sys.exit(main())
