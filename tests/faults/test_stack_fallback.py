"""A batch's persistent stack after a crash (issue 27): the next simulation starts cold, and flies.

A batch of two simulations of the drill's short mission keeps one stack (master, simulator, world node,
ORCA-3D) up. While the first flies, its simulator is SIGKILLed; that simulation ends as crashed, naming
the simulator, and the second starts a fresh stack (result.json stack.start "cold") and succeeds.
Nothing of either stack outlives the batch.
"""
from __future__ import annotations

import io
import os
import signal
import threading
from pathlib import Path

import pytest

from magna_common.processes import TOKEN_ENV, ancestors, tagged_processes
from magna_gs.inputs import resolve_inputs
from magna_master.batch import Batch
from magna_master.batch_config import BatchConfig
from tests.faults.test_killed_components import GUARD, MISSION, PATH_ROWS, WORLD, csv_rows, environment
from tests.support import wait_until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(600)]


def our_processes(marker: str) -> dict[int, str]:
    """{pid: token} of the live processes this test started whose command line holds `marker`."""
    me, found = os.getpid(), {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if marker.encode() in command and me in ancestors(int(entry.name)):
            found[int(entry.name)] = environment(int(entry.name)).get(TOKEN_ENV, "")
    return found


def test_a_crash_on_a_warm_stack_makes_the_next_simulation_start_cold(tmp_path):
    config = BatchConfig(inputs=resolve_inputs(WORLD, str(MISSION)), n_iter=2, rtf="5", data_root=tmp_path,
                         stop_grace=3.0)
    results = {}
    batch = Batch(config, progress=False, out=io.StringIO(), on_simulation=lambda r: results.setdefault(r.id, r))
    outcome: dict = {}
    thread = threading.Thread(target=lambda: outcome.setdefault("batch", batch.run()), daemon=True)
    thread.start()
    tokens: set[str] = set()
    try:
        first = config.dataset_dir / "simulation_1" / "uav_1.csv"
        wait_until(lambda: csv_rows(first, "path") >= PATH_ROWS or results or not thread.is_alive(),
                   "UAV 1 of simulation 1 in flight", timeout=GUARD, poll=0.05)
        assert not results, f"simulation 1 ended before its fault: {results}"
        simulators = our_processes("__name:=magna_sim")
        assert len(simulators) == 1, simulators
        (pid, token), = simulators.items()
        tokens.add(token)
        os.kill(pid, signal.SIGKILL)
        thread.join(GUARD * 2)
        assert not thread.is_alive(), "the batch did not end"
    finally:
        if thread.is_alive():
            batch.stop.event.set()
            thread.join(120)
    crashed, after = results[1], results[2]
    assert crashed.termination == "crashed" and crashed.message.startswith("the simulator (magna_sim) died"), \
        crashed.message
    assert crashed.extra["stack"] == {"start": "cold", "index": 1}
    assert after.extra["stack"] == {"start": "cold", "index": 1}  # a fresh stack, not the broken one
    assert after.termination == "ground_station" and after.success, after.message
    assert [r.id for r in outcome["batch"].simulations] == [1, 2] and not outcome["batch"].interrupted
    assert not [p for token in tokens for p in tagged_processes(TOKEN_ENV, token)], "the first stack outlived it"
    assert our_processes("__name:=magna_sim") == {}
