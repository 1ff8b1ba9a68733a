"""`fly`: a mission flown N times with ORCA-3D and N times with a trained network, compared side by side.

    magna learn fly --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA \\
        --model ~/magna_data/mlr/runs/crossing_quick/crossing_quick.pt --n-iter 20

Steps (see mlr/README.md, "Flying a trained network"):

1. checks, before anything starts or is written: the model and its spec load as the UAV managers
   load them, the world and mission are found and valid, the mission sets ORCA-3D (orca3/orca3d)
   with an algorithm_control state, and no dataset would be mixed up with older data;
2. the network variant of the mission (`nn_variant`): every algorithm_control state that sets
   ORCA-3D is followed by one that sets neural_network with the model (the ORCA state becomes a
   configure: the teacher's parameters); written to OUT/missions/MISSION/SUBMISSION_nn.json, so
   `magna run --search-path OUT` finds it;
3. two batches through the real `magna run`: the mission as it is under the name NAME_orca, the
   variant under NAME_nn, with the same --seed so simulation m of both flies the same random
   waypoints (seed S+m);
4. the metrics of both datasets (`read_batch`), written to OUT/comparison.md, .json and .png.

Exit status: 0 when both batches ran, 1 when a simulation crashed or could not start (it is left
out of the metrics), 2 for bad input (nothing started), 130 when interrupted (Ctrl-C is forwarded
to the running `magna run`, which stops its simulation cleanly; no comparison is written).
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass, field, fields
from pathlib import Path

from magna_common.cli_vocabulary import add_output, add_rtf, add_search_path, parse_rtf
from magna_common.errors import UsageError
from magna_common.storage_tree import StorageError, StorageKey, check_component, existing_simulations
from mlr.flight_metrics import Comparison, read_batch, write_comparison
from mlr.nn_mission import VARIANT_SUFFIX, Change, FlyError, mission_roles, nn_variant, write_variant

HELP = "fly a mission with a trained network and with ORCA-3D, N simulations each, and compare them side by side"

_EPILOG = """\
Data: DATA_ROOT/Simulations/WORLD/SUBWORLD/MISSION/SUBMISSION/NAME_orca/dataset_1/ (ORCA-3D) and
.../MISSION/SUBMISSION_nn/NAME_nn/dataset_1/ (network); the comparison goes to -o/--output DIR (default
DATA_ROOT/mlr/fly/NAME): comparison.md, comparison.json, comparison.png, and the network's mission
DIR/missions/MISSION/SUBMISSION_nn.json.

Existing datasets: --append adds N simulations to both, --overwrite rewrites simulations 1..N of both
(and a different variant file); the comparison covers every simulation of each dataset. --skip-orca
flies only the network and compares with the ORCA-3D dataset already there.

examples:
  magna learn train mlr/configs/crossing_quick.yaml --quiet    # the network flown below (under a minute; reused)
  magna learn fly --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA \\
      --model ~/magna_data/mlr/runs/crossing_quick/crossing_quick.pt --n-iter 1 --name quick --append
  magna learn fly --world Gym/Central_Obstacle_Torus --mission Gym/2UAVs_Crossing_ORCA \\
      --model ~/magna_data/mlr/runs/crossing_quick/crossing_quick.pt --n-iter 20 --name crossing   # [long]
"""


def add_batch_arguments(parser: argparse.ArgumentParser) -> None:
    """What the batches of `fly` and `compare` are: the world and mission, how many, where, how fast, which seeds."""
    parser.add_argument("--world", required=True, metavar="WORLD/SUBWORLD", help="the world, as for magna run")
    parser.add_argument("--mission", required=True, metavar="MISSION/SUBMISSION",
                        help="a mission that sets orca3/orca3d with an algorithm_control state")
    parser.add_argument("--n-iter", type=int, default=20, metavar="N", help="simulations per batch (default: 20)")
    add_search_path(parser, what="worlds and missions (passed on to magna run)")
    parser.add_argument("--data-root", type=Path, default=Path("~/magna_data"), metavar="DIR",
                        help="where Simulations/ goes (default: ~/magna_data)")
    add_rtf(parser)
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="base seed of every batch; simulation M uses S+M (default: 0)")
    parser.add_argument("--no-bag", action="store_true", help="do not record a bag per simulation")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    add_batch_arguments(parser)
    parser.add_argument("--model", required=True, type=Path, metavar="PATH.pt",
                        help="the TorchScript network (its spec PATH.json beside it), as mlr's export writes it")
    parser.add_argument("--name", default="fly",
                        help="the batches are named NAME_orca and NAME_nn (default: %(default)s)")
    add_output(parser, metavar="DIR", old=("--out",),
               help="where the comparison and the network's mission go (default: DATA_ROOT/mlr/fly/NAME)")
    parser.add_argument("--fallback", action="store_true",
                        help="the network flies with the NAI's safety fallback: ORCA-3D, the teacher, takes over a "
                             "step whose network command would collide within its time horizon (report such "
                             "flights apart from the network's own)")
    parser.add_argument("--teacher-agent-radius", type=float, metavar="M",
                        help="the teacher's ORCA-3D agent_radius while the network flies (what the recorder's "
                             "teacher_vel and the fallback use; default: the mission's)")
    policy = parser.add_mutually_exclusive_group()
    policy.add_argument("--append", dest="policy", action="store_const", const="append",
                        help="add the simulations to existing datasets (passed on to magna run)")
    policy.add_argument("--overwrite", dest="policy", action="store_const", const="overwrite",
                        help="rewrite simulations 1..N of existing datasets and a different network mission")
    parser.add_argument("--skip-orca", action="store_true",
                        help="fly only the network; compare with the ORCA-3D dataset NAME_orca already there")
    parser.add_argument("--orca-name", metavar="NAME",
                        help="the ORCA-3D dataset's name (default NAME_orca); with --skip-orca, compare another "
                             "network with the ORCA-3D batch of an earlier fly")


def repo_root() -> Path:
    """The repository whose `magna` script runs the batches: $MAGNA_ROOT, else the parent of mlr/."""
    env = os.environ.get("MAGNA_ROOT")
    return Path(env).resolve() if env else Path(__file__).resolve().parents[1]


@dataclass
class FlyPlan:
    magna: Path
    world: str
    mission: str
    model: Path
    out: Path
    variant: Path
    changes: list[Change]
    orca_dataset: Path
    nn_dataset: Path
    orca_argv: list[str] | None  # None with --skip-orca
    nn_argv: list[str]


def _spec_arg(value: str) -> str:
    """A --world/--mission value: a .json file becomes absolute (the batches may run elsewhere), a name stays."""
    path = Path(value).expanduser()
    return str(path.resolve()) if value.endswith(".json") and path.is_file() else value


@dataclass(frozen=True)
class FlyRequest:
    """What to fly and compare: the command line's options, typed. Other commands (DAgger) build one directly."""

    world: str
    mission: str
    model: Path
    name: str
    data_root: Path
    n_iter: int = 20
    search_path: list[Path] = field(default_factory=list)
    output: Path | None = None
    rtf: str = "max"
    seed: int = 0
    no_bag: bool = False
    policy: str | None = None  # None, "append" or "overwrite" (passed on to magna run)
    skip_orca: bool = False
    fallback: bool = False
    teacher_agent_radius: float | None = None
    orca_name: str | None = None  # the ORCA-3D dataset's NAME (default NAME_orca): several networks, one ORCA batch

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> FlyRequest:
        return cls(**{f.name: getattr(args, f.name) for f in fields(cls)})

    def teacher(self) -> dict[str, float] | None:
        """The teacher's ORCA-3D parameters that differ from the mission's (--teacher-agent-radius)."""
        radius = self.teacher_agent_radius
        if radius is None:
            return None
        if not radius > 0:
            raise FlyError(f"--teacher-agent-radius is {radius}: give a radius in metres > 0")
        return {"agent_radius": float(radius)}


def prepare(request: FlyRequest) -> FlyPlan:
    """Check everything and write the network's mission; FlyError/InputError/StorageError before anything flies."""
    from magna_gs.inputs import resolve_inputs
    from magna_uav.nai.neural import NeuralModelError, load_model

    if request.n_iter < 1:
        raise FlyError(f"--n-iter must be >= 1, got {request.n_iter}")
    rtf = parse_rtf(request.rtf)
    orca_name, nn_name = request.orca_name or f"{request.name}_orca", f"{request.name}_nn"
    for value in (orca_name, nn_name):
        check_component(value, "--name")
    magna = repo_root() / "magna"
    if not os.access(magna, os.X_OK):
        raise FlyError(f"{magna}: no magna command there; set MAGNA_ROOT to the repository root")

    model = request.model.expanduser().resolve()
    try:
        loaded = load_model(model)  # as the UAV managers will: a bad model stops here, not 20 missions later
    except NeuralModelError as err:
        raise FlyError(str(err)) from None
    neighbor_dist = loaded.spec.neighbor_dist  # the distance it was trained with, when its spec says

    search = [p.expanduser().resolve() for p in request.search_path]
    world, mission = _spec_arg(request.world), _spec_arg(request.mission)
    inputs = resolve_inputs(world, mission, search)
    try:
        raw = json.loads(inputs.mission_file.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise FlyError(f"{inputs.mission_file}: cannot read it as JSON: {err}") from None
    variant, changes = nn_variant(raw, str(model), neighbor_dist, inputs.mission_file,
                                  fallback=request.fallback, teacher=request.teacher())
    missing = [role for role in mission_roles(raw) if role != loaded.role]
    if missing:
        print(f"fly: warning: the model flies role {loaded.role!r}; the mission's {', '.join(missing)} role(s) will "
              "hover with no network for them", file=sys.stderr)

    data_root = request.data_root.expanduser().resolve()
    out = request.output.expanduser() if request.output is not None else data_root / "mlr" / "fly" / request.name
    out = out.resolve()
    nn_submission = f"{inputs.submission}{VARIANT_SUFFIX}"
    orca_dataset = StorageKey(inputs.world, inputs.subworld, inputs.mission, inputs.submission,
                              orca_name).dataset_dir(data_root, 1)
    nn_dataset = StorageKey(inputs.world, inputs.subworld, inputs.mission, nn_submission,
                            nn_name).dataset_dir(data_root, 1)
    # magna run would stop at such a conflict too, but only after the other batch had flown
    if request.skip_orca:
        if not existing_simulations(orca_dataset):
            raise FlyError(f"--skip-orca: {orca_dataset} holds no simulations; run without --skip-orca first")
    elif request.policy is None and existing_simulations(orca_dataset):
        raise FlyError(f"{orca_dataset} holds simulations already; nothing was started. Choose --append, "
                       "--overwrite, --skip-orca (compare with them) or another --name")
    if request.policy is None and existing_simulations(nn_dataset):
        raise FlyError(f"{nn_dataset} holds simulations already; nothing was started. Choose --append, "
                       "--overwrite or another --name")

    path = write_variant(out, inputs.mission, inputs.submission, variant, request.policy == "overwrite")
    nn_search = [out, *search]
    found = resolve_inputs(world, f"{inputs.mission}/{nn_submission}", nn_search)  # the ground station's checks
    if found.mission_file != path.resolve():
        raise FlyError(f"magna run would fly {found.mission_file} instead of {path}; rename or move it")

    common = ["--world", world, "--n-iter", str(request.n_iter), "--rtf", rtf, "--seed", str(request.seed),
              "--data-root", str(data_root)]
    if request.policy:
        common.append(f"--{request.policy}")
    if request.no_bag:
        common.append("--no-bag")

    def searching(dirs):
        return [arg for d in dirs for arg in ("--search-path", str(d))]

    orca_argv = None if request.skip_orca else [str(magna), "run", *common, "--mission", mission, "--name", orca_name,
                                             *searching(search)]
    nn_argv = [str(magna), "run", *common, "--mission", f"{inputs.mission}/{nn_submission}", "--name", nn_name,
               *searching(nn_search)]
    return FlyPlan(magna, f"{inputs.world}/{inputs.subworld}", f"{inputs.mission}/{inputs.submission}", model, out,
                   path, changes, orca_dataset, nn_dataset, orca_argv, nn_argv)


def run_batch(argv: list[str], stop_wait: float = 180.0) -> tuple[int, bool]:
    """Run one `magna run`; (its exit status, whether we were interrupted). Never leaves it running.

    The batch runs in a session of its own, so a terminal's Ctrl-C reaches only us: we forward
    one SIGINT (SIGTERM likewise), on which magna run stops its simulation, ends every process
    of it and exits 130. Should we leave for another reason, it is stopped the same way, then
    terminated and killed if it does not end.
    """
    process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, start_new_session=True)
    interrupted = threading.Event()

    def forward(signum, _frame):
        if interrupted.is_set():
            print("fly: still waiting for magna run to clean up", file=sys.stderr, flush=True)
            return
        interrupted.set()
        print(f"\nfly: {signal.Signals(signum).name}: stopping the running batch (no further batch starts)",
              file=sys.stderr, flush=True)
        _signal(process, signal.SIGINT)

    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, forward)
    try:
        return process.wait(), interrupted.is_set()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if process.poll() is None:
            _stop(process, stop_wait)


def _signal(process: subprocess.Popen, sig: int, group: bool = False) -> None:
    try:
        if group:
            os.killpg(process.pid, sig)
        else:
            process.send_signal(sig)
    except ProcessLookupError:
        pass


def _stop(process: subprocess.Popen, wait: float) -> None:
    for sig, timeout, group in ((signal.SIGINT, wait, False), (signal.SIGTERM, 30.0, False),
                                (signal.SIGKILL, 10.0, True)):
        _signal(process, sig, group)
        try:
            process.wait(timeout)
            return
        except subprocess.TimeoutExpired:
            continue


def fly_batches(plan: FlyPlan) -> int:
    """Run the batches of `plan`: 0 when all ran, 1 when a simulation failed, else the status to stop with."""
    for change in plan.changes:
        print(f"fly: network mission {plan.variant}: {change}", flush=True)
    codes = []
    for label, argv in (("ORCA-3D", plan.orca_argv), ("network", plan.nn_argv)):
        if argv is None:
            print(f"fly: {label}: reusing {plan.orca_dataset}", flush=True)
            continue
        print(f"fly: {label} batch: {' '.join(argv)}", flush=True)
        code, interrupted = run_batch(argv)
        if interrupted or code == 130:
            print(f"fly: interrupted during the {label} batch; no comparison written", file=sys.stderr)
            return 130
        if code not in (0, 1):
            print(f"fly: the {label} batch failed (magna run exit status {code}); see its message above",
                  file=sys.stderr)
            return code
        codes.append(code)
    return 1 if any(codes) else 0


def fly(plan: FlyPlan) -> int:
    """Run the batches of `plan`, then compare them; the exit status (module doc)."""
    status = fly_batches(plan)
    if status not in (0, 1):
        return status
    comparison = Comparison(read_batch(plan.orca_dataset, "ORCA-3D"), read_batch(plan.nn_dataset, "network"),
                            plan.world, plan.mission, str(plan.model), [str(c) for c in plan.changes])
    files = write_comparison(comparison, plan.out)
    print(comparison.markdown(), flush=True)
    print("fly: " + ", ".join(str(f) for f in files), flush=True)
    return status


def run(args) -> int:
    from magna_gs.inputs import InputError

    try:
        plan = prepare(FlyRequest.from_args(args))
        return fly(plan)
    except (FlyError, InputError, StorageError) as err:
        raise UsageError(" ".join(str(err).split())) from None


def main(argv: list[str] | None = None) -> int:
    """`python -m mlr.fly` (in the workspace's environment): the subcommand on its own."""
    parser = argparse.ArgumentParser(prog="fly", description=HELP)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except UsageError as error:
        print(f"fly: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fly: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
