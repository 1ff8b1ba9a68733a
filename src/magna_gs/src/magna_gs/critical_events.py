"""The critical events of a mission, as the ground station keeps them and reports them to the Master.

A UAV manager reports its own (collision, low_battery, pilot_takeover); the ground station adds those
it notices itself: a MAVLink link lost, a UAV manager lost (magna_common.liveness). Each has the
simulated time the ground station heard of it. They end up in result.json ("critical_events", sent to the
Master in the SimulationTermination request) and, in words, in its message.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class CriticalEvent:
    uav_id: int
    event: str  # collision, low_battery, pilot_takeover, link_lost, manager_lost, ...
    sim_time: float  # simulated s when the ground station heard of it
    detail: str = ""

    def describe(self) -> str:
        return f"UAV {self.uav_id} {self.event} at {self.sim_time:.2f} s" + (f" ({self.detail})" if self.detail else "")


def describe_all(events: Iterable[CriticalEvent]) -> str:
    return ", ".join(event.describe() for event in events)
