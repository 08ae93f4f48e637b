"""The kinds of world, registered once: each is one module whose ``claims`` says whether a
world file's mapping is of its kind and whose declaration reads, validates and builds it
(:mod:`mitlc.worlds.door` is the door every command enters by).

A new kind is one module here and one line in :data:`KINDS`; callers ask the world it builds
(:class:`mitlc.worlds.door.AnyWorld`), never the file.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mitlc.worlds.kinds import env, grid, pettingzoo, plane, team

if TYPE_CHECKING:
    from mitlc.worlds.door import Declaration
    from mitlc.worlds.source import Source


@dataclass(frozen=True, slots=True)
class Kind:
    """A kind of world: its name, which files it claims, and how it reads one."""

    name: str
    claims: Callable[[Mapping[str, Any]], bool]
    read: Callable[[Path, Source], Declaration]


KINDS: tuple[Kind, ...] = (
    Kind("plane", plane.claims, plane.PlaneDeclaration.read),
    Kind("pettingzoo", pettingzoo.claims, pettingzoo.PettingZooDeclaration.read),
    Kind("env", env.claims, env.EnvDeclaration.read),
    Kind("team", team.claims, team.TeamDeclaration.read),
    Kind("grid", grid.claims, grid.GridDeclaration.read),
)
"""The kinds, in the order they are asked; the last (the grid) claims every mapping."""


def kind_for(data: Mapping[str, Any]) -> Kind:
    """The first kind that claims a world file's mapping."""
    return next(kind for kind in KINDS if kind.claims(data))
