"""SIGINT and SIGTERM (and SIGHUP) at seeded random points of 5-simulation batches on the real stack (issue 26, item 4).

One dataset is grown by successive `magna run --n-iter 5 --append` batches of a short mission; each
batch is interrupted once, at a point drawn from a seeded generator: in a simulation's launch (the
supervisor started roslaunch, the mission has not begun), its flight (the ground station wrote
mission.json, no result yet), its finishing (result.json written, the launch coming down) or between
two simulations (a summary row written, the next simulation not yet started). The test waits for the
observable condition of the phase, then for a seeded delay, notes the phase it sees just before it
signals, and signals the batch (sometimes twice, as an impatient user would).

After each interruption: the batch exits 130 and leaves no process behind; every simulation that
had finished before is byte for byte what it was; summary.csv has one row per simulation folder, and
the interrupted simulation (if one was running) is marked 'interrupted' in its row and result.json.
A last batch with --append runs to its end on the same dataset.
"""
from __future__ import annotations

import random
import signal
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from magna_common.storage_tree import existing_simulations, simulation_dir
from tests.faults.batch_runs import (
    PHASE_FILES,
    MagnaRun,
    append_one_simulation,
    check_dataset,
    dataset_dir,
    folder_digest,
    result_of,
    summary_ids,
    wait_for,
)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(1200)]

SEED = 26
BATCH_SIZE = 5
# Ten points: each phase the issue names three times, one between simulations; shuffled by SEED.
PHASES = ["launch"] * 3 + ["flight"] * 3 + ["finishing"] * 3 + ["between"]
# Ctrl-C and SIGTERM, as the issue asks, and now and then SIGHUP (the terminal of the batch closed).
SIGNALS = [signal.SIGINT, signal.SIGTERM] * 2 + [signal.SIGHUP]
MAX_DELAY = {"launch": 1.0, "flight": 1.0, "finishing": 0.3, "between": 0.3}  # wall s, well inside each phase


@dataclass(frozen=True)
class Point:
    phase: str
    simulation: int  # which simulation of the batch (1-based) the signal falls in
    signal: signal.Signals
    delay: float  # wall s after the phase's condition appeared
    twice: bool  # a second signal during the clean-up


def interrupt_plan(rng: random.Random) -> list[Point]:
    phases = list(PHASES)
    rng.shuffle(phases)
    points = []
    for phase in phases:
        points.append(Point(phase=phase, simulation=rng.choice([1, 1, 1, 2]),
                            signal=rng.choice(SIGNALS),
                            delay=round(rng.uniform(0.0, MAX_DELAY[phase]), 3), twice=rng.random() < 0.3))
    return points


def phase_condition(dataset: Path, m: int, phase: str):
    """The observable condition that simulation m has entered `phase`."""
    if phase == "between":
        return lambda: m in summary_ids(dataset)
    marker = simulation_dir(dataset, m) / PHASE_FILES[phase]
    return marker.is_file


def observed_phase(dataset: Path, m: int) -> str:
    """Where simulation m is now, read from its files (the same conditions, latest first)."""
    if m in summary_ids(dataset):
        return "between"
    folder = simulation_dir(dataset, m)
    return next((phase for phase, marker in reversed(PHASE_FILES.items()) if (folder / marker).is_file()), "starting")


def test_the_plan_covers_both_signals_and_every_phase():
    plan = interrupt_plan(random.Random(SEED))
    assert len(plan) >= 10
    assert {p.signal for p in plan} == {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    assert {p.phase for p in plan} >= {"launch", "flight", "finishing"}


def test_signals_at_random_points_keep_the_dataset_and_leave_no_process(tmp_path):
    data_root = tmp_path / "data"
    dataset = dataset_dir(data_root)
    plan = interrupt_plan(random.Random(SEED))
    seen_phases: list[str] = []
    marked_interrupted = 0
    for n, point in enumerate(plan):
        finished_before = {m: folder_digest(simulation_dir(dataset, m)) for m in existing_simulations(dataset)}
        rows_before = summary_ids(dataset)
        first = len(finished_before) + 1  # --append numbers after the last folder
        target = first + point.simulation - 1
        run = MagnaRun(data_root, tmp_path / f"run_{n}", ("--n-iter", str(BATCH_SIZE), "--append", "--no-report"))
        try:
            run.start()
            wait_for(phase_condition(dataset, target, point.phase), f"simulation {target}'s {point.phase}", run)
            time.sleep(point.delay)
            phase = observed_phase(dataset, target)
            run.process.send_signal(point.signal)
            if point.twice:
                time.sleep(0.2)
                if run.running():
                    run.process.send_signal(point.signal)
            status = run.wait(timeout=180)
            left = run.wait_for_no_process()
        finally:
            run.kill_everything()
        where = f"point {n} {point} (seen: {phase})"
        seen_phases.append(phase)
        assert status == 130, f"{where}: magna run exited {status}\n{run.output()[-3000:]}"
        assert not left, f"{where}: processes left behind: {left}"

        results = check_dataset(dataset)
        for m, digest in finished_before.items():
            assert folder_digest(simulation_dir(dataset, m)) == digest, f"{where}: simulation_{m} was changed"
        assert summary_ids(dataset)[:len(rows_before)] == rows_before
        last = max(results)
        if phase in ("launch", "flight"):
            # the running simulation is kept, marked as interrupted; nothing started after it
            assert last == target, f"{where}: simulations {sorted(results)}"
            assert (results[target]["termination"], results[target]["success"]) in (
                ("interrupted", False), ("ground_station", results[target]["success"])), results[target]
            marked_interrupted += results[target]["termination"] == "interrupted"
        else:
            # the ground station had reported: the simulation finished with its own outcome; between two
            # simulations the next one may have been starting (then it is marked, or was never started)
            assert last == target or (phase == "between" and last == target + 1), \
                f"{where}: simulations {sorted(results)}"
            assert results[target]["termination"] == "ground_station", results[target]
            assert results[target]["reported"] is True
            if last == target + 1:
                assert results[last]["termination"] == "interrupted", results[last]
        if results[last]["termination"] == "interrupted":
            assert "interrupted" in run.output()
        print(f"\npoint {n}: {point.signal.name}{' twice' if point.twice else ''} in simulation {target}'s "
              f"{phase} (+{point.delay:.2f} s): exit {status}, {len(left)} processes left, simulations "
              f"{min(results)}..{last} kept ({len(finished_before)} unchanged), simulation {last}: "
              f"{results[last]['termination']}/{results[last]['outcome']}", end="")

    assert {"launch", "flight", "finishing"} <= set(seen_phases), seen_phases
    assert marked_interrupted >= 4, f"only {marked_interrupted} simulations were marked interrupted"

    # --append carries on from the last folder, interrupted ones included, and runs to its end
    before = existing_simulations(dataset)
    results = append_one_simulation(data_root, tmp_path / "run_last")
    assert sorted(results) == [*before, len(before) + 1]
    assert results[len(before) + 1]["outcome"] == "completed" and results[len(before) + 1]["success"] is True
    print(f"\n{len(plan)} interrupts, phases seen {seen_phases}, {marked_interrupted} marked interrupted; "
          f"dataset of {len(results)} simulations")
    assert result_of(dataset, 1) is not None
