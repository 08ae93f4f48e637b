"""Loading a world file: the names of :mod:`mitlc.worlds.door` (the one door: read once,
build once) and :mod:`mitlc.worlds.source` (its YAML and its problems), kept here for the
callers that know them by this module."""

from __future__ import annotations

from mitlc.worlds.door import (
    is_finite,
    load_env_task,
    load_plane_world,
    load_world,
    open_world,
    read_any_world_file,
    read_world,
    read_world_file,
)
from mitlc.worlds.source import (
    Problem,
    Source,
    WorldError,
    from_pydantic,
    read_mapping,
    read_yaml,
    require_labelled,
    task_of,
    world_costs,
)

__all__ = [
    "Problem",
    "Source",
    "WorldError",
    "from_pydantic",
    "is_finite",
    "load_env_task",
    "load_plane_world",
    "load_world",
    "open_world",
    "read_any_world_file",
    "read_mapping",
    "read_world",
    "read_world_file",
    "read_yaml",
    "require_labelled",
    "task_of",
    "world_costs",
]
