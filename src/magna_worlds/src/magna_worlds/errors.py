"""The one error a bad world file gets: which file, where in its JSON, what is wrong and how to fix it."""
from __future__ import annotations

from magna_common.json_fields import FieldError


class WorldError(FieldError):
    """Bad world input. str() reads `worlds/x.json: scenario.volumes[2].geometries[0].shape: unknown shape ...`."""
