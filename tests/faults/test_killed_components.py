"""Components killed or frozen in the middle of a mission (issue 26, items 1-3), on the real stack.

One batch of six simulations of a short two-UAV mission (tests/faults/missions: take off, an
out-and-back path each, land; a critical event takes the safety branch: hover, land) at 5x real time.
The test waits for each simulation to be in flight (its UAVs' CSVs, streamed as they fly, show rows
of the path) and then hits one process of that simulation, found by its pid among the processes
this test started:

1. UAV 2's manager SIGKILLed       -> the ground station notices it, UAV 1 takes the safety branch
2. UAV 2's manager SIGSTOPped      -> the same, for a frozen manager
3. the simulator (magna_sim) SIGKILLed -> the simulation ends as crashed, naming the simulator
4. the ground station SIGKILLed    -> the simulation ends as crashed, naming the ground station
5. the ground station SIGSTOPped   -> the Master's time limit ends it
6. nothing                         -> the batch goes on as usual

Detection is asserted on what result.json records (simulated time), never on a wall clock; the
wall-clock figures (how soon the supervisor heard of the simulator's death) are printed for
bench-style reading (`-s`). After every simulation no process carrying its token is left.
"""
from __future__ import annotations

import csv
import datetime
import io
import os
import signal
import threading
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from magna_common.processes import TOKEN_ENV, ancestors, tagged_processes
from magna_common.simulation_bag import read_simulation_bag
from magna_gs.inputs import resolve_inputs
from magna_master.batch import Batch
from magna_master.batch_config import BatchConfig
from magna_uav.recorder import read_csv
from tests.support import wait_until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(900)]

MISSION = Path(__file__).resolve().parent / "missions" / "Faults" / "2UAVs_Out_And_Back.json"
WORLD = "Gym/Central_Obstacle_Torus"
PATH_ROWS = 10  # rows of the path role (1 simulated s at 10 Hz) before a fault: the UAVs are in flight
GUARD = 240.0  # wall s: a guard against hangs while waiting for a simulation, never a performance figure
TIME_LIMIT = 600.0  # wall s, the batch's usual limit
# The limit of the simulation whose ground station is frozen: long enough to reach the flight on a
# loaded machine, and what that simulation costs.
FREEZE_LIMIT = 35.0
MANAGER_DETECTION = 2.0  # simulated s: the bound from a manager's death to the ground station's notice


@dataclass
class Simulation:
    """What the test saw and did in one simulation."""

    number: int
    tokens: set[str] = field(default_factory=set)
    fault_pid: int | None = None
    fault_wall: datetime.datetime | None = None  # when the signal was sent (UTC)
    rows_at_fault: dict[int, int] = field(default_factory=dict)  # UAV id: rows in its CSV just before
    orphans: list[tuple[int, str]] | None = None  # tagged processes alive once the batch moved on


def environment(pid: int) -> dict[str, str]:
    try:
        raw = Path(f"/proc/{pid}/environ").read_bytes()
    except OSError:
        return {}
    pairs = (item.split(b"=", 1) for item in raw.split(b"\0") if b"=" in item)
    return {k.decode(errors="replace"): v.decode(errors="replace") for k, v in pairs}


def simulation_processes(sim_dir: Path) -> dict[int, tuple[str, str]]:
    """{pid: (command line, token)} of the live processes of the simulation in `sim_dir` that this test started:
    they carry a simulation token, log under its folder (its ROS master's ROS_LOG_DIR) and descend from us."""
    me, found = os.getpid(), {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        env = environment(int(entry.name))
        if TOKEN_ENV not in env or not env.get("ROS_LOG_DIR", "").startswith(str(sim_dir)):
            continue
        if me not in ancestors(int(entry.name)):
            continue
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        found[int(entry.name)] = (command, env[TOKEN_ENV])
    return found


def csv_rows(path: Path, role: str | None = None) -> int:
    """Rows (of one role) in a CSV a manager is streaming; 0 before it exists."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return 0
    return sum(1 for row in csv.DictReader(io.StringIO(text)) if role is None or row.get("role") == role)


class FaultDrill:
    def __init__(self, tmp_path: Path):
        inputs = resolve_inputs(WORLD, str(MISSION))
        # One process per UAV manager: the drill kills and freezes UAV 2's alone (in a host, a thread). A cold
        # start each: the drill finds each simulation's processes by the logs they keep in its folder.
        self.config = BatchConfig(inputs=inputs, n_iter=6, rtf="5", data_root=tmp_path, time_limit=TIME_LIMIT,
                                  stop_grace=3.0, managers="process", cold_start=True)
        self.dataset = self.config.dataset_dir
        self.simulations = {m: Simulation(m) for m in range(1, 7)}
        self.results = {}
        self.batch = Batch(self.config, progress=False, out=io.StringIO(), on_simulation=self._ended)
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.error: BaseException | None = None
        self.finished = None

    def _run(self) -> None:
        try:
            self.finished = self.batch.run()
        except BaseException as error:  # reported by the test
            self.error = error

    def _ended(self, result) -> None:
        """After each simulation (the batch's thread): no orphan, and the next one's time limit."""
        simulation = self.simulations[result.id]
        self.results[result.id] = result
        simulation.orphans = [p for token in simulation.tokens for p in tagged_processes(TOKEN_ENV, token)]
        # Only the simulation with the frozen ground station waits for a time limit; the others get the usual one.
        self.config.time_limit = FREEZE_LIMIT if result.id == 4 else TIME_LIMIT

    def sim_dir(self, m: int) -> Path:
        return self.dataset / f"simulation_{m}"

    def in_flight(self, m: int, uav_id: int) -> None:
        """Wait until UAV `uav_id` of simulation m has flown PATH_ROWS steps of its path."""
        csv_path = self.sim_dir(m) / f"uav_{uav_id}.csv"
        wait_until(lambda: csv_rows(csv_path, "path") >= PATH_ROWS or self._over(m),
                   f"UAV {uav_id} of simulation {m} in flight", timeout=GUARD, poll=0.05)
        assert not self._over(m), f"simulation {m} ended before its fault: {self.results.get(m)}"

    def _over(self, m: int) -> bool:
        return m in self.results or self.error is not None or not self.thread.is_alive()

    def hit(self, m: int, marker: str, sig: signal.Signals) -> int:
        """Send `sig` to the process of simulation m whose command line holds `marker`."""
        processes = simulation_processes(self.sim_dir(m))
        simulation = self.simulations[m]
        simulation.tokens |= {token for _, token in processes.values()}
        pids = [pid for pid, (command, _) in processes.items() if marker in command.split()]
        assert len(pids) == 1, f"simulation {m}: one process with {marker}, found {processes}"
        simulation.rows_at_fault = {u: csv_rows(self.sim_dir(m) / f"uav_{u}.csv") for u in (1, 2)}
        simulation.fault_pid, simulation.fault_wall = pids[0], datetime.datetime.now(datetime.UTC)
        os.kill(pids[0], sig)
        return pids[0]

    def note_tokens(self, m: int) -> None:
        self.simulations[m].tokens |= {token for _, token in simulation_processes(self.sim_dir(m)).values()}

    def stop(self) -> None:
        """Whatever happened: end the batch, and any process this test froze."""
        if self.thread.is_alive():
            self.batch.stop.event.set()
            self.thread.join(120)
        for simulation in self.simulations.values():
            for token in simulation.tokens:
                for pid, _ in tagged_processes(TOKEN_ENV, token):
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass


def manager_lost_event(result, uav_id: int) -> dict:
    events = [e for e in result.extra.get("critical_events", []) if e["event"] == "manager_lost"]
    assert [e["uav"] for e in events] == [uav_id], result.extra.get("critical_events")
    return events[0]


def roles_in_order(rows: list[dict]) -> list[str]:
    return list(dict.fromkeys(row["role"] for row in rows))


def check_lost_manager(drill: FaultDrill, m: int, cause: str) -> dict:
    """Simulation m lost UAV 2's manager: noticed in time, UAV 1 in the safety branch, UAV 2's rows kept."""
    result = drill.results[m]
    sim_dir = drill.sim_dir(m)
    assert result.termination == "ground_station" and result.outcome == "completed", result.message
    assert result.success is False, result.message
    event = manager_lost_event(result, 2)
    assert cause in event["detail"], event
    assert "UAV 2 manager_lost at" in result.message, result.message
    # UAV 2's CSV is what it streamed until the fault: readable, every row it had then, none after the notice
    _, lost_rows = read_csv(sim_dir / "uav_2.csv")
    assert len(lost_rows) >= drill.simulations[m].rows_at_fault[2] >= PATH_ROWS
    last_beat_before = lost_rows[-1]["time"]  # it was alive at its last row: the fault came later
    detection = event["sim_time"] - last_beat_before
    assert 0 < detection <= MANAGER_DETECTION, (event, last_beat_before)
    # UAV 1 heard the critical event in its path and took the safety branch
    _, rows = read_csv(sim_dir / "uav_1.csv")
    ended = [row for row in rows if row["role"] == "path" and row["outcome"]]
    assert [row["outcome"] for row in ended] == ["GS_critical_event"], ended
    assert ended[0]["time"] >= event["sim_time"] - 0.5  # it ended on this event, not before it
    assert roles_in_order(rows) == ["take_off", "path", "basic_move", "land"], roles_in_order(rows)
    return {"detection": detection, "rows": len(lost_rows), "noticed": event["sim_time"]}


def check_data_kept(drill: FaultDrill, m: int) -> dict[int, int]:
    """The UAVs' CSVs read back whole, with at least the rows there were at the fault; the bag reads."""
    kept = {}
    for uav_id in (1, 2):
        _, rows = read_csv(drill.sim_dir(m) / f"uav_{uav_id}.csv")
        assert len(rows) >= drill.simulations[m].rows_at_fault[uav_id] >= 1, (m, uav_id)
        kept[uav_id] = len(rows)
    bag = read_simulation_bag(drill.sim_dir(m) / "simulation.bag", kinds=("pose",))
    assert bag.uav_ids() == [1, 2] and bag.messages.get("pose"), f"simulation {m}: the bag holds no poses"
    return kept


def test_killed_and_frozen_components_end_as_stated_and_the_batch_goes_on(tmp_path):
    drill = FaultDrill(tmp_path)
    drill.thread.start()
    try:
        drill.in_flight(1, 2)
        drill.hit(1, "__name:=uav_2_manager", signal.SIGKILL)
        drill.in_flight(2, 2)
        drill.hit(2, "__name:=uav_2_manager", signal.SIGSTOP)
        drill.in_flight(3, 1)
        drill.hit(3, "__name:=magna_sim", signal.SIGKILL)
        drill.in_flight(4, 1)
        drill.hit(4, "__name:=ground_station", signal.SIGKILL)
        drill.in_flight(5, 1)
        drill.hit(5, "__name:=ground_station", signal.SIGSTOP)
        drill.in_flight(6, 1)
        drill.note_tokens(6)
        drill.thread.join(GUARD * 2)
        assert not drill.thread.is_alive(), "the batch did not end"
    finally:
        drill.stop()
    assert drill.error is None, drill.error
    figures = {}

    # 1, 2: a manager killed, then one frozen
    figures["manager SIGKILL"] = check_lost_manager(drill, 1, "killed by SIGKILL")
    figures["manager SIGSTOP"] = check_lost_manager(drill, 2, "stopped")

    # 3: the simulator killed: a crash naming it, noticed by the supervisor from roslaunch's report
    result = drill.results[3]
    assert result.termination == "crashed" and result.success is False, result.message
    assert result.message.startswith("the simulator (magna_sim) died"), result.message
    died = result.extra["died"]
    assert died["node"] == "magna_sim" and died["exit_code"] == -signal.SIGKILL, died
    latency = (datetime.datetime.fromisoformat(died["noticed_at"]) - drill.simulations[3].fault_wall).total_seconds()
    figures["simulator SIGKILL"] = {"noticed after (wall s)": latency, "kept": check_data_kept(drill, 3)}

    # 4: the ground station killed: the same, naming it
    result = drill.results[4]
    assert result.termination == "crashed" and result.message.startswith("the ground station died"), result.message
    assert result.extra["died"]["node"] == "ground_station"
    figures["ground station SIGKILL"] = {"kept": check_data_kept(drill, 4), "wall": result.wall_time}

    # 5: the ground station frozen: the Master's time limit ends it
    result = drill.results[5]
    assert result.termination == "time_limit" and result.timed_out and not result.reported, result.message
    assert result.time_limit == FREEZE_LIMIT
    figures["ground station SIGSTOP"] = {"kept": check_data_kept(drill, 5), "wall": result.wall_time}

    # 6: the batch went on as usual
    result = drill.results[6]
    assert result.success is True and result.termination == "ground_station", result.message
    assert result.extra["critical_events"] == []

    summary = list(csv.DictReader((drill.dataset / "summary.csv").open()))
    assert [row["id"] for row in summary] == ["1", "2", "3", "4", "5", "6"]
    for simulation in drill.simulations.values():
        assert simulation.tokens, f"simulation {simulation.number}: none of its processes was seen"
        assert simulation.orphans == [], f"simulation {simulation.number} left {simulation.orphans}"
    for name, figure in figures.items():
        print(f"fault figure: {name}: {figure}")
