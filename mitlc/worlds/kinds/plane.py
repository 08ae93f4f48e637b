"""The plane kind: a world file with ``plane:``, a point robot in a continuous room
(:mod:`mitlc.worlds.plane`; its file's shape: :mod:`mitlc.worlds.plane_schema`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NoReturn

from pydantic import ValidationError

from mitlc.worlds import plane_schema
from mitlc.worlds.grid import FieldPath
from mitlc.worlds.plane import PlaneWorld, build_plane_world
from mitlc.worlds.plane_schema import PlaneWorldFile
from mitlc.worlds.source import Source, WorldError, message_of, require_labelled, task_of

NOT_FINITE = (
    "a continuous world is not a finite world: it cannot be checked exactly (learn it through "
    "the task wrapper: mitlc.worlds.plane_env.make_plane_env)"
)
"""Why a plane world is refused where a finite world is needed."""


def claims(data: Mapping[str, Any]) -> bool:
    """Whether a world file's mapping declares a continuous world (``plane:``)."""
    return "plane" in data


def validate(path: Path, source: Source) -> PlaneWorldFile:
    """A plane world file's shape and whole-file checks (:func:`plane_schema.check_file`)."""
    filename = str(path)
    try:
        world = PlaneWorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = []
        for p, m, k in _problems(err):
            if p in (("grid",), ("env",)) and m.startswith("unknown field"):
                m = "a world has one of grid:, env: or plane:, not two"
            problems.append(source.locate(p, m, key=k))
        raise WorldError(filename, problems) from None
    found = plane_schema.check_file(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world


def _problems(error: ValidationError) -> list[tuple[FieldPath, str, bool]]:
    """The pydantic errors of a plane world file, its unions' tags dropped from the path."""
    found = []
    for item in error.errors():
        loc, kind, ctx = item["loc"], item["type"], item.get("ctx") or {}
        at_key = loc[-1] == "[key]"
        tags = plane_schema.tag_positions(loc)
        path = tuple(x for i, x in enumerate(loc) if i not in tags and x != "[key]")
        if kind == "extra_forbidden":
            found.append((path, plane_schema.unknown_field(path), True))
        else:
            found.append((path, message_of(kind, item["msg"], item.get("input"), ctx), at_key))
    return found


@dataclass(frozen=True, slots=True)
class PlaneDeclaration:
    """A validated plane world file (see the module docstring)."""

    path: Path
    source: Source
    file: PlaneWorldFile
    kind = "plane"

    @staticmethod
    def read(path: Path, source: Source) -> PlaneDeclaration:
        """The declaration of the plane world file at ``path`` (its YAML read: ``source``)."""
        return PlaneDeclaration(path, source, validate(path, source))

    @property
    def name(self) -> str:
        """The world's name: the file's ``name``, else the file's stem."""
        return self.file.name or self.path.stem

    def finite(self, spec: str | None = None) -> NoReturn:
        """A :class:`WorldError` at ``plane``, once the world is found valid: it is not
        finite."""
        self.build(spec)
        raise WorldError(str(self.path), [self.source.locate(("plane",), NOT_FINITE, key=True)])

    def build(self, spec: str | None = None) -> PlaneWorld:
        """The world, its task replaced by ``spec`` (a formula's text) when given."""
        path, source, world = self.path, self.source, self.file
        text, spec_source, propositions = task_of(world, path, source, spec)
        missing = [p for p in propositions if p not in world.labels]
        told = (text, spec_source)
        require_labelled(path, source, told, missing, world.labels, "labels no region")
        built = build_plane_world(
            world, name=self.name, spec=text, spec_source=spec_source, propositions=propositions
        )
        return replace(built, training=dict(world.training))
