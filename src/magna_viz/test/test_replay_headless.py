"""`magna replay --headless` on the session's recorded simulation (root conftest.py `recorded_run`).

The bag is played into rviz under Xvfb; the final picture must be a real picture (not blank) that
shows each UAV in its mission colour, and every process the replay started must be gone after it.
A second replay with the UAVs recoloured shows the colours come from the mission file, not the world.
"""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.recorded_run import _processes_with
from tests.support import ROOT

NEAR = 30  # max difference per channel (0-255) for a pixel to count as a UAV's colour
ENOUGH = 200  # pixels of a colour: a trail across the world is thousands


def magna_replay(*argv, token: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(ROOT / "magna"), "replay", *map(str, argv)], capture_output=True, text=True,
                          cwd=ROOT, stdin=subprocess.DEVNULL, timeout=600,
                          env=dict(os.environ, MAGNA_REPLAY_TEST_TOKEN=token))


def pixels_near(image: np.ndarray, rgb) -> int:
    return int((np.abs(image.astype(int) - np.array(rgb[:3])).max(axis=2) <= NEAR).sum())


def mission_colours(mission_file: Path) -> dict[int, tuple[int, int, int]]:
    agents = json.loads(mission_file.read_text())["Agents_Config"]
    return {a["ID"]: tuple(int(c) for c in a["marker_color"][:3]) for a in agents}


@pytest.fixture(scope="module")
def replayed(recorded_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("replay")
    token = f"magna-replay-test-{os.getpid()}"
    before = sorted(p.name for p in recorded_run.sim_dir.iterdir())
    done = magna_replay(recorded_run.sim_dir, "--headless", "--speed", "8", "--every", "8", "--gif", "--mp4",
                        "--size", "960x540", "-o", out, token=token)
    return recorded_run, out, done, token, before


def test_the_replay_writes_frames_final_gif_and_mp4(replayed):
    run, out, done, _token, _before = replayed
    assert done.returncode == 0, done.stdout + done.stderr
    frames = sorted(out.glob("frame_*.png"))
    assert frames and frames[0].name == "frame_0001.png"
    assert sorted(p.name for p in out.iterdir()) == sorted([p.name for p in frames] +
                                                           ["final.png", "replay.gif", "replay.mp4"])
    assert f"final:   {out / 'final.png'}" in done.stdout
    with Image.open(out / "final.png") as final:
        assert final.size == (960, 540)
    with Image.open(out / "replay.gif") as gif:
        # every frame and the final one (Pillow merges a frame identical to the one before it)
        assert gif.format == "GIF" and 2 <= gif.n_frames <= len(frames) + 1
        assert gif.size == (800, 450)
    assert (out / "replay.mp4").read_bytes()[4:8] == b"ftyp"


def test_the_final_frame_is_a_picture_with_every_uav_in_its_mission_colour(replayed):
    run, out, done, _token, _before = replayed
    assert done.returncode == 0, done.stderr
    image = np.asarray(Image.open(out / "final.png").convert("RGB"))
    colours = len(np.unique(image.reshape(-1, 3), axis=0))
    assert colours > 500 and image.std() > 5.0, f"a blank picture: {colours} colours, std {image.std():.1f}"
    expected = mission_colours(run.sim_dir / "mission.json")
    assert expected == mission_colours(ROOT / "missions" / "Gym" / "2UAVs_Crossing_ORCA.json")
    assert set(expected) == set(run.uav_ids)
    for uav, rgb in expected.items():
        assert pixels_near(image, rgb) >= ENOUGH, f"uav {uav}: too few pixels near its colour {rgb}"


def test_nothing_the_replay_started_is_left_and_the_simulation_is_untouched(replayed):
    run, _out, done, token, before = replayed
    assert done.returncode == 0, done.stderr
    assert _processes_with(token) == []
    assert sorted(p.name for p in run.sim_dir.iterdir()) == before


def test_the_colours_come_from_the_mission_file(replayed, tmp_path):
    run, _out, first, _token, _before = replayed
    assert first.returncode == 0, first.stderr
    mission = json.loads((run.sim_dir / "mission.json").read_text())
    recolour = {1: [0, 0, 255, 0.5], 2: [255, 255, 0, 0.5]}
    for agent in mission["Agents_Config"]:
        agent["marker_color"] = recolour[agent["ID"]]
    (tmp_path / "mission.json").write_text(json.dumps(mission))
    token = f"magna-replay-test-recoloured-{os.getpid()}"
    done = magna_replay(run.sim_dir / "simulation.bag", "--headless", "--speed", "8", "--every", "0",
                        "--size", "960x540", "--mission", tmp_path / "mission.json", "--output", tmp_path / "out",
                        token=token)
    assert done.returncode == 0, done.stdout + done.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["final.png"]
    image = np.asarray(Image.open(tmp_path / "out" / "final.png").convert("RGB"))
    for rgb in recolour.values():
        assert pixels_near(image, rgb) >= ENOUGH
    for rgb in mission_colours(run.sim_dir / "mission.json").values():  # red and green are gone
        assert pixels_near(image, rgb) < ENOUGH / 10
    assert _processes_with(token) == []
