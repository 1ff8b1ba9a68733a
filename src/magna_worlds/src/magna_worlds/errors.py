"""The one error a bad world file gets: which file, where in its JSON, what is wrong and how to fix it; and the
warning for what the original tolerated, which keeps the same three parts."""
from __future__ import annotations

from magna_common.json_fields import FieldError, located


class WorldError(FieldError):
    """Bad world input. str() reads `worlds/x.json: scenario.volumes[2].geometries[0].shape: unknown shape ...`."""


class WorldWarning(str):
    """What the original tolerated and what MAGNA does with it: a str reading `file: JSON.path: message`, as every
    warning reads, that keeps its parts (`source`, `path` as the file writes it, `message`) for callers that place
    it, such as an editor marking the field."""

    source: str
    path: str
    message: str

    def __new__(cls, source: str, path: str, message: str) -> WorldWarning:
        warning = super().__new__(cls, f"{located(source, path)}: {message}")
        warning.source, warning.path, warning.message = source, path, message
        return warning

    def __getnewargs__(self) -> tuple[str, str, str]:  # type: ignore[override]  # pickle and copy rebuild all three
        return self.source, self.path, self.message
