"""magna_master.reports: each report is drawn by one worker thread while the batch goes on; the index comes last."""
from __future__ import annotations

import io
import threading
from dataclasses import dataclass
from pathlib import Path

from magna_master.reports import Reports


@dataclass
class Finished:  # the fields of a SimulationResult that Reports reads
    id: int
    directory: Path | None
    interrupted: bool = False


class GatedWriter:
    """A write_report that waits for `gate` and keeps who drew what, on which thread."""

    def __init__(self, fail_for: tuple[str, ...] = ()):
        self.gate = threading.Event()
        self.drawn: list[str] = []
        self.threads: set[str] = set()
        self.fail_for = fail_for

    def __call__(self, directory: Path) -> Path:
        assert self.gate.wait(10), "the test never opened the gate"
        self.threads.add(threading.current_thread().name)
        if directory.name in self.fail_for:
            raise RuntimeError("no bag in it")
        self.drawn.append(directory.name)
        return directory / "report.html"


def test_the_caller_goes_on_while_a_worker_draws_the_reports_in_order(tmp_path):
    writer = GatedWriter()
    reports = Reports(write_report=writer, write_index=lambda d: d / "index.html", out=io.StringIO())
    for m in (1, 2, 3):
        reports(Finished(m, tmp_path / f"simulation_{m}"))  # returns although nothing can be drawn yet
    assert writer.drawn == []
    assert reports.pending() == 3
    writer.gate.set()
    reports.wait()
    assert writer.drawn == ["simulation_1", "simulation_2", "simulation_3"]
    assert writer.threads == {"magna-reports"}
    assert reports.pending() == 0
    assert reports.written == [tmp_path / f"simulation_{m}" / "report.html" for m in (1, 2, 3)]


def test_a_report_that_fails_is_said_with_the_command_that_draws_it_and_the_others_are_written(tmp_path):
    writer = GatedWriter(fail_for=("simulation_2",))
    writer.gate.set()
    out = io.StringIO()
    reports = Reports(write_report=writer, write_index=lambda d: d / "index.html", out=out)
    for m in (1, 2, 3):
        reports(Finished(m, tmp_path / f"simulation_{m}"))
    reports.finish(tmp_path)
    assert writer.drawn == ["simulation_1", "simulation_3"]
    assert reports.failed == [2]
    said = out.getvalue()
    assert f"simulation 2: no report: no bag in it; try `magna report {tmp_path / 'simulation_2'}`" in said
    assert f"report:  {tmp_path / 'simulation_3' / 'report.html'} (the last simulation's)" in said
    assert f"index:   {tmp_path / 'index.html'}" in said


def test_the_index_is_written_after_every_report(tmp_path):
    writer = GatedWriter()
    seen_at_index: list[int] = []

    def write_index(dataset_dir: Path) -> Path:
        seen_at_index.append(len(writer.drawn))
        return dataset_dir / "index.html"

    reports = Reports(write_report=writer, write_index=write_index, out=io.StringIO())
    for m in (1, 2):
        reports(Finished(m, tmp_path / f"simulation_{m}"))
    threading.Timer(0.05, writer.gate.set).start()  # the drawing ends after finish has begun waiting
    reports.finish(tmp_path)
    assert seen_at_index == [2]


def test_interrupted_and_unsaved_simulations_get_no_report_and_no_worker(tmp_path):
    writer = GatedWriter()
    writer.gate.set()
    reports = Reports(write_report=writer, write_index=lambda d: d / "index.html", out=io.StringIO())
    reports(Finished(1, None))
    reports(Finished(2, tmp_path / "simulation_2", interrupted=True))
    assert reports.pending() == 0
    reports.wait()  # nothing handed over: returns at once
    assert writer.drawn == [] and writer.threads == set()


def test_reports_can_be_handed_over_again_after_a_wait(tmp_path):
    writer = GatedWriter()
    writer.gate.set()
    reports = Reports(write_report=writer, write_index=lambda d: d / "index.html", out=io.StringIO())
    reports(Finished(1, tmp_path / "simulation_1"))
    reports.wait()
    reports(Finished(2, tmp_path / "simulation_2"))
    reports.wait()
    assert writer.drawn == ["simulation_1", "simulation_2"]
