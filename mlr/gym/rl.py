"""`magna learn rl CONFIG`: PPO (stable-baselines3, CPU) on the gym, one shared policy for every UAV.

The config (YAML or JSON; mlr/gym/README.md has the table) names the world and mission, the gym's
settings and PPO's. The run writes into its output folder:
- `tensorboard/`: SB3's curves (episode return and length, losses), for `magna learn board`;
- `checkpoints/ppo_<steps>.zip` and `vecnormalize_<steps>.pkl` every `checkpoint_every` steps: the same
  command resumes from the latest one after an interruption;
- `policy.zip`, `vecnormalize.pkl`: the final model and observation statistics;
- `policy.pt` and `policy.json`: the policy exported for the NAI (mlr.gym.export);
- `rl.json`: the config, steps, wall time, the mean return of the first and last episodes, and the
  success rate (mlr.gym.evaluate: whole missions flown deterministically in the gym) at every checkpoint
  and at the end, with the training wall time it was reached at; TensorBoard has it as eval/success_rate,
  and `success.png` draws it against the training time.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from magna_common.files import write_text_atomically
from mlr.gym.rl_config import RlConfig, RlError, load_config

HELP = "reinforcement learning: PPO on the gym (one policy for every UAV), with TensorBoard and checkpoints"
DESCRIPTION = __doc__
EXAMPLES = """\
examples:
  magna learn rl mlr/configs/rl_four_cylinders.yaml --search-path ../shared/ros_magna_corpus   # [long]
  magna learn rl mlr/configs/rl_four_cylinders.yaml --search-path ../shared/ros_magna_corpus \\
      --total-steps 20000 -o /tmp/rl_quick    # a short run [long]
"""


def prepare_output(config: RlConfig, out: Path, force: bool) -> None:
    """OUT/config.json names the config a folder's checkpoints belong to; another config is refused, unless
    `force`, which starts afresh (the old checkpoints and curves are removed)."""
    import shutil

    record = out / "config.json"
    mine = {k: v for k, v in config.as_json().items() if k not in ("path", "total_steps")}
    if record.is_file():
        theirs = json.loads(record.read_text())
        if theirs != mine and not force:
            changed = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
            raise RlError(f"{out}: holds a run of another config (differs in {', '.join(changed)}); give another "
                          "-o/--output, or --force to start afresh there")
        if theirs != mine:
            for name in ("checkpoints", "tensorboard"):
                shutil.rmtree(out / name, ignore_errors=True)
            (out / "history.json").unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomically(record, json.dumps(mine, indent=2) + "\n", overwrite=True)


def add_arguments(parser) -> None:
    from magna_common.cli_vocabulary import add_force, add_output, add_search_path

    parser.add_argument("config", type=Path, help="the RL config (YAML or JSON; mlr/gym/README.md)")
    add_search_path(parser, what="the world and mission files")
    add_output(parser, metavar="DIR", help="where the run goes (default ~/magna_data/mlr/rl/NAME)")
    parser.add_argument("--total-steps", type=int, metavar="N", help="agent-steps to train (default: the config's)")
    add_force(parser, help="start afresh in an output folder that holds a run of another config")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    import sys

    from magna_common.errors import UsageError
    from mlr.gym.ppo_training import train
    from mlr.gym.scenario import ScenarioError

    try:
        config = load_config(args.config)
        if args.total_steps is not None:
            if args.total_steps < 1:
                raise RlError(f"--total-steps is {args.total_steps}: give a whole number >= 1")
            config = dataclasses.replace(config, total_steps=args.total_steps)
        out = Path(args.output).expanduser().resolve() if args.output is not None \
            else Path("~/magna_data/mlr/rl").expanduser() / config.name
        prepare_output(config, out, args.force)
        numbers = train(config, out, [Path(p) for p in args.search_path], progress=not args.quiet)
    except (RlError, ScenarioError) as err:
        raise UsageError(" ".join(str(err).split())) from None
    except KeyboardInterrupt:
        print("rl: interrupted; run the same command again to go on from the last checkpoint", file=sys.stderr)
        return 130
    print(f"rl: {numbers['steps']} steps in {numbers['wall_seconds'] / 60:.1f} min; mean return "
          f"{numbers['first_mean_return']} (first episodes) -> {numbers['last_mean_return']} (last)")
    final = numbers["evaluation"]
    print(f"rl: success rate {final['succeeded']}/{final['flights']} whole missions flown in the gym "
          f"({final['success_rate']:.0%}), minimum gap {final['min_gap']:.2f} m")
    print(f"rl: {out / 'policy.pt'}, {out / 'rl.json'}, TensorBoard: magna learn board {out / 'tensorboard'}")
    return 0
