"""YAML to a team :class:`~mitlc.worlds.model.World` (the semantics: :mod:`mitlc.worlds.team`).

The three passes of every world file (:mod:`mitlc.worlds.load`): read the YAML, check its shape
(:class:`~mitlc.worlds.team_schema.TeamWorldFile`), check what needs the whole file
(:func:`~mitlc.worlds.team.check_team`, the spec and its propositions), then build. Every
problem names the file, the line and column, the field's path and the offending value:
``two-robots.yaml:12:21: robots.robot_1.start: cell [0, 0] is robot 'robot_0''s start too``.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from mitlc.limits import MAX_TEAM_TRANSITIONS
from mitlc.worlds.grid import FieldPath, Layout
from mitlc.worlds.model import World
from mitlc.worlds.schema import OBSERVATION_TYPES
from mitlc.worlds.source import (
    Source,
    WorldError,
    from_pydantic,
    read_mapping,
    require_labelled,
    task_of,
)
from mitlc.worlds.team import TeamError, build_team_world, check_team, meanings
from mitlc.worlds.team_schema import TEAM_MODELS, TeamWorldFile

MOVED = {
    "start": "a team world gives each robot its start (robots.<id>.start), not start:",
    "observation": "a team world gives each robot its observation (robots.<id>.observation), "
    "not observation:",
    "costs": "a team world has no costs: yet",
}
"""Grid fields a team file does not have, and what to write instead."""


def claims(data: Mapping[str, Any]) -> bool:
    """Whether a world file's mapping declares a team of robots (``robots:``)."""
    return "robots" in data


def is_team_file(data: object) -> bool:
    """Whether a world file's YAML (its value) declares a team of robots (``robots:``)."""
    return isinstance(data, dict) and claims(data)


def validate(path: Path, source: Source) -> tuple[TeamWorldFile, Layout]:
    """The team file's shape (pydantic) and its whole-file checks
    (:func:`~mitlc.worlds.team.check_team`); a :class:`WorldError` with every problem."""
    filename = str(path)
    try:
        world = TeamWorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = [source.locate(p, m, key=k) for p, m, k in shape_problems(err)]
        raise WorldError(filename, problems) from None
    layout, found = check_team(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world, layout


def shape_problems(error: ValidationError) -> list[tuple[FieldPath, str, bool]]:
    """:func:`~mitlc.worlds.load.from_pydantic` for a team file: a robot's observation tag
    dropped from the path, and an unknown field's hint from the team file's own models."""
    found = []
    for item, (path, message, at_key) in zip(error.errors(), from_pydantic(error), strict=True):
        loc = item["loc"]
        if len(path) > 3 and path[0] == "robots" and path[3] in OBSERVATION_TYPES:
            path = (*path[:3], *path[4:])
        if item["type"] == "extra_forbidden":
            message = _unknown(loc)
        found.append((path, message, at_key))
    return found


def _unknown(loc: tuple[str | int, ...]) -> str:
    """An unknown field's message, with the closest known field of the model it is in."""
    name = str(loc[-1])
    if len(loc) == 1 and name in MOVED:
        return f"unknown field: {MOVED[name]}"
    key = tuple("*" if (i == 1 and loc[0] == "robots") else str(x) for i, x in enumerate(loc[:-1]))
    model = TEAM_MODELS.get(key, TeamWorldFile)
    fields = [f.alias or n for n, f in model.model_fields.items()]
    close = difflib.get_close_matches(name, fields, n=1)
    return "unknown field" + (
        f"; did you mean {close[0]!r}?" if close else f" (known: {', '.join(fields)})"
    )


@dataclass(frozen=True, slots=True)
class TeamDeclaration:
    """A validated team world file (a declaration of :mod:`mitlc.worlds.door`'s kind
    ``team``: ``Kind("team", claims, TeamDeclaration.read)``, asked before the grid)."""

    path: Path
    source: Source
    file: TeamWorldFile
    layout: Layout
    limit: int = MAX_TEAM_TRANSITIONS
    kind = "team"

    @staticmethod
    def read(path: Path, source: Source) -> TeamDeclaration:
        """The declaration of the team file at ``path`` (its YAML already read: ``source``)."""
        return TeamDeclaration(path, source, *validate(path, source))

    @property
    def name(self) -> str:
        """The world's name: the file's ``name``, else the file's stem."""
        return self.file.name or self.path.stem

    def finite(self, spec: str | None = None) -> World:
        """The joint world: a team on a grid is finite."""
        return self.build(spec)

    def build(self, spec: str | None = None) -> World:
        """The joint world, its task replaced by ``spec`` (a formula's text) when given; a
        :class:`WorldError` if the task reads a proposition the file does not label, or the
        joint tables would have more than ``limit`` entries (at ``robots``)."""
        path, source, world = self.path, self.source, self.file
        text, spec_source, propositions = task_of(world, path, source, spec)
        known, _ = meanings(world)
        robots = list(world.robots.values())

        def labels_a_cell(name: str) -> bool:
            meaning = known[name]
            if meaning.kind == "collision":
                return True
            own = robots[meaning.robot].labels if meaning.kind == "robot" else {}
            return bool(world.labels.get(meaning.label) or own.get(meaning.label))

        missing = [p for p in propositions if p not in known or not labels_a_cell(p)]
        labelled = [p for p in known if labels_a_cell(p)]
        told = (text, spec_source)
        require_labelled(path, source, told, missing, labelled, "labels no cell of any robot")
        try:
            return build_team_world(
                world,
                self.layout,
                name=self.name,
                spec=text,
                spec_source=spec_source,
                propositions=propositions,
                limit=self.limit,
            )
        except TeamError as err:
            problems = [source.locate(p, m, key=True) for p, m in err.found]
            raise WorldError(str(path), problems) from None


def read_team_file(path: str | Path) -> TeamDeclaration:
    """The validated team file at ``path``; a :class:`WorldError` with every problem if it
    is bad or not a team file."""
    path = Path(path)
    source = read_mapping(path)
    if not is_team_file(source.data):
        message = "this is not a team world: a team world declares its robots (robots: ...)"
        raise WorldError(str(path), [source.locate((), message)])
    return TeamDeclaration.read(path, source)


def load_team_world(
    path: str | Path, spec: str | None = None, *, limit: int = MAX_TEAM_TRANSITIONS
) -> World:
    """Load, validate and build the team world at ``path``; a :class:`WorldError` if it is
    bad, its task reads a proposition it does not label, or its joint tables would have more
    than ``limit`` entries (at ``robots``). ``spec`` (a formula's text) replaces the file's
    task, as for :func:`mitlc.worlds.load.load_world`."""
    declaration = read_team_file(path)
    if limit != declaration.limit:
        declaration = TeamDeclaration(
            declaration.path, declaration.source, declaration.file, declaration.layout, limit
        )
    return declaration.build(spec)
