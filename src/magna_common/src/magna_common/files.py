"""Writing files so that nothing is lost: a reader (or a crash) never sees half a file, and an
existing file is only replaced when the caller says so.
"""
from __future__ import annotations

import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any


def write_atomically(path: str | os.PathLike, write_fn: Callable[[IO[Any]], None], overwrite: bool = False,
                     binary: bool = False) -> Path:
    """Write `path` through `write_fn(file)`, all or nothing.

    The data goes to a temporary file in the same folder (so the final rename stays on one file
    system), is flushed and fsync'ed, then renamed onto `path`. The file gets the mode a plain
    open() gives (0o666 less the umask, or the folder's default ACL): the kernel applies the umask
    as it creates the temporary file, so nothing here reads or changes the process's umask (another
    thread creating a file meanwhile gets the user's umask too). If `write_fn` raises, the temporary
    file is removed and `path` is untouched. An existing `path` is refused with FileExistsError
    unless `overwrite`; without `overwrite` the final step is a hard link, which fails rather than
    replace a file that appeared meanwhile. Text files are opened with newline="" (csv's rule).
    Returns the path written.
    """
    path = Path(path)
    if not overwrite and path.exists():
        raise FileExistsError(f"{path}: already exists (pass overwrite=True to replace it)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _create_temporary(path)
    try:
        out = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", newline="", encoding="utf-8")
        with out:
            write_fn(out)
            out.flush()
            os.fsync(out.fileno())
        if overwrite:
            os.replace(tmp, path)
        else:
            _publish_without_overwrite(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)
    return path


def _create_temporary(path: Path) -> tuple[int, Path]:
    """A new file beside `path`, opened for writing, with open()'s mode (tempfile.mkstemp's would be 0600:
    summary.csv and result.json came out unreadable to the group whatever the user's umask)."""
    for _ in range(100):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp"
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666), tmp
        except FileExistsError:  # a name another writer holds: draw again
            continue
    raise FileExistsError(f"{path.parent}: no free temporary name for {path.name} in 100 tries")


def _publish_without_overwrite(tmp: Path, path: Path) -> None:
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise FileExistsError(f"{path}: already exists (pass overwrite=True to replace it)") from None
    except OSError:  # a file system without hard links: the check above is the best we can do
        if path.exists():
            raise FileExistsError(f"{path}: already exists (pass overwrite=True to replace it)") from None
        os.replace(tmp, path)
        return
    tmp.unlink()


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_text_atomically(path: str | os.PathLike, text: str, overwrite: bool = False) -> Path:
    """`write_atomically` for a text that is already in memory."""
    def write(out: IO[Any]) -> None:
        out.write(text)

    return write_atomically(path, write, overwrite=overwrite)


def write_bytes_atomically(path: str | os.PathLike, data: bytes, overwrite: bool = False) -> Path:
    """`write_atomically` for bytes that are already in memory."""
    def write(out: IO[Any]) -> None:
        out.write(data)

    return write_atomically(path, write, overwrite=overwrite, binary=True)
