"""The one base class of "the user can fix this" errors, and the exit status it carries.

The `magna` command line prints any `UserError` as `magna COMMAND: message` (no traceback) and
exits with its `exit_status`. Packages derive their own error types from it (a bad world, a bad
mission, a storage conflict), so a new kind of bad input needs no change to the command line.
"""
from __future__ import annotations


class UserError(Exception):
    """Bad input or a state the user can change; the message says what and how to fix it."""

    exit_status = 2


class UsageError(UserError):
    """A command used wrongly: a missing argument, a value out of range, a file that is not there."""
