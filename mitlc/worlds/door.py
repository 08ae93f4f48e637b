"""The one door for worlds: a world file is read and validated once per command into a
declaration of its kind, and built once into a world.

``read_world(path)`` reads the file once (:func:`mitlc.worlds.source.read_mapping`), asks the
registered kinds (:mod:`mitlc.worlds.kinds`) which one it is, and validates it into that kind's
:class:`Declaration` (every problem with its field path, line and column). ``declaration.build``
makes the world (an env world makes its env once, to tell whether it is finite);
``declaration.finite`` makes the finite model or says why there is none. Everything after asks
the world (:class:`AnyWorld`): is it finite (:func:`is_finite`: a
:class:`~mitlc.worlds.model.World`), its observation model (``is_pomdp``), its env under the task
(``task_env``), its default learner (``default_algo``), its map (``drawing``), its ``training``
settings, never the file again.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeGuard

from mitlc.worlds.kinds import kind_for
from mitlc.worlds.model import Rewards, World
from mitlc.worlds.source import Source, WorldError, read_mapping

if TYPE_CHECKING:
    from mitlc.worlds.env_task import EnvTask
    from mitlc.worlds.plane import PlaneWorld
    from mitlc.worlds.schema import WorldFile


class AnyWorld(Protocol):
    """What every world offers, whatever its kind."""

    @property
    def name(self) -> str: ...
    @property
    def spec(self) -> str: ...
    @property
    def spec_source(self) -> str: ...
    @property
    def propositions(self) -> tuple[str, ...]: ...
    @property
    def horizon(self) -> int: ...
    @property
    def discount(self) -> float: ...
    @property
    def rewards(self) -> Rewards: ...
    @property
    def training(self) -> Mapping[str, Any]: ...
    @property
    def is_pomdp(self) -> bool: ...
    @property
    def default_algo(self) -> str: ...
    @property
    def drawing(self) -> Any: ...
    def task_env(self, automaton: Any, *, flatten: bool = False, **options: Any) -> Any:
        """A fresh gymnasium env of the world under its task (:class:`mitlc.gym.TaskWrapper`)."""
        ...


class Declaration(Protocol):
    """A validated world file of one kind."""

    @property
    def path(self) -> Path: ...
    @property
    def kind(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def file(self) -> Any:
        """The file's validated contents (its kind's pydantic model)."""
        ...

    @property
    def source(self) -> Source:
        """The file's YAML, to locate a problem at a field."""
        ...

    def build(self, spec: str | None = None) -> AnyWorld:
        """The world, its task replaced by ``spec`` (a formula's text) when given."""
        ...

    def finite(self, spec: str | None = None) -> World:
        """The finite world (a :class:`WorldError` saying why where there is none)."""
        ...


def read_world(path: str | Path) -> Declaration:
    """The declaration of the world file at ``path``: read once and validated by its kind; a
    :class:`WorldError` with every problem if it is bad."""
    path = Path(path)
    source = read_mapping(path)
    return kind_for(source.data).read(path, source)


def open_world(path: str | Path, spec: str | None = None) -> AnyWorld:
    """The world the file at ``path`` declares, its task replaced by ``spec`` (a formula's
    text) when given; a :class:`WorldError` naming the field if it is bad."""
    return read_world(path).build(spec)


def is_finite(world: AnyWorld) -> TypeGuard[World]:
    """Whether ``world`` is finite: its model can be checked, simulated and evaluated
    exactly."""
    return isinstance(world, World)


def load_world(path: str | Path, spec: str | None = None) -> World:
    """The finite world the file at ``path`` declares (``spec`` in place of its task); a
    :class:`WorldError` if it is bad or not finite (a continuous world, an env without a
    transition table)."""
    return read_world(path).finite(spec)


def _of_kind(path: str | Path, kind: str, needed: str) -> Declaration:
    declaration = read_world(path)
    if declaration.kind != kind:
        name, key = _KIND_NAMES.get(declaration.kind, (f"a {declaration.kind} world", ""))
        message = f"this is {name}, where {needed} is needed"
        where = declaration.source.locate((key,) if key else (), message, key=bool(key))
        raise WorldError(str(path), [where])
    return declaration


_KIND_NAMES = {
    "grid": ("a grid world", "grid"),
    "env": ("a gymnasium env world", "env"),
    "plane": ("a continuous world", "plane"),
    "team": ("a team world", "robots"),
    "pettingzoo": ("a PettingZoo env world", "pettingzoo"),
}


def load_plane_world(path: str | Path, spec: str | None = None) -> PlaneWorld:
    """The continuous world (``plane:``) at ``path``; a :class:`WorldError` if it is bad or
    of another kind."""
    from mitlc.worlds.plane import PlaneWorld

    world = _of_kind(path, "plane", "a continuous world (plane: ...)").build(spec)
    assert isinstance(world, PlaneWorld)
    return world


def load_env_task(path: str | Path, spec: str | None = None) -> EnvTask:
    """The env world at ``path`` as an env learned through the task wrapper, finite or not
    (its env made once); a :class:`WorldError` if it is bad or of another kind."""
    from mitlc.worlds.kinds.env import EnvDeclaration

    declaration = _of_kind(path, "env", "a gymnasium env world (env: ...)")
    assert isinstance(declaration, EnvDeclaration)
    return declaration.learned(spec)


def read_world_file(path: str | Path) -> WorldFile:
    """The validated contents of the grid world file at ``path``; a :class:`WorldError` if it
    is bad or of another kind."""
    file: WorldFile = _of_kind(path, "grid", "a grid world (grid: ...)").file
    return file


def read_any_world_file(path: str | Path) -> Any:
    """The validated contents of the world file at ``path``, of any kind (its pydantic
    model); a :class:`WorldError` if it is bad."""
    return read_world(path).file


__all__ = [
    "AnyWorld",
    "Declaration",
    "WorldError",
    "is_finite",
    "load_env_task",
    "load_plane_world",
    "load_world",
    "open_world",
    "read_any_world_file",
    "read_world",
    "read_world_file",
]
