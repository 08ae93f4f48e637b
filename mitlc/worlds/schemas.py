"""The JSON schemas of the kinds of world file, for editors and other tools."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from mitlc.worlds.env_schema import EnvWorldFile
from mitlc.worlds.plane_schema import PlaneWorldFile
from mitlc.worlds.schema import WorldFile
from mitlc.worlds.team_schema import TeamWorldFile


def world_json_schema(kind: str = "world") -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of a grid world file (``world``), a gymnasium env world
    file (``env-world``), a continuous world file (``plane-world``) or a team of robots on a
    grid (``team-world``), for editors and other tools; a ``KeyError`` for another kind."""
    models: dict[str, type[BaseModel]] = {
        "world": WorldFile,
        "env-world": EnvWorldFile,
        "plane-world": PlaneWorldFile,
        "team-world": TeamWorldFile,
    }
    model = models[kind]
    schema = model.model_json_schema()
    labels = schema["properties"]["labels"]
    if "patternProperties" in labels:
        labels["additionalProperties"] = False  # names must match the pattern
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "mitlc " + kind.replace("-", " ")
    return schema


SCHEMA_KINDS = ("world", "env-world", "plane-world", "team-world")
"""The kinds of :func:`world_json_schema`."""
