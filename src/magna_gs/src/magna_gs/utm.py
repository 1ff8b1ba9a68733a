"""UTM flight plans: timed (4-D) waypoints per UAV, issued over simulated time, and the conflicts between them.

A UTM (UAS traffic management) service hands each UAV a flight plan and may change it in
flight; a mission's follow_path with `"path": "from utm"` flies the UAV's current plan, and a
change ends the follow_path the UAV is flying with the outcome `utm_new_flightplan`. This
module is the part without ROS: the plan file format (`parse_plan`, `load_plan`), the
schedule of plan issues and the current plans (`Utm`), and the conflict check between plans
(`find_conflicts`). The node (magna_gs.utm_node) resolves pose definitions through the world
node and publishes what this module decides.

Plan file (JSON), also accepted as the mission's top-level "UTM" object:

    {"flight_plans": [
        {"ids": [1], "at": 0.0, "waypoints": [[x, y, z], [x, y, z, t], ["Volume", "Geometry", "path", "Zigzag"]]},
        {"ids": [1], "at": 40.0, "waypoints": [[0, 0, 5]]}],
     "conflict": {"distance": 3.0, "time": 3.0},
     "speed": 2.0}

`at` is the simulated second (the simulation's clock) at which the plan is issued; a waypoint
is a position, a position with its planned time, or a pose definition [volume, geometry,
kind, arg] as missions write them. Waypoints without a time are planned at `speed` m/s from
the one before. Two plans conflict where their segments come within `distance` metres of each
other at planned times less than `time` seconds apart.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magna_gs.mission.model import FROM_UTM

DEFAULT_DISTANCE = 3.0  # m: closer than this, two plans may conflict
DEFAULT_TIME = 3.0  # s: ... when their planned times there are closer than this
DEFAULT_SPEED = 2.0  # m/s between waypoints without a planned time
TOP_KEYS = ("flight_plans", "conflict", "speed")
ENTRY_KEYS = ("ids", "at", "waypoints")
_EPS = 1e-12

FORMAT_HINT = ('a UTM plan is {"flight_plans": [{"ids": [1], "at": 0.0, "waypoints": [[x, y, z], ...]}, ...], '
               '"conflict": {"distance": 3, "time": 3}}')


class UtmPlanError(ValueError):
    """A plan that cannot be used; the message names the file, the JSON path and the fix."""


# --- the plan file ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Waypoint:
    """A position (with its planned time, if the plan gives one), or a pose definition to resolve."""

    position: tuple[float, float, float] | None = None
    time: float | None = None
    definition: tuple | None = None  # [volume, geometry, kind, arg]


@dataclass(frozen=True)
class PlanIssue:
    """One entry of "flight_plans": these UAVs get these waypoints at simulated time `at`."""

    ids: tuple[int, ...]
    at: float
    waypoints: tuple[Waypoint, ...]
    where: str  # "file: flight_plans[i]", for messages


@dataclass(frozen=True)
class ConflictLimits:
    distance: float = DEFAULT_DISTANCE
    time: float = DEFAULT_TIME


@dataclass(frozen=True)
class UtmPlan:
    source: str
    issues: tuple[PlanIssue, ...] = ()
    limits: ConflictLimits = ConflictLimits()
    speed: float = DEFAULT_SPEED


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _fail(source: str, path: str, message: str) -> UtmPlanError:
    return UtmPlanError(f"{source}: {path}: {message}")


def _waypoint(raw, source: str, path: str) -> Waypoint:
    if isinstance(raw, list) and raw and isinstance(raw[0], str):
        if len(raw) != 4 or not all(isinstance(v, str) for v in raw[:3]):
            raise _fail(source, path, f"a pose definition is [volume, geometry, kind, arg], got {json.dumps(raw)}; "
                                      f'e.g. ["Ground_Station", "volume", "coordinates", [[1, 2, 3], [0, 0, 0, 1]]]')
        return Waypoint(definition=tuple(raw))
    if isinstance(raw, list) and len(raw) in (3, 4) and all(_number(v) for v in raw):
        return Waypoint(position=(float(raw[0]), float(raw[1]), float(raw[2])),
                        time=float(raw[3]) if len(raw) == 4 else None)
    raise _fail(source, path, f"expected [x, y, z], [x, y, z, t] or a pose definition [volume, geometry, kind, arg], "
                              f"got {json.dumps(raw)}")


def _entry(raw, source: str, path: str) -> PlanIssue:
    if not isinstance(raw, dict):
        raise _fail(source, path, f'expected an object {{"ids": [1], "at": 0.0, "waypoints": [...]}}, got '
                                  f"{type(raw).__name__}")
    for key in raw:
        if key not in ENTRY_KEYS:
            raise _fail(source, f"{path}.{key}", f"unknown key; a flight plan has {', '.join(ENTRY_KEYS)}")
    ids = raw.get("ids")
    if isinstance(ids, int) and not isinstance(ids, bool):
        ids = [ids]
    if not isinstance(ids, list) or not ids or not all(isinstance(i, int) and not isinstance(i, bool) for i in ids):
        raise _fail(source, f"{path}.ids", f"expected the UAV ids the plan is for, e.g. [1], got {json.dumps(ids)}")
    at = raw.get("at", 0.0)
    if not _number(at) or at < 0:
        raise _fail(source, f"{path}.at", f"expected the simulated second the plan is issued at (0 or more), got "
                                          f"{json.dumps(at)}")
    waypoints = raw.get("waypoints")
    if not isinstance(waypoints, list) or not waypoints:
        raise _fail(source, f"{path}.waypoints", "expected a non-empty list of waypoints ([x, y, z], [x, y, z, t] "
                                                 "or [volume, geometry, kind, arg])")
    return PlanIssue(tuple(ids), float(at), tuple(_waypoint(w, source, f"{path}.waypoints[{i}]")
                                                 for i, w in enumerate(waypoints)), f"{source}: {path}")


def parse_plan(data, source: str) -> UtmPlan:
    """The plan read from parsed JSON; UtmPlanError names `source`, the JSON path and the fix."""
    if not isinstance(data, dict):
        raise UtmPlanError(f"{source}: the top level must be an object; {FORMAT_HINT}")
    for key in data:
        if key not in TOP_KEYS:
            raise _fail(source, str(key), f"unknown key; {FORMAT_HINT}")
    entries = data.get("flight_plans", [])
    if not isinstance(entries, list):
        raise _fail(source, "flight_plans", f"expected a list of flight plans; {FORMAT_HINT}")
    issues = [_entry(raw, source, f"flight_plans[{i}]") for i, raw in enumerate(entries)]
    conflict = data.get("conflict", {})
    if not isinstance(conflict, dict):
        raise _fail(source, "conflict", 'expected {"distance": metres, "time": seconds}')
    limits = {}
    for key, default in (("distance", DEFAULT_DISTANCE), ("time", DEFAULT_TIME)):
        value = conflict.get(key, default)
        if not _number(value) or value < 0:
            unit = "metres" if key == "distance" else "seconds"
            raise _fail(source, f"conflict.{key}", f"expected a number of {unit} (0 or more), got {json.dumps(value)}")
        limits[key] = float(value)
    for key in conflict:
        if key not in limits:
            raise _fail(source, f"conflict.{key}", 'unknown key; conflict has "distance" and "time"')
    speed = data.get("speed", DEFAULT_SPEED)
    if not _number(speed) or speed <= 0:
        raise _fail(source, "speed", f"expected the planning speed in m/s (more than 0), got {json.dumps(speed)}")
    # issued in time order; entries at the same time keep the file's order
    ordered = sorted(issues, key=lambda issue: issue.at)
    return UtmPlan(source, tuple(ordered), ConflictLimits(**limits), float(speed))


def load_plan(path: str | Path) -> UtmPlan:
    path = Path(path).expanduser()
    try:
        text = path.read_text()
    except OSError as error:
        raise UtmPlanError(f"{path}: cannot read the UTM plan ({error.strerror}); give an existing JSON file") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise UtmPlanError(f"{path}: line {error.lineno} column {error.colno}: not JSON ({error.msg}); "
                           f"{FORMAT_HINT}") from None
    return parse_plan(data, str(path))


def mission_plan(mission_data, mission_file: str | Path) -> UtmPlan | None:
    """The plan a mission carries in its top-level "UTM": the plan itself, or a file name (relative to the
    mission's folder); None when it has none."""
    if not isinstance(mission_data, dict) or "UTM" not in mission_data:
        return None
    section = mission_data["UTM"]
    if isinstance(section, str):
        return load_plan(Path(mission_file).expanduser().parent / section)
    return parse_plan(section, f"{mission_file}: UTM")


def mission_uses_utm(mission_data) -> bool:
    """Whether a mission (raw JSON) flies UTM plans: a "from utm" path or a "UTM" section. A transition on
    utm_new_flightplan alone does not count: many missions map that outcome, and without a plan it never comes."""
    if isinstance(mission_data, dict):
        if "UTM" in mission_data:
            return True
        if isinstance(mission_data.get("path"), str) and mission_data["path"].strip().lower() in FROM_UTM:
            return True
        return any(mission_uses_utm(v) for v in mission_data.values())
    if isinstance(mission_data, list):
        return any(mission_uses_utm(v) for v in mission_data)
    return False


# --- flight plans in time -----------------------------------------------------------------------
@dataclass(frozen=True)
class FlightPlan:
    """One UAV's plan: positions (n, 3) and their planned simulated times (n,)."""

    uav_id: int
    points: np.ndarray
    times: np.ndarray
    version: int = 0  # 0: a path the UAV flies of its own (filed); >= 1: issued by the UTM, counted per UAV
    issued_at: float = 0.0

    def as_json(self) -> dict:
        return {"version": self.version, "issued_at": self.issued_at,
                "waypoints": [[float(v) for v in p] for p in self.points], "times": [float(t) for t in self.times]}


def timed(points: Sequence, given_times: Sequence[float | None], start_time: float, speed: float,
          start: np.ndarray | None = None) -> np.ndarray:
    """Planned times of `points`: the given ones, the others at `speed` m/s from the point before (the first
    from `start`, where the UAV is, when known), never earlier than the point before."""
    positions = np.asarray(points, dtype=float).reshape(-1, 3)
    times = np.empty(len(positions))
    previous, now = (None if start is None else np.asarray(start, dtype=float)), float(start_time)
    for i, point in enumerate(positions):
        travel = 0.0 if previous is None else float(np.linalg.norm(point - previous)) / speed
        given = given_times[i] if i < len(given_times) else None
        now = max(now, float(given)) if given is not None else now + travel
        times[i] = now
        previous = point
    return times


# --- conflicts ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Conflict:
    """Two plans closer than the limits: UAVs, segment indices, closest points, distance, planned times there."""

    uav_ids: tuple[int, int]
    segments: tuple[int, int]
    points: tuple[np.ndarray, np.ndarray]
    distance: float
    times: tuple[float, float]

    @property
    def time_gap(self) -> float:
        return abs(self.times[0] - self.times[1])

    def describe(self) -> str:
        a, b = self.points
        return (f"UAVs {self.uav_ids[0]} and {self.uav_ids[1]}: {self.distance:.2f} m apart at t = "
                f"{self.times[0]:.1f} s / {self.times[1]:.1f} s (segments {self.segments[0]} and {self.segments[1]}, "
                f"near ({a[0]:.1f}, {a[1]:.1f}, {a[2]:.1f}) and ({b[0]:.1f}, {b[1]:.1f}, {b[2]:.1f}))")


def _clamp(value: float) -> float:
    return min(1.0, max(0.0, value))


def closest_parameters(a0, a1, b0, b1) -> tuple[float, float, bool]:
    """Parameters s, u in [0, 1] of the closest points a0 + s (a1 - a0) and b0 + u (b1 - b0) of two segments,
    and whether the segments are parallel (then the pair is one of many at the same distance). Zero-length
    segments are points."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    if a <= _EPS and e <= _EPS:
        return 0.0, 0.0, False
    if a <= _EPS:
        return 0.0, _clamp(f / e), False
    c = float(d1 @ r)
    if e <= _EPS:
        return _clamp(-c / a), 0.0, False
    b = float(d1 @ d2)
    denom = a * e - b * b
    parallel = denom <= 1e-9 * a * e
    s = 0.0 if parallel else _clamp((b * f - c * e) / denom)
    u = (b * s + f) / e
    if u < 0.0:
        u, s = 0.0, _clamp(-c / a)
    elif u > 1.0:
        u, s = 1.0, _clamp((b - c) / a)
    return s, u, parallel


def segment_conflict(a: tuple, b: tuple, limits: ConflictLimits) -> tuple[float, float, float, float] | None:
    """Closest approach of two timed segments, a = (a0, a1, ta0, ta1) and b likewise, as (s, u, distance,
    time gap), when it breaks both limits; None otherwise. Parallel segments side by side are close all
    along their overlap: the pair taken is the one whose planned times are nearest."""
    a0, a1, ta0, ta1 = a
    b0, b1, tb0, tb1 = b
    # the time gap at any pair of points is at least the gap between the segments' time windows
    if max(ta0, tb0) - min(ta1, tb1) > limits.time:
        return None
    s, u, parallel = closest_parameters(a0, a1, b0, b1)
    if parallel:
        d1, d2, r = a1 - a0, b1 - b0, a0 - b0
        e, b_, f = float(d2 @ d2), float(d1 @ d2), float(d2 @ r)
        # u(s) = (b s + f) / e is b's foot point for a's point s; overlap where both stay in [0, 1]
        lo, hi = sorted(((0.0 - f) / b_, (e - f) / b_))
        lo, hi = max(lo, 0.0), min(hi, 1.0)
        if lo <= hi:
            def gap_at(x: float) -> float:
                return (ta0 + x * (ta1 - ta0)) - (tb0 + (b_ * x + f) / e * (tb1 - tb0))
            g_lo, g_hi = gap_at(lo), gap_at(hi)
            if g_lo * g_hi <= 0.0 and g_lo != g_hi:  # the times meet inside the overlap
                s = lo + (hi - lo) * g_lo / (g_lo - g_hi)
            else:
                s = lo if abs(g_lo) <= abs(g_hi) else hi
            u = (b_ * s + f) / e
    pa, pb = a0 + s * (a1 - a0), b0 + u * (b1 - b0)
    distance = float(np.linalg.norm(pa - pb))
    gap = abs((ta0 + s * (ta1 - ta0)) - (tb0 + u * (tb1 - tb0)))
    if distance > limits.distance or gap > limits.time:
        return None
    return s, u, distance, gap


def _segments(plan: FlightPlan) -> list[tuple]:
    p, t = plan.points, plan.times
    if len(p) == 1:
        return [(p[0], p[0], t[0], t[0])]
    return [(p[i], p[i + 1], t[i], t[i + 1]) for i in range(len(p) - 1)]


def plan_conflicts(a: FlightPlan, b: FlightPlan, limits: ConflictLimits) -> list[Conflict]:
    found = []
    for i, sa in enumerate(_segments(a)):
        for j, sb in enumerate(_segments(b)):
            hit = segment_conflict(sa, sb, limits)
            if hit is None:
                continue
            s, u, distance, _ = hit
            pa, pb = sa[0] + s * (sa[1] - sa[0]), sb[0] + u * (sb[1] - sb[0])
            found.append(Conflict((a.uav_id, b.uav_id), (i, j), (pa, pb), distance,
                                  (sa[2] + s * (sa[3] - sa[2]), sb[2] + u * (sb[3] - sb[2]))))
    return found


def find_conflicts(plans: Iterable[FlightPlan], limits: ConflictLimits) -> list[Conflict]:
    """Every conflict between the plans of different UAVs."""
    plans = sorted(plans, key=lambda p: p.uav_id)
    found = []
    for k, a in enumerate(plans):
        for b in plans[k + 1:]:
            if a.uav_id != b.uav_id:
                found.extend(plan_conflicts(a, b, limits))
    return found


# --- the plans over time ------------------------------------------------------------------------
Resolver = Callable[[list], list[np.ndarray]]  # pose definition -> positions


@dataclass
class Utm:
    """The schedule of a plan and the UAVs' current plans: `due(now)` issues what is due, `file` records a
    path a UAV flies of its own, `conflicts()` checks the latest plan of every UAV against the others."""

    plan: UtmPlan
    issued: dict[int, FlightPlan] = field(default_factory=dict)  # the UTM's plans, what "from utm" flies
    filed: dict[int, FlightPlan] = field(default_factory=dict)  # paths the UAVs fly of their own
    next_issue: int = 0

    def due(self, now: float, resolve: Resolver, positions: dict[int, np.ndarray] | None = None
            ) -> list[FlightPlan]:
        """Issue every plan entry due at simulated time `now`; the new plans, one per UAV and entry.
        UtmPlanError (naming the entry) when a pose definition does not resolve; the entry is skipped."""
        changed = []
        while self.next_issue < len(self.plan.issues) and self.plan.issues[self.next_issue].at <= now:
            issue = self.plan.issues[self.next_issue]
            self.next_issue += 1
            points: list[tuple[float, float, float] | np.ndarray] = []
            given: list[float | None] = []
            for k, waypoint in enumerate(issue.waypoints):
                if waypoint.definition is None:
                    assert waypoint.position is not None  # _waypoint makes a position or a definition
                    points.append(waypoint.position)
                    given.append(waypoint.time)
                    continue
                try:
                    resolved = resolve(list(waypoint.definition))
                except ValueError as error:
                    raise UtmPlanError(f"{issue.where}.waypoints[{k}]: {error}; fix the pose definition") from None
                points.extend(resolved)
                given.extend([None] * len(resolved))
            for uav_id in issue.ids:
                start = (positions or {}).get(uav_id)
                times = timed(points, given, max(now, issue.at), self.plan.speed, start)
                old = self.issued.get(uav_id)
                plan = FlightPlan(uav_id, np.asarray(points, dtype=float).reshape(-1, 3), times,
                                  (old.version if old else 0) + 1, float(now))
                self.issued[uav_id] = plan
                changed.append(plan)
        return changed

    def file(self, uav_id: int, points, now: float, start: np.ndarray | None = None) -> FlightPlan:
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        plan = FlightPlan(uav_id, points, timed(points, [], now, self.plan.speed, start), 0, float(now))
        self.filed[uav_id] = plan
        return plan

    def latest(self) -> list[FlightPlan]:
        """Each UAV's newest plan, issued or filed."""
        ids = set(self.issued) | set(self.filed)
        newest = []
        for uav_id in sorted(ids):
            candidates = [p for p in (self.issued.get(uav_id), self.filed.get(uav_id)) if p is not None]
            newest.append(max(candidates, key=lambda p: p.issued_at))
        return newest

    def conflicts(self) -> list[Conflict]:
        return find_conflicts(self.latest(), self.plan.limits)

    def snapshot(self) -> dict:
        """What the ground station needs: every issued plan, by UAV id."""
        return {"plans": {str(i): p.as_json() for i, p in sorted(self.issued.items())}}


def choose_plan(plan_file: str | Path | None, mission_data, mission_file: str | Path) -> tuple[UtmPlan, str]:
    """The plan of a simulation and a warning ("" when there is nothing to say): the file given (utm_plan),
    else the mission's top-level "UTM", else no plan at all, said once when the mission flies UTM plans."""
    if plan_file:
        found = load_plan(plan_file)
        if isinstance(mission_data, dict) and "UTM" in mission_data:
            return found, (f"{mission_file}: UTM: replaced by the plan given to the run ({plan_file}); "
                           f"the mission's own plan is not flown")
        return found, ""
    from_mission = mission_plan(mission_data, mission_file)
    if from_mission is not None:
        return from_mission, ""
    warning = ""
    if mission_uses_utm(mission_data):
        warning = (f"{mission_file}: the mission flies UTM flight plans (a follow_path \"from utm\") but "
                   f"names no plan: the UTM issues none, checks the paths the UAVs fly for conflicts, and a "
                   f"follow_path \"from utm\" flies the UAV's last path again; give a plan with "
                   f"magna run --utm-plan FILE (utm_plan:=FILE of simulation.launch) or in the mission's "
                   f"top-level \"UTM\"")
    return UtmPlan("no plan"), warning
