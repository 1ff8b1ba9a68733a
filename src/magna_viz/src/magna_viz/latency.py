"""Command-to-motion latency in a recording, as the thesis's Experiment III measures it.

A command is an action state of one UAV (a leaf of the state-machine timeline whose class ends in
"ActionState" and whose label names a UAV) becoming active while that UAV hovers or rests: its speed
at that moment, the newest velocity sample at or before it, is below `hover_speed`. Its latency is
the simulated time from that moment to the first velocity sample after it whose speed exceeds
`threshold` (0.05 m/s, as bench/command_latency.py uses), within the state's active interval. A
state that began before the recording (its start is unknown) or while its UAV was already moving is
not a command from rest and is left out; one during which the UAV never moved has no latency.

The bag's velocities arrive at the simulator's 30 Hz, so a latency is known to one period (~33 ms);
the CSVs' 10 Hz would be coarser, and without a bag there is no timeline: no commands.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from magna_viz.recording import Recording

DEFAULT_THRESHOLD = 0.05  # m/s


@dataclass(frozen=True)
class CommandLatency:
    uav_id: int
    state: str  # the action state's path, e.g. "/MISSION/1_crossing/2_cross"
    command_time: float  # simulated s: the state became active
    speed_at_command: float  # m/s
    motion_time: float | None  # the first sample above the threshold; None if the UAV did not move in the state
    latency: float | None  # s, motion_time - command_time


def command_latencies(recording: Recording, threshold: float = DEFAULT_THRESHOLD,
                      hover_speed: float | None = None) -> list[CommandLatency]:
    """Every command from rest in the recording (module docstring), by time; `hover_speed` defaults to `threshold`."""
    if recording.timeline is None:
        return []
    hover = threshold if hover_speed is None else hover_speed
    out = []
    for interval in recording.timeline.intervals:
        uav = recording.uavs.get(interval.uav_id) if interval.uav_id is not None else None
        if uav is None or not interval.kind.endswith("ActionState") or interval.started_before:
            continue
        velocity = uav.velocity
        if not len(velocity):
            continue
        speed = velocity.norm()
        before = int(np.searchsorted(velocity.time, interval.start, side="right")) - 1
        if before < 0 or not speed[before] < hover:
            continue
        after = (velocity.time > interval.start) & (velocity.time <= interval.end) & (speed > threshold)
        hit = int(np.argmax(after)) if after.any() else None
        motion = float(velocity.time[hit]) if hit is not None else None
        out.append(CommandLatency(uav.id, interval.path, interval.start, float(speed[before]), motion,
                                  None if motion is None else motion - interval.start))
    return sorted(out, key=lambda c: (c.command_time, c.uav_id))


def latency_samples(latencies: list[CommandLatency], scale: float = 1000.0) -> dict[str, list[float]]:
    """The measured latencies per UAV ("UAV 1": [...]), times `scale` (default: milliseconds)."""
    out: dict[str, list[float]] = {}
    for c in sorted(latencies, key=lambda c: c.uav_id):
        if c.latency is not None and math.isfinite(c.latency):
            out.setdefault(f"UAV {c.uav_id}", []).append(c.latency * scale)
    return out


__all__ = ["DEFAULT_THRESHOLD", "CommandLatency", "command_latencies", "latency_samples"]
