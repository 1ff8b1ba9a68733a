"""Drawing: clusters per container, labelled transitions, active states highlighted, files written whole."""
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from magna_sm import CBState, StateMachine
from magna_sm.draw import ACTIVE_FILL, DrawError, draw, structures_of, to_dot
from magna_sm.examples import filmed_delivery


def active_fill_pixels(png: Path) -> int:
    target = np.array([int(ACTIVE_FILL[i:i + 2], 16) for i in (1, 3, 5)])
    pixels = np.asarray(Image.open(png).convert("RGB"), dtype=int)
    return int((np.abs(pixels - target).max(axis=2) <= 6).sum())


def test_dot_has_a_cluster_per_container_and_labelled_edges():
    dot = to_dot(structures_of(filmed_delivery()))
    for path in ("/MISSION", "/MISSION/1_filmed_delivery", "/MISSION/1_filmed_delivery/1_delivery",
                 "/MISSION/1_filmed_delivery/2_filming"):
        assert f'subgraph "cluster_{path}"' in dot
    assert '"/MISSION/spawn_agents" -> "/MISSION/1_take_off" [label="completed"]' in dot
    assert 'lhead="cluster_/MISSION/1_filmed_delivery"' in dot  # an edge into the nested Concurrence
    assert ACTIVE_FILL not in dot  # nothing runs


def test_running_state_is_highlighted_in_the_png(tmp_path):
    release = threading.Event()
    machine = StateMachine(["done"], name="M")
    with machine:
        StateMachine.add("FIRST", CBState(lambda ud: "ok", ["ok"]), {"ok": "HOVER"})
        StateMachine.add("HOVER", CBState(lambda ud: release.wait(10) and "ok", ["ok"]), {"ok": "done"})
    thread = threading.Thread(target=machine.execute, daemon=True)
    thread.start()
    try:
        for _ in range(200):
            if machine.get_active_states() == ["HOVER"]:
                break
            threading.Event().wait(0.01)
        running = draw(machine, tmp_path / "running.png")
    finally:
        release.set()
        thread.join(5)
    idle = draw(machine, tmp_path / "idle.png")
    assert active_fill_pixels(running) > 100
    assert active_fill_pixels(idle) == 0


def test_svg_names_every_state(tmp_path):
    svg = draw(filmed_delivery(), tmp_path / "mission.svg").read_text()
    for label in ("spawn_agents", "1_take_off", "to_delivery_height", "follow_agent_ap", "mission_failed"):
        assert label in svg


def test_unknown_format_is_refused_and_nothing_is_left(tmp_path):
    with pytest.raises(DrawError, match=r"mission\.jpg: unknown picture format"):
        draw(filmed_delivery(), tmp_path / "mission.jpg")
    assert list(tmp_path.iterdir()) == []


def test_rosrun_draw_writes_the_picture(tmp_path):
    out = tmp_path / "delivery.png"
    done = subprocess.run(["rosrun", "magna_sm", "draw", "magna_sm.examples:filmed_delivery", "-o", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert Image.open(out).size[0] > 400


def test_rosrun_draw_bad_target_is_a_clear_error(tmp_path):
    done = subprocess.run(["rosrun", "magna_sm", "draw", "magna_sm.examples:nope", "-o", str(tmp_path / "x.png")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode != 0
    assert "cannot load 'magna_sm.examples:nope'" in done.stderr
    assert not (tmp_path / "x.png").exists()
