"""Cost of the UAV manager's obstacle gaps per control step: real shapes against bounding spheres.

A step asks `WorldView.nearest_obstacles` three times at one pose (evaluator, neighbour
selection, recorder): the first call computes the signed distance to every obstacle, the
others reuse it. Prints microseconds per step for 10, 100 and 500 obstacles made of
boxes, cylinders and spheres (plus 2 tori of 4096 triangles each), against the same
obstacles known only by their bounding spheres. Never fails on a time.

    python bench/obstacle_gaps.py [--steps N]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/obstacle_gaps.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "magna_uav", "magna_worlds"))

import numpy as np  # noqa: E402

from magna_uav.shapes import Box, Cylinder, Mesh, Sphere  # noqa: E402
from magna_uav.world_view import AgentState, Obstacle, WorldView  # noqa: E402
from magna_worlds.shapes import torus_mesh  # noqa: E402


def yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def obstacles(count: int, tori: int, rng: np.random.Generator) -> list[Obstacle]:
    out = []
    for i in range(count):
        centre = rng.uniform(-200, 200, 3)
        kind = i % 3
        if kind == 0:
            part = Box(centre, yaw(rng.uniform(0, math.pi)), rng.uniform(0.5, 20, 3))
        elif kind == 1:
            part = Cylinder(centre, yaw(rng.uniform(0, math.pi)), rng.uniform(0.1, 3), rng.uniform(1, 200))
        else:
            part = Sphere(centre, rng.uniform(0.5, 5))
        out.append(Obstacle.solid(f"o{i}", part))
    vertices, triangles = torus_mesh(3.0, 1.5)
    for j in range(tori):
        out.append(Obstacle.solid(f"torus{j}", Mesh(vertices[triangles] + rng.uniform(-50, 50, 3))))
    return out


def per_step(view: WorldView, steps: int, rng: np.random.Generator) -> float:
    """Microseconds per control step: a new pose, then three queries."""
    poses = rng.uniform(-200, 200, (steps, 3))
    start = time.perf_counter()
    for p in poses:
        view.update_agent(AgentState(1, p, safety_radius=0.5))
        view.nearest_obstacles()
        view.nearest_obstacles(5, 6.0)
        view.nearest_obstacles()
    return (time.perf_counter() - start) / steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    print(f"{'obstacles':>10} {'real shapes us/step':>20} {'bounding spheres us/step':>25} {'ratio':>6}")
    for count, tori in ((10, 0), (100, 0), (500, 0), (100, 2)):
        real = obstacles(count, tori, rng)
        spheres = [Obstacle(o.name, o.position, o.radius) for o in real]
        figures = []
        for obstacle_set in (real, spheres):
            view = WorldView(1)
            view.set_obstacles(obstacle_set)
            figures.append(per_step(view, args.steps, rng))
        label = f"{count}" + (f" + {tori} tori" if tori else "")
        print(f"{label:>10} {figures[0]:>20.1f} {figures[1]:>25.1f} {figures[0] / figures[1]:>6.2f}")


if __name__ == "__main__":
    main()
