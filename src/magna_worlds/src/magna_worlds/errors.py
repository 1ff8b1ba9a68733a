"""The one error a bad world file gets: which file, where in its JSON, what is wrong and how to fix it."""
from __future__ import annotations


class WorldError(ValueError):
    """Bad world input. str() reads `worlds/x.json: scenario.volumes[2].geometries[0].shape: unknown shape ...`."""

    exit_status = 2

    def __init__(self, source: str, path: str, message: str):
        self.source, self.path, self.message = source, path, message
        where = f"{source}: {path}" if path else source
        super().__init__(f"{where}: {message}")


def join_path(base: str, key) -> str:
    """JSON path one level down: `a.b` for a key, `a[3]` for an index."""
    if isinstance(key, int):
        return f"{base}[{key}]"
    return f"{base}.{key}" if base else str(key)
