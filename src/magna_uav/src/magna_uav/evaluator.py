"""The evaluator: at every control step, is this UAV still safe to carry on?

It measures the gap between our safety sphere and every other UAV's, and between our safety
sphere and every obstacle's real shape (the signed distance from our centre to its surface
minus our safety radius: a wire is as thin as it is, not its bounding sphere), as WorldView
gives them, and turns what it finds into an action outcome:

    collision          a gap below zero (closer than the two radii), naming who or what
    aborted            our position is outside the world boundaries
    GS_critical_event  the ground station raised a critical event
    low_battery        the battery fraction is known and below the threshold

in that priority. Collisions and boundary exits are counted once per episode: an episode
starts when the gap goes below zero (or the UAV leaves the boundaries) and ends only once
the gap is back above `release_gap` (or the UAV is back inside), so a gap that flickers
around zero is one contact, not one per step.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

from magna_uav.config import UavConfig
from magna_uav.world_view import WorldView

COLLISION = "collision"
ABORTED = "aborted"
GS_CRITICAL = "GS_critical_event"
LOW_BATTERY = "low_battery"
OUTCOME_PRIORITY = (COLLISION, ABORTED, GS_CRITICAL, LOW_BATTERY)


def agent_name(agent_id: int) -> str:
    return f"uav_{agent_id}"


@dataclass(frozen=True)
class Evaluation:
    """What one control step found; `outcome` is None while it is safe to carry on."""

    agent_gaps: dict[int, float] = field(default_factory=dict)  # other UAV id -> gap between safety spheres, m
    obstacle_gaps: dict[str, float] = field(default_factory=dict)  # obstacle name -> gap to its surface, m
    nearest_agent_gap: float = math.inf
    nearest_obstacle_gap: float = math.inf
    collided_with: list[str] = field(default_factory=list)  # "uav_2", obstacle names; nearest first
    # contact episodes still open: collided_with, and those whose gap has not yet opened past release_gap
    in_contact: list[str] = field(default_factory=list)
    out_of_bounds: bool = False
    low_battery: bool = False
    gs_critical: bool = False
    battery: float = math.nan  # own battery fraction, NaN when unknown
    outcome: str | None = None  # one of OUTCOME_PRIORITY
    reason: str = ""

    @property
    def safe(self) -> bool:
        return self.outcome is None


class Evaluator:
    """One per UAV manager; call `step` once per control step."""

    def __init__(self, config: UavConfig, low_battery: float = 0.15, release_gap: float = 0.05):
        if not 0.0 <= low_battery <= 1.0:
            raise ValueError(f"low_battery: {low_battery!r} is not a battery fraction; give a value in 0..1 "
                             f"(0.15 means 15 %)")
        if not release_gap >= 0.0:
            raise ValueError(f"release_gap: {release_gap!r} must be 0 or more metres")
        self.config = config
        self.low_battery_threshold = float(low_battery)
        self.release_gap = float(release_gap)
        self.reset()

    def reset(self) -> None:
        """Forget counters and open episodes (a new simulation)."""
        self.steps = 0
        self.collisions: Counter[str] = Counter()  # contact episodes per UAV / obstacle name
        self.out_of_bounds_episodes = 0
        self.min_agent_gap = math.inf  # smallest gap seen so far
        self.min_obstacle_gap = math.inf
        self._in_contact: set[str] = set()
        self._was_out = False

    @property
    def collision_count(self) -> int:
        """Contact episodes so far, with any UAV or obstacle."""
        return sum(self.collisions.values())

    def step(self, view: WorldView, gs_critical_event: bool = False) -> Evaluation:
        if view.own_id != self.config.id:
            raise ValueError(f"the evaluator of {self.config.name} was given the world view of "
                             f"{agent_name(view.own_id)}")
        self.steps += 1
        if not view.has_own:  # nothing to measure before our first pose
            outcome = GS_CRITICAL if gs_critical_event else None
            reason = "ground station critical event" if gs_critical_event else ""
            return Evaluation(gs_critical=gs_critical_event, outcome=outcome,
                              reason=reason or f"no pose of {self.config.name} yet")

        agent_gaps = {agent.id: gap for agent, gap in view.nearest_agents()}
        obstacle_gaps: dict[str, float] = {}
        for obstacle, gap in view.nearest_obstacles():
            obstacle_gaps.setdefault(obstacle.name, gap)  # nearest first: a repeated name keeps its smallest gap
        nearest_agent = min(agent_gaps.values(), default=math.inf)
        nearest_obstacle = min(obstacle_gaps.values(), default=math.inf)
        self.min_agent_gap = min(self.min_agent_gap, nearest_agent)
        self.min_obstacle_gap = min(self.min_obstacle_gap, nearest_obstacle)

        gaps = {agent_name(i): g for i, g in agent_gaps.items()} | obstacle_gaps
        collided = sorted((name for name, gap in gaps.items() if gap < 0.0), key=lambda n: (gaps[n], n))
        self._count_contacts(gaps, collided)

        out = not view.inside_boundaries()
        if out and not self._was_out:
            self.out_of_bounds_episodes += 1
        self._was_out = out

        battery = float(view.own.battery)
        low = not math.isnan(battery) and battery < self.low_battery_threshold

        found = []  # (outcome, text) in priority order
        if collided:
            found.append((COLLISION, "collision with " + ", ".join(f"{n} (gap {gaps[n]:.2f} m)" for n in collided)))
        if out:
            x, y, z = view.own.position
            found.append((ABORTED, f"out of the world boundaries at ({x:.2f}, {y:.2f}, {z:.2f})"))
        if gs_critical_event:
            found.append((GS_CRITICAL, "ground station critical event"))
        if low:
            found.append((LOW_BATTERY, f"low battery {battery:.0%} < {self.low_battery_threshold:.0%}"))
        outcome = found[0][0] if found else None
        reason = "; ".join(text for _, text in found)

        return Evaluation(agent_gaps=agent_gaps, obstacle_gaps=obstacle_gaps, nearest_agent_gap=nearest_agent,
                          nearest_obstacle_gap=nearest_obstacle, collided_with=collided,
                          in_contact=sorted(self._in_contact), out_of_bounds=out,
                          low_battery=low, gs_critical=gs_critical_event, battery=battery, outcome=outcome,
                          reason=reason)

    def _count_contacts(self, gaps: dict[str, float], collided: list[str]) -> None:
        for name in collided:
            if name not in self._in_contact:
                self._in_contact.add(name)
                self.collisions[name] += 1
        # an episode ends once the gap is clearly open again, or the other one is gone from the view
        self._in_contact = {n for n in self._in_contact if n in gaps and gaps[n] <= self.release_gap}
