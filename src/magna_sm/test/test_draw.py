"""Drawing: clusters per container, labelled transitions, active states highlighted, files written whole;
a flat picture when graphviz cannot lay the clusters out; never an output replaced without --force."""
import logging
import os
import shlex
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from magna_sm import CBState, StateMachine
from magna_sm.container import ContainerStructure
from magna_sm.draw import ACTIVE_FILL, DrawError, draw, draw_structures, render, structures_of, to_dot
from magna_sm.examples import filmed_delivery
from magna_sm.tools import draw_main


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


# --- when graphviz cannot lay the clusters out ---------------------------------------------------------------------

# A machine dot (2.43) cannot draw as nested clusters with its usual ranking: a nested machine whose outcome
# leads to a state that may go back into it. dot stops with an error ("trouble in init_rank", "triangulation
# failed") and, for the first, a dump of its ranks.
UNRANKABLE = [
    ContainerStructure("/M", "StateMachine", ("s0", "s1", "s2"), ("StateMachine", "CBState", "CBState"), (), ("s0",),
                       (("s0", "e0", "s1"), ("s0", "e1", "s2"), ("s2", "e1", "s0"), ("s2", "e2", "s1"))),
    ContainerStructure("/M/s0", "StateMachine", ("s0", "s1"), ("CBState", "CBState"), ("o0", "o1"), ("s0",),
                       (("s0", "e0", "o1"), ("s1", "e3", "o0"))),
]
DUMP_LINES = 300


def fake_dot(folder: Path, fails_unless: str = "") -> Path:
    """A `dot` on PATH that fails as graphviz does (an error and a long dump on stderr) unless its input holds
    `fails_unless` (empty: it always fails); otherwise it hands the input to the real dot."""
    real = shutil.which("dot")
    folder.mkdir(exist_ok=True)
    script = folder / "dot"
    script.write_text(f"""#!/bin/sh
input=$(cat)
case "$input" in
  *{shlex.quote(fails_unless) if fails_unless else "NEVER-IN-A-DOT-SOURCE"}*)
    printf '%s' "$input" | {real} "$@"
    exit $? ;;
esac
echo "Error: trouble in init_rank" >&2
i=0; while [ $i -lt {DUMP_LINES} ]; do echo "	%0 $i" >&2; i=$((i+1)); done
exit 1
""")
    script.chmod(0o755)
    return folder


def test_a_machine_dot_cannot_rank_in_clusters_is_still_drawn_with_its_clusters(tmp_path, caplog, capfd):
    clustered = to_dot(UNRANKABLE)
    plain_dot = subprocess.run(["dot", "-Tsvg"], input=clustered, text=True, capture_output=True)
    assert plain_dot.returncode != 0, "graphviz now ranks this machine: find one it cannot, or the fallback is untested"
    with caplog.at_level(logging.DEBUG, logger="magna_sm.draw"):
        svg = draw_structures(UNRANKABLE, tmp_path / "m.svg").read_text()
        png = draw_structures(UNRANKABLE, tmp_path / "m.png")
    assert 'class="cluster"' in svg and "s0 &#160;[StateMachine]" in svg  # dot's other ranking kept the boxes
    assert Image.open(png).size[0] > 100
    assert [r for r in caplog.records if r.levelno >= logging.WARNING] == []  # the whole picture: nothing to say
    assert capfd.readouterr() == ("", "")  # graphviz's dump never reaches the terminal
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.png", "m.svg"]


def test_render_of_dot_source_also_falls_back_to_the_other_ranking(tmp_path):
    assert Image.open(render(to_dot(UNRANKABLE), tmp_path / "m.png")).size[0] > 100


def test_clusters_graphviz_cannot_draw_at_all_are_drawn_flat_with_one_line(tmp_path, monkeypatch, caplog, capfd):
    monkeypatch.setenv("PATH", f"{fake_dot(tmp_path / 'bin', fails_unless='compound=false')}:{os.environ['PATH']}")
    with caplog.at_level(logging.WARNING, logger="magna_sm.draw"):
        svg = draw(filmed_delivery(), tmp_path / "flat.svg").read_text()
        draw(filmed_delivery(), tmp_path / "flat.svg")  # drawn again: said once
    assert 'class="cluster"' not in svg
    for label in ("1_filmed_delivery &#160;[Concurrence]", "follow_agent_ap", "mission_failed"):
        assert label in svg  # containers become nodes; every state and outcome is still there
    assert [r.getMessage() for r in caplog.records] == [
        f"{tmp_path / 'flat.svg'}: graphviz could not lay out the clusters; drew them flat"]
    assert capfd.readouterr() == ("", "")


def test_flat_layout_links_containers_to_their_first_states_and_leaves_from_their_outcomes():
    dot = to_dot(structures_of(filmed_delivery()), layout="flat")
    assert "subgraph" not in dot and "lhead" not in dot
    # the Concurrence starts both its machines; its outcome box is where its transition leaves
    assert ('"/MISSION/1_filmed_delivery/__anchor" -> "/MISSION/1_filmed_delivery/1_delivery/__anchor" '
            '[style=dashed, arrowhead=empty];') in dot
    assert '"/MISSION/1_filmed_delivery/:completed" -> "/MISSION/1_land" [label="completed"];' in dot
    plain = to_dot(structures_of(filmed_delivery()), layout="plain")
    assert '"/MISSION/1_filmed_delivery/:completed" -> "/MISSION/1_land" [xlabel="completed"];' in plain


def test_when_even_the_plain_layout_fails_the_error_is_one_line_and_nothing_is_left(tmp_path, monkeypatch, capfd):
    monkeypatch.setenv("PATH", f"{fake_dot(tmp_path / 'bin')}:{os.environ['PATH']}")
    out = tmp_path / "pics" / "never.png"
    with pytest.raises(DrawError) as caught:
        draw(filmed_delivery(), out)
    assert str(caught.value) == f"graphviz could not draw {out}: Error: trouble in init_rank"
    assert list(out.parent.iterdir()) == []
    assert capfd.readouterr() == ("", "")


def test_rosrun_draw_says_one_line_when_it_draws_flat(tmp_path):
    env = dict(os.environ, PATH=f"{fake_dot(tmp_path / 'bin', fails_unless='compound=false')}:{os.environ['PATH']}")
    out = tmp_path / "delivery.png"
    done = subprocess.run(["rosrun", "magna_sm", "draw", "magna_sm.examples:filmed_delivery", "-o", str(out)],
                          capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"{out}\n"
    assert done.stderr == f"{out}: graphviz could not lay out the clusters; drew them flat\n"
    assert Image.open(out).size[0] > 100


# --- never replaced without --force ------------------------------------------------------------------------------

def test_rosrun_draw_refuses_an_existing_picture_unless_forced(tmp_path):
    out = tmp_path / "delivery.png"
    out.write_bytes(b"keep me")
    command = ["rosrun", "magna_sm", "draw", "magna_sm.examples:filmed_delivery", "-o", str(out)]
    refused = subprocess.run(command, capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2
    assert refused.stderr == f"draw: {out} already exists; pass --force to replace it\n"
    assert out.read_bytes() == b"keep me"
    forced = subprocess.run([*command, "--force"], capture_output=True, text=True, timeout=60)
    assert forced.returncode == 0, forced.stderr
    assert Image.open(out).size[0] > 400


def test_draw_main_long_option_and_force(tmp_path, capsys):
    out = tmp_path / "m.svg"
    assert draw_main(["magna_sm.examples:filmed_delivery", "--output", str(out)]) == 0
    assert draw_main(["magna_sm.examples:filmed_delivery", "--output", str(out)]) == 2
    assert "already exists; pass --force" in capsys.readouterr().err
    assert draw_main(["magna_sm.examples:filmed_delivery", "--output", str(out), "--force", "--title", "T"]) == 0
    assert ">T<" in out.read_text()


def test_viewer_refuses_an_existing_picture_before_joining_ros(tmp_path):
    out = tmp_path / "live.png"
    out.write_bytes(b"keep me")
    done = subprocess.run(["rosrun", "magna_sm", "viewer", "demo", "-o", str(out), "--once"],
                          capture_output=True, text=True, timeout=60,
                          env=dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:9"))  # no master: none needed
    assert done.returncode == 2
    assert done.stderr == f"viewer: {out} already exists; pass --force to replace it\n"
    assert out.read_bytes() == b"keep me"
