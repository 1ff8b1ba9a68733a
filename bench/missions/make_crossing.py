"""Write an N-UAV crossing mission with ORCA-3D throughout, for bench/mission_batch.py.

The UAVs stand on pads in rows of a ground-station volume (2 m apart by default). They take off
together, fly each to its own point on a ring round a central zone (neighbours on the ring at
different altitudes, in turn), then each crosses to the opposite point of the ring at its altitude
and flies home above its pad, and all land. ORCA-3D is on for every UAV from the start. A collision
or a failed leg takes the safety branch (hover, save the CSVs, land), as in the project's missions.

Two shapes, chosen by --uavs (every value can be overridden):
  up to 10 UAVs   the world Gym/Central_Obstacle_Torus (worlds/): a ring of 8 m at 5.5 / 6.5 m,
                  take-off to 3 m, home at 3 m; `--uavs 10` writes bench/missions/Gym/10UAVs_Crossing_ORCA.json
                  as it is;
  more            the world Gym/Big_Crossing (bench/worlds/, 120 x 120 x 30 m, one central obstacle
                  4 m high, 50 pads): a ring of N * 5 m / (2 pi) (40 m for 50), in four layers at
                  8 / 10.5 / 13 / 15.5 m, take-off to 5 m, home at 5 m. In two layers 25 UAVs met
                  at the centre in each, and ORCA-3D let two of them touch (gap -0.01 to -0.02 m) in
                  both runs tried, with 5 or 10 neighbours; four layers of 12 or 13 fly it with none.
                  A number of layers that divides N / 2 is refused: a UAV and the one crossing the
                  other way from the opposite point would meet head-on in the same layer.

Each leg's time limit is 100 s, or three times its longest leg at ORCA's maxSpeed when that is
longer. The mission is loaded and checked against its world (every place inside the world
boundaries, pads far enough apart) before it is written; a mission that fails the check is not
written. An existing file is replaced only with --force.

    python bench/missions/make_crossing.py --uavs 50 --force     # bench/missions/Gym/50UAVs_Crossing_ORCA.json
    python bench/missions/make_crossing.py --uavs 10 -o /tmp/10.json
    ./magna run --search-path bench --world Gym/Big_Crossing --mission Gym/50UAVs_Crossing_ORCA --rtf max
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

if __name__ == "__main__":  # runs in the workspace from any Python (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[2] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("magna_gs", "magna_worlds"))

BENCH = Path(__file__).resolve().parents[1]
PAD_VOLUME, RING_VOLUME = "Ground_Station", "CentralZone"
PAD_HEIGHT = 0.05  # m: a pad's spawn height in its volume
SPAWN_YAW = 1.570796
COLORS = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [255, 0, 255], [0, 255, 255], [255, 128, 0],
          [128, 0, 255], [0, 128, 128], [128, 128, 128]]
ORCA_PARAMS = ["N_neighbors_aware", "timeStep", "neighborDist", "timeHorizon", "agent_radius", "maxSpeed"]
MIN_LEG_TIME = 100.0  # s
RING_GAP = 5.0  # m between neighbours on the ring of a big crossing
BIG_LAYERS = (8.0, 10.5, 13.0, 15.5)  # m: the altitudes of a big crossing, in turn round the ring


@dataclass(frozen=True)
class Crossing:
    uavs: int
    world: str  # WORLD/SUBWORLD, looked up with bench/ first
    ring_radius: float  # m, round the ring volume's origin
    altitudes: tuple[float, ...]  # m in the ring volume: UAV k (from 0) at altitudes[k % len(altitudes)]
    take_off: float  # m above the pad
    home: float  # m in the pad volume
    rows: int = 2
    pad_spacing: float = 2.0  # m between pads, along and across the rows
    neighbors: int = 5  # ORCA-3D's N_neighbors_aware
    max_speed: float = 2.0  # m/s, ORCA-3D's maxSpeed

    @property
    def columns(self) -> int:
        return math.ceil(self.uavs / self.rows)


def default_crossing(uavs: int) -> Crossing:
    if uavs <= 10:
        return Crossing(uavs, "Gym/Central_Obstacle_Torus", 8.0, (5.5, 6.5), 3.0, 3.0)
    return Crossing(uavs, "Gym/Big_Crossing", float(round(uavs * RING_GAP / (2 * math.pi))), BIG_LAYERS, 5.0, 5.0)


def pads(c: Crossing) -> list[tuple[float, float]]:
    """(x, y) of each UAV's pad in the pad volume: rows centred on x, the first at y = 0, the next behind it."""
    out = []
    for index in range(c.uavs):
        row, column = divmod(index, c.columns)
        out.append((_round((column - (c.columns - 1) / 2) * c.pad_spacing), _round(-row * c.pad_spacing)))
    return out


def ring_point(c: Crossing, index: int, opposite: bool = False) -> list[float]:
    """UAV `index`'s point on the ring (the first due south of the centre), or the opposite one, at its altitude."""
    angle = math.radians(-90.0 + 360.0 * index / c.uavs + (180.0 if opposite else 0.0))
    return [_round(c.ring_radius * math.cos(angle)), _round(c.ring_radius * math.sin(angle)),
            c.altitudes[index % len(c.altitudes)]]


def _round(value: float) -> float:
    return round(value, 3)


def _coordinates(volume: str, position) -> list:
    return [volume, "volume", "coordinates", [list(position), [0, 0, 0]]]


def _concurrence(name: str, occurrencies: list[dict], completed: str, failed: str = "1_safety_hover") -> dict:
    """A Concurrence over every UAV that succeeds when all do; a collision or a failure takes `failed`."""
    return {"type": "Concurrence", "name": name, "ids": 1, "occurrencies": occurrencies,
            "outcome_cb": "collision_if_any_collided", "child_termination_cb": "all_at_one_collision",
            "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "failed": {"all": "aborted"}},
            "outcomes": {"completed": completed, "failed": failed, "collision": failed}}


def _for_all(state_type: str, name: str, parameters: dict) -> dict:
    return {"type": "SimpleActionState", "state_type": state_type, "name": name, "ids": "all", "ids_var": "agent",
            "parameters": parameters}


def _follow(name: str, uav: int, path: list[list], duration: float) -> dict:
    return {"type": "SimpleActionState", "state_type": "follow_path", "name": name, "ids": uav, "ids_var": "agent",
            "parameters": {"path": [{"definition": d} for d in path], "smooth_path_mode": 0, "dynamic": "velocity",
                           "duration": duration}}


def _cb(state_type: str, name: str, parameters: dict | None, outcomes: dict, all_uavs: bool = False) -> dict:
    state: dict = {"type": "CBState", "state_type": state_type, "name": name}
    if all_uavs:
        state.update(ids="all", ids_var="agent")
    if parameters is not None:
        state["parameters"] = parameters
    state["outcomes"] = outcomes
    return state


def leg_time(c: Crossing, legs: list[list[list[float]]]) -> float:
    """The time limit of one leg for every UAV: 100 s, or 3 x its longest path at maxSpeed rounded up to 10 s."""
    longest = max(sum(math.dist(a, b) for a, b in zip(points, points[1:], strict=False)) for points in legs)
    return max(MIN_LEG_TIME, 10.0 * math.ceil(3.0 * longest / c.max_speed / 10.0))


def mission(c: Crossing, pad_origin, ring_origin) -> dict:
    """The mission as JSON data; the origins (map x, y, z of the pad and ring volumes) size the legs' time limits."""
    def in_map(origin, point):
        return [o + p for o, p in zip(origin, point, strict=True)]

    homes = [[x, y, c.home] for x, y in pads(c)]
    rings = [ring_point(c, i) for i in range(c.uavs)]
    opposites = [ring_point(c, i, opposite=True) for i in range(c.uavs)]
    to_ring = leg_time(c, [[in_map(pad_origin, [x, y, c.take_off]), in_map(ring_origin, r)]
                           for (x, y), r in zip(pads(c), rings, strict=True)])
    crossing = leg_time(c, [[in_map(ring_origin, r), in_map(ring_origin, o), in_map(pad_origin, h)]
                            for r, o, h in zip(rings, opposites, homes, strict=True)])
    ids = range(1, c.uavs + 1)
    agents = [{"ID": i, "model": "iris", "mode": "sitl", "marker_color": [*COLORS[(i - 1) % len(COLORS)], 0.5],
               "ual_use": True, "agent_manager_on_gs": True} for i in ids]
    hover = {"move_type": "translation", "dynamic": "position", "direction": "up", "value": 0.0, "duration": 2.0}
    states = [
        _cb("world_config", "new_world", {"action": "spawn", "id": 1}, {"completed": "add_world"}),
        _cb("world_config", "add_world", {"action": "add", "world_part_def": "from_hyperparameters"},
            {"completed": "world_created_wait"}),
        _cb("wait", "world_created_wait", {"exit_type": "time", "duration": 0.5}, {"completed": "spawn_agents"}),
        _cb("spawn_agents", "spawn_agents",
            {"initial_poses": [[*_coordinates(PAD_VOLUME, [x, y, PAD_HEIGHT]), SPAWN_YAW] for x, y in pads(c)]},
            {"completed": "orca3d"}),
        _cb("algorithm_control", "orca3d",
            {"name": "orca3d", "action": "set", "params": ORCA_PARAMS,
             "values": [c.neighbors, 0.1, 8.0, 4.0, 0.5, c.max_speed]}, {"completed": "1_take_off"}, all_uavs=True),
        _concurrence("take_off", [_for_all("take_off", "take_off", {"height": c.take_off})], "after_takeoff_wait"),
        _cb("wait", "after_takeoff_wait", {"exit_type": "time", "duration": 0.5}, {"completed": "1_to_ring"}),
        _concurrence("to_ring", [_follow("ring", i, [_coordinates(RING_VOLUME, r)], to_ring)
                                 for i, r in zip(ids, rings, strict=True)], "1_crossing"),
        _concurrence("crossing", [_follow("cross", i, [_coordinates(RING_VOLUME, o), _coordinates(PAD_VOLUME, h)],
                                          crossing)
                                  for i, o, h in zip(ids, opposites, homes, strict=True)], "save_csv"),
        _cb("save_csv", "save_csv", None, {"completed": "1_land", "failed": "1_land"}, all_uavs=True),
        _concurrence("land", [_for_all("land", "land", {})], "delete_world", failed="failed"),
        _cb("world_config", "delete_world", {"action": "delete", "id": 1},
            {"completed": "completed", "failed": "failed"}),
        _concurrence("safety_hover", [_for_all("basic_move", "safety_hover", hover)], "safety_wait",
                     failed="safety_wait"),
        _cb("wait", "safety_wait", {"exit_type": "time", "duration": 5.0},
            {"completed": "safety_save_csv", "failed": "safety_save_csv"}),
        _cb("save_csv", "safety_save_csv", None, {"completed": "1_safety_land", "failed": "1_safety_land"},
            all_uavs=True),
        _concurrence("safety_land", [_for_all("land", "safety_land", {})], "failed", failed="failed"),
    ]
    return {"Agents_Config": agents, "State_Machine": states}


def mission_text(data: dict) -> str:
    return json.dumps(data, indent=4) + "\n"


def find_world(name: str) -> Path:
    from magna_common.search_path import find_world_file, world_candidates, world_folders

    if name.endswith(".json") and Path(name).is_file():
        return Path(name)
    world, _, subworld = name.partition("/")
    found = find_world_file(world, subworld, world_folders([BENCH]))
    if found is None:
        raise SystemExit(f"make_crossing: --world {name}: no such world; looked at "
                         f"{world_candidates(world, subworld, world_folders([BENCH]))}")
    return found


def volume_origin(world_file: Path, name: str) -> list[float]:
    """Map x, y, z of a volume's origin: the legs' time limits need their lengths (a volume's turn is left out)."""
    from magna_common.search_path import world_folders
    from magna_worlds.loader import load_world

    world = load_world(world_file, world_folders([BENCH]))
    volume = next((v for v in world.volumes if v.name == name), None)
    if volume is None:
        raise SystemExit(f"make_crossing: {world_file}: no volume {name!r}; the crossing flies from "
                         f"{PAD_VOLUME!r} to {RING_VOLUME!r}: give a world that has both")
    return [float(v) for v in volume.origin.translation]


def problems_in_world(data: dict, world_file: Path, source: str) -> list[str]:
    """What `magna mission check` would refuse: loading, building, and every place against the world (seeds 0-2)."""
    from magna_common.search_path import world_folders
    from magna_gs.mission.build import InertFactory, build_machine
    from magna_gs.mission.loader import mission_from_data
    from magna_gs.mission.world_check import check_against_world
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import load_world

    loaded = mission_from_data(data, source)
    build_machine(loaded.mission, InertFactory(), loaded.plan)
    world = load_world(world_file, world_folders([BENCH]))
    problems = list(loaded.warnings)
    for seed in (0, 1, 2):
        problems += check_against_world(loaded.mission, resolve_world(world, seed), seed)
    return problems


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python bench/missions/make_crossing.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--uavs", type=int, default=50, help="how many UAVs (default 50)")
    parser.add_argument("-o", "--output", type=Path,
                        help="the mission file (default bench/missions/Gym/<N>UAVs_Crossing_ORCA.json)")
    parser.add_argument("--force", action="store_true", help="replace the output file if it exists")
    parser.add_argument("--world", help="WORLD/SUBWORLD (bench/ searched first) or a .json file; default by --uavs")
    parser.add_argument("--ring-radius", type=float, help="m round the CentralZone origin; default by --uavs")
    parser.add_argument("--altitudes", type=float, nargs="+", metavar="M",
                        help="m of the UAVs on the ring, in turn (two or more layers); default by --uavs")
    parser.add_argument("--take-off", type=float, help="take-off height above the pad, m; default by --uavs")
    parser.add_argument("--home", type=float, help="height flown home at, m in the pad volume; default by --uavs")
    parser.add_argument("--rows", type=int, help="rows of pads (default 2)")
    parser.add_argument("--pad-spacing", type=float, help="m between pads (default 2)")
    parser.add_argument("--neighbors", type=int, help="ORCA-3D's N_neighbors_aware (default 5)")
    return parser


def crossing_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Crossing:
    if args.uavs < 2:
        parser.error(f"--uavs {args.uavs}: a crossing needs at least 2 UAVs")
    c = default_crossing(args.uavs)
    chosen = {"world": args.world, "ring_radius": args.ring_radius, "take_off": args.take_off, "home": args.home,
              "rows": args.rows, "pad_spacing": args.pad_spacing, "neighbors": args.neighbors,
              "altitudes": tuple(args.altitudes) if args.altitudes else None}
    c = Crossing(**{**c.__dict__, **{k: v for k, v in chosen.items() if v is not None}})
    layers = len(c.altitudes)
    if layers < 2 or len(set(c.altitudes)) != layers:
        parser.error(f"--altitudes {' '.join(f'{a:g}' for a in c.altitudes)}: give two or more different altitudes")
    if c.uavs % 2 == 0 and (c.uavs // 2) % layers == 0:
        parser.error(f"--altitudes: {layers} layers put each of the {c.uavs} UAVs in the layer of the one crossing "
                     f"towards it from the opposite point (head-on); give a number of layers that does not divide "
                     f"{c.uavs // 2}")
    for name, value in (("--ring-radius", c.ring_radius), ("--rows", c.rows), ("--pad-spacing", c.pad_spacing),
                        ("--neighbors", c.neighbors), ("--take-off", c.take_off)):
        if value <= 0:
            parser.error(f"{name} {value:g}: give a positive value")
    return c


def main(argv=None) -> int:
    from magna_common.files import write_text_atomically
    from magna_gs.mission.model import MissionError

    parser = build_parser()
    args = parser.parse_args(argv)
    c = crossing_from_args(parser, args)
    output = args.output or BENCH / "missions" / "Gym" / f"{c.uavs}UAVs_Crossing_ORCA.json"
    if output.exists() and not args.force:
        parser.error(f"{output} already exists; pass --force to replace it")
    world_file = find_world(c.world)
    data = mission(c, volume_origin(world_file, PAD_VOLUME), volume_origin(world_file, RING_VOLUME))
    try:
        problems = problems_in_world(data, world_file, str(output))
    except MissionError as err:
        problems = [str(err)]
    if problems:
        print(f"make_crossing: not written: the mission does not fit {world_file}:", *problems, sep="\n  ",
              file=sys.stderr)
        return 1
    write_text_atomically(output, mission_text(data), overwrite=args.force)
    print(f"{output}: {c.uavs} UAVs, pads {c.rows} x {c.columns} ({c.pad_spacing:g} m), ring {c.ring_radius:g} m at "
          f"{' / '.join(f'{a:g}' for a in c.altitudes)} m, checked against {world_file}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
