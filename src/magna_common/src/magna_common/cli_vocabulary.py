"""The one command-line vocabulary every MAGNA command follows.

- where a command writes (a file or a folder): `-o/--output PATH`;
- replace an output that exists: `--force`;
- a dataset that already holds simulations (datasets only): `--append`, `--overwrite`, `--skip-save`;
- a world or a mission: a `WORLD/SUBWORLD` or `MISSION/SUBMISSION` name, or a file path, with
  `--search-path DIR`;
- simulated time against wall time: `--rtf max|FACTOR`.

Older spellings (`--out`, `--overwrite` for a single output, `--no-data`, ...) keep
working for one release: they do what the new spelling does and print one line
saying which spelling replaces them. The table lives in the root README too.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from magna_common.errors import UsageError

RTF_METAVAR = "max|FACTOR"
RTF_HELP = "real-time factor: 'max' runs as fast as the machine goes, a number runs that many times real time"


class OutputExists(Exception):
    """An output is already there and --force was not given."""


def deprecation_line(prog: str, old: str, new: str) -> str:
    return f"{prog}: {old} is deprecated and goes in the next release; use {new}"


def _warn(parser_or_prog, old: str, new: str) -> None:
    prog = getattr(parser_or_prog, "prog", parser_or_prog)
    print(deprecation_line(prog, old, new), file=sys.stderr)


class _DeprecatedStore(argparse.Action):
    """An old spelling of an option that takes a value: stores it, says what replaces it."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs):
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        _warn(parser, option_string, self.new)
        setattr(namespace, self.dest, values)


class _DeprecatedConst(argparse.Action):
    """An old spelling of a flag: stores its constant, says what replaces it."""

    def __init__(self, option_strings, dest, new: str = "", const=True, **kwargs):
        self.new = new
        super().__init__(option_strings, dest, nargs=0, const=const, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        _warn(parser, option_string, self.new)
        setattr(namespace, self.dest, self.const)


def add_deprecated_option(parser, old: str, dest: str, new: str, **kwargs) -> None:
    """`old VALUE` still works for one release, hidden from --help, as `new VALUE`."""
    parser.add_argument(old, dest=dest, action=_DeprecatedStore, new=new, help=argparse.SUPPRESS, **kwargs)


def add_deprecated_flag(parser, old: str, dest: str, new: str, const=True) -> None:
    """The flag `old` still works for one release, hidden from --help, as `new`."""
    parser.add_argument(old, dest=dest, action=_DeprecatedConst, new=new, const=const, help=argparse.SUPPRESS,
                        default=argparse.SUPPRESS)


def add_output(parser, *, help: str, required: bool = False, default=None, metavar: str = "PATH",
               type=Path, old: tuple[str, ...] = ()) -> None:
    """-o/--output, with the command's old spellings (e.g. `--out`) kept for one release."""
    target = parser
    if required and old:
        # One of the spellings must be given; argparse names only the visible one when none is.
        target = parser.add_mutually_exclusive_group(required=True)
        required = False
    target.add_argument("-o", "--output", dest="output", required=required, default=default, metavar=metavar,
                        type=type, help=help)
    for spelling in old:
        target.add_argument(spelling, dest="output", action=_DeprecatedStore, new="-o/--output",
                            help=argparse.SUPPRESS, metavar=metavar, type=type, default=default)


def add_force(parser, *, help: str = "replace the output if it exists", old: tuple[str, ...] = ()) -> None:
    """--force, with old spellings (e.g. `--overwrite` of a single output) kept for one release."""
    parser.add_argument("--force", action="store_true", help=help)
    for spelling in old:
        add_deprecated_flag(parser, spelling, "force", "--force")


def add_search_path(parser, *, what: str = "worlds and missions") -> None:
    parser.add_argument("--search-path", action="append", default=[], type=Path, metavar="DIR",
                        help=f"also look for {what} by name under DIR (repeatable), "
                             "e.g. a folder laid out like ROS-MAGNA's Code/JSONs")


def add_rtf(parser, *, default: str = "max", help: str = RTF_HELP) -> None:
    parser.add_argument("--rtf", default=default, metavar=RTF_METAVAR, help=f"{help} (default {default})")


def parse_rtf(value: str) -> str:
    """An --rtf value as the simulator takes it: 'max' or a factor > 0 ('10.0' -> '10'); UsageError otherwise."""
    text = str(value).strip().lower()
    if text == "max":
        return "max"
    try:
        factor = float(text)
    except ValueError:
        factor = math.nan
    if not math.isfinite(factor) or factor <= 0:
        raise UsageError(f"--rtf {value!r}: give 'max' (as fast as possible) or a factor > 0 such as 1.0 or 10")
    return f"{factor:g}"


def check_output(path, force: bool, what: str = "") -> None:
    """Refuse to replace an existing output unless --force was given."""
    path = Path(path)
    if path.exists() and not force:
        label = f"{what} " if what else ""
        raise OutputExists(f"{label}{path} already exists; pass --force to replace it")
