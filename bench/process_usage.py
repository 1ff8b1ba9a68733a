"""CPU seconds and memory of a process tree, by kind of MAGNA process, sampled from /proc (no psutil).

Every --period seconds (default 0.5) the processes descending from the root process (found by walking
the parent pid in /proc/*/stat) are read: user + system CPU time from /proc/PID/stat, the resident set
from /proc/PID/statm. Each process is put in a kind by its command line (read again each time: rosrun
execs its node in the same process): the simulator, the world node, ORCA-3D, the ground station, the
UAV managers (one host or one process each), rosbag, the supervisor or stack server, the ROS master,
roslaunch, and so on. A process's CPU is its last reading, so up to one period of a process that
exits between two samples is missed.

Used by bench/mission_batch.py for its 10- and 50-UAV runs; on its own it runs a command and prints
the figures of its tree, by default one simulation of `make run`'s mission (2 UAVs, bags on, rtf max,
into a temporary data root, removed):

    python bench/process_usage.py [--period 0.5] [--uavs N] [-- ./magna run --world ... --mission ...]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
PAGE_BYTES = os.sysconf("SC_PAGE_SIZE")

ROOT_KIND = "magna run (batch, reports)"
MAGNA = Path(__file__).resolve().parents[1] / "magna"
DEFAULT_RUN = ["run", "--world", "Gym/Central_Obstacle_Torus", "--mission", "Gym/2UAVs_Crossing_ORCA", "--rtf", "max"]
# (a piece of the command line, its kind), first match wins; a process keeps the kind of its last reading
KINDS = [
    ("catkin_find", "rosrun start-up"),
    ("/rosrun ", "rosrun start-up"),  # until it execs the node
    ("rosmaster", "master"),
    ("magna_master.stack_server", "supervisor / stack server"),
    ("magna_master.supervisor", "supervisor / stack server"),
    ("roslaunch", "roslaunch"),
    ("__name:=magna_sim", "sim"),
    ("magna_sim/sim", "sim"),
    ("__name:=magna_world", "world"),
    ("magna_worlds/world", "world"),
    ("orca3d_server", "orca"),
    # a warm start (magna_common.warm_start) keeps the command line it was prepared with: the modules it imported
    ("warm_start magna_gs", "ground station"),
    ("warm_start magna_uav", "managers (host or processes)"),
    ("ground_station", "ground station"),
    ("uav_manager", "managers (host or processes)"),
    ("rosbag/record", "rosbag"),
    ("rosbag record", "rosbag"),
    ("__name:=utm", "utm"),
    ("dot -T", "reports (graphviz)"),
]


def kind_of(cmdline: str) -> str:
    for piece, kind in KINDS:
        if piece in cmdline:
            return kind
    words = cmdline.split()
    if words and os.path.basename(words[0]).startswith("python") and len(words) > 1:
        words = words[1:]  # a Python script: name the script
    return f"other ({os.path.basename(words[0])})" if words else "other"


def _read(path: str) -> str | None:
    try:
        with open(path, "rb") as f:
            return f.read().decode(errors="replace")
    except OSError:  # the process ended meanwhile
        return None


def _stat_fields(pid: int) -> list[str] | None:
    """/proc/PID/stat after the command name (which may hold spaces and parentheses): state, ppid, ..."""
    text = _read(f"/proc/{pid}/stat")
    return text[text.rindex(")") + 2:].split() if text else None


def descendants(root: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            fields = _stat_fields(int(entry))
            if fields:
                children.setdefault(int(fields[1]), []).append(int(entry))
    found, todo = [], [root]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


@dataclass
class Sample:
    at: float  # monotonic s
    rss: dict[str, int] = field(default_factory=dict)  # bytes by kind, the root left out

    @property
    def total_rss(self) -> int:
        return sum(self.rss.values())


@dataclass
class Usage:
    """What the sampler saw of one tree."""

    cpu_s: dict[str, float] = field(default_factory=dict)  # CPU s by kind, the root's included
    processes: dict[str, int] = field(default_factory=dict)  # distinct processes by kind
    peak: Sample | None = None  # the sample with the largest resident total (the root's left out)
    samples: int = 0
    wall_s: float = 0.0

    @property
    def total_cpu_s(self) -> float:
        return sum(self.cpu_s.values())


class ProcessSampler:
    """Samples the tree under `root` in a thread of its own while the `with` block runs."""

    def __init__(self, root: int, period: float = 0.5):
        self.root, self.period = root, period
        self._ticks: dict[int, tuple[str, int]] = {}  # pid -> (kind, CPU ticks at its last reading)
        self._peak: Sample | None = None
        self._samples = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._started = 0.0
        self._wall = 0.0

    def __enter__(self) -> ProcessSampler:
        self._started = time.monotonic()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        self._wall = time.monotonic() - self._started

    def _loop(self) -> None:
        while True:
            self.sample()
            if self._stop.wait(self.period):
                return

    def sample(self) -> None:
        now = Sample(time.monotonic())
        for pid in [self.root, *descendants(self.root)]:
            fields, cmdline, statm = _stat_fields(pid), _read(f"/proc/{pid}/cmdline"), _read(f"/proc/{pid}/statm")
            if fields is None or cmdline is None or statm is None:
                continue
            if fields[0] == "Z":  # a zombie's times are final; its last reading stands
                continue
            kind = ROOT_KIND if pid == self.root else kind_of(cmdline.replace("\0", " "))
            ticks = int(fields[11]) + int(fields[12])  # utime + stime
            self._ticks[pid] = (kind, ticks)
            if pid != self.root:
                now.rss[kind] = now.rss.get(kind, 0) + int(statm.split()[1]) * PAGE_BYTES
        self._samples += 1
        if self._peak is None or now.total_rss > self._peak.total_rss:
            self._peak = now

    def usage(self) -> Usage:
        result = Usage(peak=self._peak, samples=self._samples, wall_s=self._wall)
        for kind, ticks in self._ticks.values():
            result.cpu_s[kind] = result.cpu_s.get(kind, 0.0) + ticks / CLOCK_TICKS
            result.processes[kind] = result.processes.get(kind, 0) + 1
        return result


def print_usage(usage: Usage, uavs: int | None = None, simulations: int = 1, indent: str = "   ") -> None:
    """CPU s by kind (per simulation when there were several) and the resident memory at the peak."""
    peak = usage.peak
    per = f" per simulation (of {simulations})" if simulations > 1 else ""
    print(f"{indent}{'process kind':32} {'procs':>5} {'CPU s' + per:>{10 + len(per)}} {'CPU %':>6} "
          f"{'RSS MB at peak':>14}")
    total = usage.total_cpu_s or 1.0
    kinds = sorted(set(usage.cpu_s) | set(peak.rss if peak else {}), key=lambda k: -usage.cpu_s.get(k, 0.0))
    for kind in kinds:
        rss = peak.rss.get(kind, 0) / 1e6 if peak else 0.0
        print(f"{indent}{kind:32} {usage.processes.get(kind, 0):>5} "
              f"{usage.cpu_s.get(kind, 0.0) / simulations:>{10 + len(per)}.1f} "
              f"{100 * usage.cpu_s.get(kind, 0.0) / total:>5.0f}% {rss:>14.0f}")
    cores = usage.total_cpu_s / usage.wall_s if usage.wall_s > 0 else float("nan")
    print(f"{indent}{'all':32} {sum(usage.processes.values()):>5} "
          f"{usage.total_cpu_s / simulations:>{10 + len(per)}.1f} {'':>6} "
          f"{(peak.total_rss / 1e6 if peak else 0.0):>14.0f}   ({cores:.2f} cores busy over {usage.wall_s:.0f} wall s, "
          f"{usage.samples} samples; RSS without the `magna run` process itself)")
    if uavs and peak:
        print(f"{indent}memory per UAV: {peak.total_rss / 1e6 / uavs:.0f} MB (resident sum of the simulation's "
              f"processes at its peak / {uavs} UAVs)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python bench/process_usage.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--period", type=float, default=0.5, help="wall seconds between samples (default 0.5)")
    parser.add_argument("--uavs", type=int, default=0,
                        help="divide the peak memory by this many UAVs (default: 2 for the default command)")
    parser.add_argument("command", nargs=argparse.REMAINDER,
                        help="the command to run and sample, after -- (default: one simulation of the default "
                             "mission with ./magna run)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    with tempfile.TemporaryDirectory(prefix="process_usage_") as data_root:
        if not command:
            command = [str(MAGNA), *DEFAULT_RUN, "--data-root", data_root]
            args.uavs = args.uavs or 2
        print(f"sampling every {args.period:g} s: {' '.join(command)}", flush=True)
        process = subprocess.Popen(command)
        with ProcessSampler(process.pid, args.period) as sampler:
            code = process.wait()
    print_usage(sampler.usage(), args.uavs or None)
    return code


if __name__ == "__main__":
    sys.exit(main())
