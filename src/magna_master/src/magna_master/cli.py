"""The `magna` command: one entry point, one subcommand per capability.

Each subcommand is a module exposing `HELP` (one line), `add_arguments(parser)`
and `run(args) -> int`. Modules are imported when the parser is built, so they
keep heavy imports (torch, pybullet, rospy) inside `run`.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from magna_common.errors import UsageError, UserError

__all__ = ["COMMANDS", "UsageError", "build_parser", "main"]

# Subcommands that exist in this build, in the order `magna --help` lists them.
# Later capabilities (world, mission, run, replay, learn, voice) add their line here.
COMMANDS: list[tuple[str, str]] = [
    ("doctor", "magna_master.doctor"),
    ("world", "magna_worlds.cli"),
    ("mission", "magna_gs.mission.cli"),
    ("run", "magna_master.run_cli"),
    ("port", "magna_master.port_cli"),
    ("replay", "magna_viz.replay_cli"),
    ("report", "magna_viz.report_cli"),
    ("learn", "mlr.cli"),
    ("voice", "voice.cli"),
    ("studio", "magna_studio.cli"),
]


def _project_packages_importable() -> None:
    """mlr and voice live at the repository root, beside the catkin packages, so a node
    started by roslaunch does not see them: put the root on sys.path."""
    from magna_common.workspace import WorkspaceNotFound, find_root

    try:
        root = str(find_root())
    except WorkspaceNotFound:
        return
    if root not in sys.path:
        sys.path.append(root)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="magna",
        description="MAGNA: define, simulate, fly and learn from cooperative multi-UAV missions.",
        epilog="Run 'magna COMMAND --help' for the options of one command.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    _project_packages_importable()
    for name, module_name in COMMANDS:
        module = importlib.import_module(module_name)
        sub = subparsers.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except UserError as error:
        print(f"magna {args.command}: {error}", file=sys.stderr)
        return error.exit_status
    except KeyboardInterrupt:
        print(f"magna {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
