"""`compare`: one mission flown N times with ORCA-3D and N times with each of several networks, in one table.

    magna learn compare --world Gym/Empty_4_Cylinders --mission Gym/2UAVs_2paths_4_Cylinders \\
        --model supervised=~/nets/four.pt --model rl=~/magna_data/mlr/rl/rl_four_cylinders/policy.pt \\
        --search-path ../shared/ros_magna_corpus --n-iter 20 --seed 2000

It is `magna learn fly` once per network (mlr.fly: the same checks, network missions and `magna run`
batches, with the same --seed so simulation m of every batch flies the same random waypoints), sharing
one ORCA-3D batch, NAME_orca. Network LABEL's batch is NAME_LABEL_nn and its mission goes to OUT/LABEL/missions/.
The table (mlr.flight_metrics.side_by_side: collision-free rate, successful missions, paths to the goal,
time to goal, minimum gap between UAVs) is written to OUT/comparison.md and .json (OUT defaults to
DATA_ROOT/mlr/compare/NAME). Every network is checked before anything flies.

Exit status as `magna learn fly`'s: 0 when every batch ran, 1 when a simulation crashed or could not start,
2 for bad input (nothing started), 130 when interrupted (no table written).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from magna_common.cli_vocabulary import add_output
from magna_common.errors import UsageError
from magna_common.files import write_text_atomically
from magna_common.storage_tree import StorageError, check_component

EXAMPLES = """\
examples:
  magna learn compare --world Gym/Empty_4_Cylinders --mission Gym/2UAVs_2paths_4_Cylinders \\
      --search-path ../shared/ros_magna_corpus --n-iter 20 --seed 2000 \\
      --model supervised=~/nets/four.pt --model rl=~/magna_data/mlr/rl/rl_four_cylinders/policy.pt   # [long]
"""
HELP = "fly a mission with ORCA-3D and with several networks (supervised, RL, ...), N simulations each, in one table"


def _model(value: str) -> tuple[str, Path]:
    label, sep, path = value.partition("=")
    if not sep or not label or not path:
        raise argparse.ArgumentTypeError(f"{value!r}: give LABEL=PATH.pt, e.g. rl=~/nets/policy.pt")
    return label, Path(path).expanduser()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from mlr.fly import add_batch_arguments

    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EXAMPLES
    add_batch_arguments(parser)
    parser.add_argument("--model", required=True, type=_model, action="append", metavar="LABEL=PATH.pt",
                        help="a network and its column label; give one --model per network")
    parser.add_argument("--name", default="compare", help="names the batches: NAME_orca, NAME_LABEL_nn "
                                                          "(default: compare)")
    add_output(parser, metavar="DIR", help="where the table goes (default DATA_ROOT/mlr/compare/NAME)")


def run(args) -> int:
    from magna_gs.inputs import InputError
    from mlr.flight_metrics import read_batch, side_by_side
    from mlr.fly import FlyError, FlyRequest, fly_batches, prepare

    labels = [label for label, _ in args.model]
    try:
        for label in labels:
            check_component(label, "--model LABEL")
        if len(set(labels)) != len(labels) or "orca" in labels:
            raise UsageError(f"--model labels {labels}: give each network a label of its own, other than 'orca'")
        data_root = args.data_root.expanduser().resolve()
        out = (args.output.expanduser() if args.output else data_root / "mlr" / "compare" / args.name).resolve()
        base = FlyRequest(world=args.world, mission=args.mission, model=Path(), name="", data_root=data_root,
                          n_iter=args.n_iter, search_path=[Path(p) for p in args.search_path], rtf=args.rtf,
                          seed=args.seed, no_bag=args.no_bag, orca_name=f"{args.name}_orca")
        plans = []
        for label, model in args.model:  # every check first (prepare): nothing flies if one network is wrong
            plans.append(prepare(dataclasses.replace(base, model=model, name=f"{args.name}_{label}",
                                                     output=out / label)))
        # the first plan flies the one ORCA-3D batch; the others fly only their network (as dagger's evaluation)
        plans[1:] = [dataclasses.replace(plan, orca_argv=None) for plan in plans[1:]]
        failed = False
        for plan in plans:
            status = fly_batches(plan)
            if status not in (0, 1):
                return status
            failed |= status == 1
        batches = [read_batch(plans[0].orca_dataset, "ORCA-3D")]
        batches += [read_batch(plan.nn_dataset, label) for plan, label in zip(plans, labels, strict=True)]
    except (FlyError, InputError, StorageError) as err:
        raise UsageError(" ".join(str(err).split())) from None
    title = f"{plans[0].mission} in {plans[0].world}: ORCA-3D and {', '.join(labels)}, seeds {args.seed + 1}.." \
            f"{args.seed + args.n_iter}"
    table = side_by_side(batches, title)
    write_text_atomically(out / "comparison.md", table, overwrite=True)
    write_text_atomically(out / "comparison.json", json.dumps(
        {"world": plans[0].world, "mission": plans[0].mission, "seed": args.seed,
         "models": {label: str(plan.model) for label, plan in zip(labels, plans, strict=True)},
         "batches": [m.to_json() for m in batches]}, indent=2) + "\n", overwrite=True)
    print(table, flush=True)
    print(f"compare: {out / 'comparison.md'}, {out / 'comparison.json'}", file=sys.stderr)
    return 1 if failed else 0
