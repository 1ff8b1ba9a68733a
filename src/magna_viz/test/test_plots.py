"""magna_viz.plots: every figure of a recorded simulation, as PNGs of the expected size and content.

The pictures are checked by their pixels: the size, that they are not blank, and that what must
show does (the UAVs' mission colours, a contact's shading, a torus's hole seen from above). The real
run is the session's `recorded_run` (root conftest.py); the rest are hand-made recordings.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.image import imread
from matplotlib.patches import PathPatch

from magna_viz import plots
from magna_viz.recorded_world import RecordedWorld, WorldShape
from magna_viz.recording import Proximity, Recording, Samples, UavRecord, load_recording
from magna_worlds.draw import OBSTACLE_COLOR
from magna_worlds.shapes import ShapeSpec
from magna_worlds.transforms import Frame
from tests.support import load_module

ROOT = Path(__file__).resolve().parents[3]
SIZE = (round(plots.FIGSIZE[1] * plots.DPI), round(plots.FIGSIZE[0] * plots.DPI))  # (rows, columns) of pixels
RED, GREEN = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)


def pixels(png: Path) -> np.ndarray:
    return imread(png)[:, :, :3]


def count_colour(image: np.ndarray, rgb, tolerance: float = 0.06) -> int:
    return int(np.sum(np.all(np.abs(image - np.asarray(rgb)) < tolerance, axis=2)))


def not_blank(image: np.ndarray) -> bool:
    """More than 2% of the picture is not background white, in more than a handful of colours."""
    ink = np.any(image < 0.97, axis=2)
    return ink.mean() > 0.02 and len(np.unique((image[ink] * 255).astype(np.uint8), axis=0)) > 20


# --- hand-made recordings ------------------------------------------------------------------------------------------

def hand_made(contact: bool = False) -> Recording:
    """Two UAVs crossing over a coloured torus and an obstacle; CSV-like data only (no bag: no timeline)."""
    t = np.arange(0.0, 20.0, 0.1)
    uavs = {}
    for uav, colour, sign in ((1, (*RED, 0.5), 1.0), (2, (*GREEN, 0.5), -1.0)):
        xyz = np.column_stack([sign * (t - 10.0) * 0.5, np.sin(t / 3.0) * 2.0, np.full(len(t), 2.0)])
        velocity = np.gradient(xyz, t, axis=0)
        gap = np.abs(t - 10.0) * 0.5 + 0.1
        if contact and uav == 1:
            gap[95:105] = -0.2  # 0.4 m apart, under the pair's 0.6 m
        proximity = Proximity(t, gap + 0.6, np.full(len(t), 0.6), np.full(len(t), 3.0), 0.3, gap < 0.0,
                              np.zeros(len(t), dtype=bool), "uav_1.csv")
        uavs[uav] = UavRecord(uav, "iris", colour, 0.3, 2.0, Samples(t, xyz, "uav.csv"),
                              Samples(t, velocity, "uav.csv"), proximity=proximity)
    world = RecordedWorld([
        WorldShape("Zone/Ring", "geometry", ShapeSpec("torus", (8.0, 8.0, 2.0)),
                   Frame(np.array([0.0, 0.0, 2.0]), np.eye(3)), (0.2, 0.4, 0.9), 1.0),
        WorldShape("obs_0", "obstacle", ShapeSpec("sphere", (1.0, 1.0, 1.0)),
                   Frame(np.array([6.0, 6.0, 2.0]), np.eye(3)), OBSTACLE_COLOR, 1.0)], None, "hand-made")
    return Recording(Path("/hand/made/simulation_1"), uavs, world, None, None, None, {}, 0.0, 19.9)


def test_without_a_bag_the_timeline_and_latency_are_skipped_with_the_reason(tmp_path):
    drawn = plots.draw_all(hand_made(), tmp_path)
    assert sorted(drawn) == ["distances", "trajectories_3d", "trajectories_top", "velocities"]
    assert sorted(drawn.skipped) == ["latency", "timeline"]
    assert all("simulation.bag" in why for why in drawn.skipped.values())
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"{name}.png" for name in drawn)  # no temporaries
    for png in drawn.values():
        image = pixels(png)
        assert image.shape[:2] == SIZE and not_blank(image)
        assert count_colour(image, RED) > 20 and count_colour(image, GREEN) > 20


def test_the_top_view_fills_silhouettes_once_and_keeps_a_torus_hole(tmp_path):
    torus = WorldShape("ring", "geometry", ShapeSpec("torus", (8.0, 8.0, 2.0)), Frame.identity(), RED, 1.0)
    faces, _ = plots._mesh(torus)
    fig = plots._figure((4.0, 4.0))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(-5.0, 5.0)
    ax.set_ylim(-5.0, 5.0)
    ax.add_patch(PathPatch(plots._silhouette(faces), facecolor=(1.0, 0.0, 0.0, 0.3), edgecolor="none"))
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    buffer.seek(0)
    image = imread(buffer)[:, :, :3]

    def at(x, y):
        return image[int((5.0 - y) / 10.0 * image.shape[0]), int((x + 5.0) / 10.0 * image.shape[1])]

    once = 1.0 - 0.3  # one coat of 30% red over white, wherever the triangles overlap
    assert at(3.5, 0.0) == pytest.approx([1.0, once, once], abs=0.01)
    assert at(-2.5, -2.5) == pytest.approx([1.0, once, once], abs=0.01)
    assert at(0.0, 0.0) == pytest.approx([1.0, 1.0, 1.0])  # the hole
    assert at(4.8, 4.8) == pytest.approx([1.0, 1.0, 1.0])


def test_a_contact_is_shaded_on_the_distances(tmp_path):
    shade = 0.15 * np.array(to_rgb(plots.CONTACT)) + 0.85  # the span's alpha over white
    touching = pixels(plots.plot_distances(hand_made(contact=True), tmp_path / "touching.png"))
    apart = pixels(plots.plot_distances(hand_made(contact=False), tmp_path / "apart.png"))
    plot_area = slice(0, int(0.77 * SIZE[1]))  # left of the legend, which has a patch of that colour
    assert count_colour(touching[:, plot_area], shade, 0.02) > 2000  # 1 s of 20 s, the axes' height
    assert count_colour(apart[:, plot_area], shade, 0.02) < 50  # a few antialiased edges of the red line


def test_a_figure_is_replaced_atomically(tmp_path):
    target = tmp_path / "velocities.png"
    target.write_bytes(b"an older picture")
    plots.plot_velocities(hand_made(), target)
    assert pixels(target).shape[:2] == SIZE
    assert [p.name for p in tmp_path.iterdir()] == ["velocities.png"]


def test_pauses_in_a_series_break_its_line():
    t = np.array([0.0, 0.1, 0.2, 0.3, 5.0, 5.1])
    gapped_t, y = plots._gapped(t, np.arange(6.0))
    assert gapped_t.tolist() == pytest.approx([0.0, 0.1, 0.2, 0.3, 2.65, 5.0, 5.1])
    assert np.isnan(y[4]) and y[[0, 3, 5, 6]].tolist() == [0.0, 3.0, 4.0, 5.0]
    assert plots._gapped(t[:4], np.arange(4.0))[0].tolist() == t[:4].tolist()


# --- the latency figure --------------------------------------------------------------------------------------------

def test_the_latency_distribution_draws_each_group_in_its_colour(tmp_path):
    png = plots.plot_latency_distribution({"UAV 1": [40.0, 55.0, 61.0, 70.0], "UAV 2": [], "UAV 3": [30.0, 35.0]},
                                          tmp_path / "latency.png", "test", colors={"UAV 1": RED, "UAV 3": GREEN})
    image = pixels(png)
    assert image.shape[:2] == SIZE and not_blank(image)
    assert count_colour(image, RED) > 50 and count_colour(image, GREEN) > 50
    with pytest.raises(ValueError, match="no latency samples"):
        plots.plot_latency_distribution({"UAV 1": []}, tmp_path / "none.png", "test")
    assert not (tmp_path / "none.png").exists()


def test_the_command_latency_bench_draws_with_the_shared_function(tmp_path):
    bench = load_module(ROOT / "bench" / "command_latency.py", "command_latency_bench")
    rng = np.random.default_rng(1)
    rows = [{"n": n, "latency": list(rng.uniform(0.02, 0.06, 30))} for n in (1, 2, 10)] + [{"n": 3, "latency": []}]
    bench.draw(rows, tmp_path / "pictures" / "command_latency.png", "1")
    image = pixels(tmp_path / "pictures" / "command_latency.png")
    assert image.shape[:2] == SIZE and not_blank(image)
    assert count_colour(image, to_rgb("tab:red"), 0.03) > 100  # the 50 ms target line on both panels


# --- the real recorded simulation ----------------------------------------------------------------------------------

def test_every_figure_is_drawn_from_the_recorded_run(recorded_run, tmp_path):
    recording = load_recording(recorded_run.sim_dir)
    drawn = plots.draw_all(recording, tmp_path / "plots")
    assert list(drawn) == list(plots.FIGURES) and drawn.skipped == {}
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == sorted(f"{n}.png" for n in plots.FIGURES)
    colours = [u.rgb for u in recording.uavs.values()]
    assert len(colours) == 2
    for name, png in drawn.items():
        image = pixels(png)
        assert image.shape[:2] == SIZE, name
        assert not_blank(image), name
        for rgb in colours:  # every figure shows each UAV in its mission colour
            assert count_colour(image, rgb) > 20, (name, rgb)
