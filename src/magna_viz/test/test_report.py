"""report.html per simulation, index.html per dataset, and `magna report`.

The real-run tests read what `magna run` itself wrote for the session's recorded simulation
(root conftest.py `recorded_run`): the batch writes the report as it goes.
"""
from __future__ import annotations

import base64
import io
import json
import re
from pathlib import Path

import pytest

from magna_master import cli
from magna_viz import index, pages, report

IMG_SOURCES = re.compile(r'<img src="([^"]+)"')


def fake_simulation(dataset: Path, m: int, success: bool = True, **more) -> Path:
    sim_dir = dataset / f"simulation_{m}"
    sim_dir.mkdir(parents=True)
    result = {"id": m, "seed": 100 + m, "success": success, "outcome": "completed" if success else "aborted",
              "message": f"mission ended {'completed' if success else 'aborted'}", "sim_duration": 60.0 + m,
              "wall_time": 10.0, "collisions": 0 if success else 2, "termination": "ground_station",
              "hyperparameters": {"world": "Gym", "subworld": "Four_Cylinders", "mission": "Gym",
                                  "submission": "Two"}, **more}
    (sim_dir / "result.json").write_text(json.dumps(result))
    return sim_dir


# --- without a recording ---------------------------------------------------------------------------------------

def test_a_simulation_without_recording_gets_its_result_and_the_reason_for_no_plots(tmp_path):
    sim_dir = fake_simulation(tmp_path, 1, success=False)
    written = report.write_report(sim_dir)
    page = written.path.read_text()
    assert written.path == sim_dir / "report.html" and written.plots == {}
    assert "Simulation 1: Gym/Two in Gym/Four_Cylinders" in page
    assert '<span class="bad">failure</span>: aborted' in page and "mission ended aborted" in page
    assert any(note.startswith("no plots: ") for note in written.notes)
    assert "no plots: " in page
    assert not (sim_dir / "plots").exists()


def test_an_existing_report_is_kept_unless_overwrite(tmp_path):
    sim_dir = fake_simulation(tmp_path, 1)
    (sim_dir / "report.html").write_text("mine")
    with pytest.raises(report.ReportError, match="already exists; pass --force"):
        report.write_report(sim_dir)
    assert (sim_dir / "report.html").read_text() == "mine"
    report.write_report(sim_dir, overwrite=True)
    assert (sim_dir / "report.html").read_text().startswith("<!DOCTYPE html>")


def test_a_folder_without_result_names_the_file(tmp_path):
    with pytest.raises(report.ReportError, match=r"result\.json: no such file"):
        report.write_report(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_page_text_is_escaped(tmp_path):
    sim_dir = fake_simulation(tmp_path, 1, message="<script>alert(1)</script>")
    page = report.write_report(sim_dir).path.read_text()
    assert "<script>" not in page and "&lt;script&gt;" in page


# --- the dataset index -----------------------------------------------------------------------------------------

def test_the_index_lists_every_simulation_in_order_and_links_the_reports(tmp_path):
    for m, ok in ((2, False), (10, True), (1, True)):
        fake_simulation(tmp_path, m, success=ok)
    report.write_report(tmp_path / "simulation_2")
    (tmp_path / "simulation_3").mkdir()  # a simulation that never wrote its result
    page = index.write_index(tmp_path).read_text()
    order = [page.index(f">simulation_{m}") for m in (1, 2, 3, 10)]
    assert order == sorted(order)
    assert '<a href="simulation_2/report.html">simulation_2</a>' in page
    assert "simulation_1 (no report)" in page and "no result.json" in page
    assert "4 simulation(s), 2 succeeded, 2 collision(s) in all" in page
    assert "mean simulated duration 64.3 s" in page  # (61 + 62 + 70) / 3


# --- the command -----------------------------------------------------------------------------------------------

def test_the_command_refuses_a_missing_folder(tmp_path, capsys):
    assert cli.main(["report", str(tmp_path / "nope")]) == 2
    assert "nope: no such folder" in capsys.readouterr().err


def test_the_command_refuses_a_folder_that_is_no_simulation(tmp_path, capsys):
    assert cli.main(["report", str(tmp_path)]) == 2
    assert "neither a simulation folder" in capsys.readouterr().err


def test_the_command_keeps_an_existing_report_without_force(tmp_path, capsys):
    sim_dir = fake_simulation(tmp_path, 1)
    (sim_dir / "report.html").write_text("mine")
    assert cli.main(["report", str(sim_dir)]) == 2
    assert capsys.readouterr().err == (f"magna report: {sim_dir / 'report.html'} already exists (magna run writes it); "
                                       "pass --force to write it again\n")
    assert (sim_dir / "report.html").read_text() == "mine"
    assert cli.main(["report", str(sim_dir), "--force"]) == 0
    assert (sim_dir / "report.html").read_text() != "mine"
    assert f"report: {sim_dir / 'report.html'}" in capsys.readouterr().out


def test_the_command_on_a_dataset_writes_missing_reports_and_the_index(tmp_path, capsys):
    for m in (1, 2):
        fake_simulation(tmp_path, m)
    (tmp_path / "simulation_2" / "report.html").write_text("kept")
    assert cli.main(["report", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"report: {tmp_path / 'simulation_1' / 'report.html'}" in out
    assert (tmp_path / "simulation_2" / "report.html").read_text() == "kept"
    assert (tmp_path / "index.html").exists() and f"index:  {tmp_path / 'index.html'}" in out


# --- what `magna run` wrote for a real simulation ------------------------------------------------------------------

def _png(source: str):
    from PIL import Image

    assert source.startswith("data:image/png;base64,"), source[:40]
    return Image.open(io.BytesIO(base64.b64decode(source.split(",", 1)[1])))


def test_magna_run_wrote_a_self_contained_report_with_every_plot(recorded_run):
    page = (recorded_run.sim_dir / "report.html").read_text()
    sources = IMG_SOURCES.findall(page)
    assert len(sources) == len(report.CAPTIONS) + 1  # the plots and the mission picture
    for source in sources:  # inlined, so the page alone is the whole report
        picture = _png(source)
        assert picture.width > 300 and picture.height > 200
        assert len(picture.convert("RGB").resize((64, 64)).getcolors(64 * 64)) > 20  # not a blank canvas
    for caption in report.CAPTIONS.values():
        assert f"<figcaption>{pages.escape(caption)}</figcaption>" in page
    assert '<span class="ok">success</span>: completed' in page
    assert "Simulation 1: Gym/2UAVs_Crossing_ORCA in Gym/Central_Obstacle_Torus" in page
    assert sorted(p.name for p in (recorded_run.sim_dir / "plots").iterdir()) == sorted(
        [f"{name}.png" for name in report.CAPTIONS] + [report.MISSION_PICTURE])


def test_the_report_shows_each_uav_in_its_mission_colour(recorded_run):
    page = (recorded_run.sim_dir / "report.html").read_text()
    mission = json.loads((recorded_run.sim_dir / "mission.json").read_text())
    for agent in mission["Agents_Config"]:
        r, g, b = agent["marker_color"][:3]
        assert f"background: rgb({r}, {g}, {b})" in page, agent


def test_magna_run_wrote_the_dataset_index(recorded_run):
    dataset = recorded_run.sim_dir.parent
    page = (dataset / "index.html").read_text()
    assert '<a href="simulation_1/report.html">simulation_1</a>' in page
    assert "1 simulation(s), 1 succeeded" in page
    assert '<img src="world.png"' in page and '<img src="mission.png"' in page
