"""YAML to a validated :class:`~mitlc.worlds.model.World`.

A world file declares a grid (``grid:``) or names a finite gymnasium environment (``env:``,
:mod:`mitlc.worlds.gym_world`); the passes below are the grid's, and an env world file goes
through the same three (its whole-file checks in :func:`mitlc.worlds.gym_world.check_file`),
then has its env made and converted. A continuous world (``plane:``, :mod:`mitlc.worlds.plane`)
goes through the same three (:mod:`mitlc.worlds.plane_schema`) and becomes a
:class:`~mitlc.worlds.plane.PlaneWorld` (:func:`load_plane_world`); it is not finite, so
:func:`load_world` refuses it once it is found valid.

Three passes, each reporting every problem it finds before giving up: read the YAML (syntax
errors and duplicate keys, with line and column), check its shape with the pydantic models of
:mod:`mitlc.worlds.schema`, then check what needs the whole file (cells inside the grid and
free, adjacent sides, the spec and its propositions). Only then are the arrays built
(:mod:`mitlc.worlds.grid`). Every problem names the file, the line and column, the field's path
and the offending value: ``case1.yaml:4:13: labels.a[0]: cell [7, 2] is outside the 5x5 grid``.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ValidationError

from mitlc.errors import MitlcError, SpecError, locate
from mitlc.inputs import bad_utf8, read_head
from mitlc.limits import MAX_WORLD_BYTES
from mitlc.syntax import atoms, parse, read_spec
from mitlc.worlds import gym_world, plane_schema, safe_yaml
from mitlc.worlds.costs import Costs, action_problems, read_costs
from mitlc.worlds.grid import (
    FieldPath,
    Layout,
    check,
    local_pattern,
    noisy_cell,
    render,
    transitions,
)
from mitlc.worlds.model import Observations, World
from mitlc.worlds.plane import PlaneWorld, build_plane_world
from mitlc.worlds.plane_schema import PlaneWorldFile
from mitlc.worlds.schema import (
    ENV_MODELS,
    MODELS,
    OBSERVATION_TYPES,
    EnvWorldFile,
    LocalPattern,
    WorldFile,
    show,
)
from mitlc.worlds.trust import OutsideError, inside_folder


@dataclass(frozen=True, slots=True)
class Problem:
    """One thing wrong with a world file: where (line and column, 0 if unknown; the field's
    path, empty for the whole file), what, and an optional detail (a spec error's text)."""

    message: str
    path: FieldPath = ()
    line: int = 0
    column: int = 0
    detail: str = ""

    def render(self, filename: str) -> str:
        """``file:line:col: path: message``, then the detail on the next lines."""
        where = f"{filename}:{self.line}:{self.column}" if self.line else filename
        field = f"{render(self.path)}: " if self.path else ""
        return f"{where}: {field}{self.message}" + (f"\n{self.detail}" if self.detail else "")


class WorldError(MitlcError):
    """A world file that cannot be loaded; ``render()`` shows one problem per line, in the
    order of the file."""

    def __init__(self, filename: str, problems: Sequence[Problem]) -> None:
        self.filename = filename
        self.problems = tuple(sorted(problems, key=lambda p: (p.line, p.column)))
        super().__init__("\n".join(p.render(filename) for p in self.problems))


@dataclass
class _Source:
    """The parsed YAML and where each path starts (its value, and its key in a mapping)."""

    data: Any
    values: dict[FieldPath, yaml.Mark]
    keys: dict[FieldPath, yaml.Mark]

    def locate(self, path: FieldPath, message: str, detail: str = "", key: bool = False) -> Problem:
        """A problem at ``path``, at the line of the longest prefix of it in the file."""
        for end in range(len(path), -1, -1):
            mark = (self.keys if key else self.values).get(path[:end])
            if mark is not None:
                return Problem(message, path, mark.line + 1, mark.column + 1, detail)
        return Problem(message, path, detail=detail)


def _marks(node: yaml.Node, path: FieldPath, source: _Source, active: set[int]) -> None:
    if id(node) in active:  # a recursive alias
        return
    active.add(id(node))
    source.values[path] = node.start_mark
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            if isinstance(key, yaml.ScalarNode):
                source.keys[(*path, key.value)] = key.start_mark
                _marks(value, (*path, key.value), source, active)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _marks(item, (*path, i), source, active)
    active.discard(id(node))


def read_yaml(path: Path, filename: str, kind: str = "world file") -> _Source:
    """Read and parse the YAML at ``path`` (a ``kind``: "world file", "sweep file"); a
    :class:`WorldError` if it cannot (unreadable, larger than
    :data:`~mitlc.limits.MAX_WORLD_BYTES`, not UTF-8, not YAML, or beyond the limits of
    :mod:`mitlc.worlds.safe_yaml`)."""
    try:
        data, more = read_head(path, MAX_WORLD_BYTES)
    except OSError as err:
        problem = Problem(f"cannot read the {kind}: {err.strerror or err}")
        raise WorldError(filename, [problem]) from None
    if more:
        message = f"the {kind} is too large: more than {MAX_WORLD_BYTES:,} bytes (mitlc's limit)"
        raise WorldError(filename, [Problem(message)])
    bad = bad_utf8(data, filename)
    if bad is not None:
        message, loc = bad
        message += f"; {kind}s must be UTF-8 text"
        raise WorldError(filename, [Problem(message, (), loc.line, loc.column)])
    text = data.decode("utf-8-sig")
    try:
        value, node = safe_yaml.load(text)
    except yaml.MarkedYAMLError as err:
        raise WorldError(filename, [_yaml_problem(err, text, filename)]) from None
    except yaml.reader.ReaderError as err:  # a character YAML does not allow
        loc = locate(text, err.position, filename)
        char = err.character
        shown = f"U+{char:04X}" if isinstance(char, int) else repr(char)
        message = f"invalid YAML: the character {shown} is not allowed"
        raise WorldError(filename, [Problem(message, (), loc.line, loc.column)]) from None
    source = _Source(value, {}, {})
    if node is not None:
        _marks(node, (), source, set())
    return source


def _yaml_problem(err: yaml.MarkedYAMLError, text: str, filename: str) -> Problem:
    mark = err.problem_mark or err.context_mark
    line, column = (mark.line + 1, mark.column + 1) if mark else (0, 0)
    invalid = "" if isinstance(err, safe_yaml.YamlLimitError) else "invalid YAML: "
    message = f"{invalid}{err.problem or err.context}"
    if err.context and err.problem and err.context_mark:
        cm = err.context_mark
        message += f" ({err.context} at line {cm.line + 1}, column {cm.column + 1})"
    detail = locate(text, mark.index, filename).caret() if mark else ""
    return Problem(message, (), line, column, detail)


def from_pydantic(error: ValidationError, env: bool = False) -> list[tuple[FieldPath, str, bool]]:
    """Each error as (the field's path, a message in the file's words, whether it is about a
    key rather than a value); union tags and ``[key]`` markers are dropped from the path.
    ``env``: the error is of an env world file (:class:`~mitlc.worlds.schema.EnvWorldFile`)."""
    found = []
    is_tag = _is_env_tag if env else _is_tag
    for item in error.errors():
        loc, kind, ctx = item["loc"], item["type"], item.get("ctx") or {}
        at_key = loc[-1] == "[key]"
        path = tuple(x for i, x in enumerate(loc) if not is_tag(loc, i) and x != "[key]")
        if kind == "extra_forbidden":
            if env:
                model = _env_model(loc[:-1])
                fields = [f.alias or n for n, f in model.model_fields.items()]
            else:
                model = MODELS.get(_grid_key(loc[:-1]), WorldFile)
                fields = [f.alias or n for n, f in model.model_fields.items()]
            close = difflib.get_close_matches(str(loc[-1]), fields, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f" (known: {', '.join(fields)})"
            found.append((path, f"unknown field{hint}", True))
        elif kind in ("union_tag_invalid", "union_tag_not_found"):
            tags = " or ".join(map(repr, OBSERVATION_TYPES))
            got = show(ctx["tag"]) if "tag" in ctx else "nothing"
            found.append(((*path, "type"), f"expected {tags}, got {got}", kind.endswith("found")))
        else:
            found.append((path, _message(kind, item["msg"], item.get("input"), ctx), at_key))
    return found


def _grid_key(loc: tuple[str | int, ...]) -> tuple[str, ...]:
    """The key of :data:`~mitlc.worlds.schema.MODELS` at ``loc``: a list index, or a priced
    proposition's name, as ``*``."""
    return tuple(
        "*" if isinstance(x, int) or (i == 2 and loc[:2] == ("costs", "propositions")) else x
        for i, x in enumerate(loc)
    )


def _is_tag(loc: tuple[str | int, ...], i: int) -> bool:
    """Whether ``loc[i]`` names a member of a union (pydantic puts it in the location)."""
    return (
        i == 1
        and loc[0] in ("observation", "spec")
        and loc[1] in (*OBSERVATION_TYPES, "path", "inline")
    )


def _is_env_tag(loc: tuple[str | int, ...], i: int) -> bool:
    """:func:`_is_tag` for an env world file: the spec's kinds and a label's form."""
    return (i == 1 and loc[0] == "spec" and loc[1] in ("path", "inline")) or (
        i == 2 and loc[0] == "labels" and loc[2] in ("obs", "decoded")
    )


def _env_model(loc: tuple[str | int, ...]) -> type[BaseModel]:
    """The model of an env world file at ``loc`` (a label's name read as ``*``)."""
    key = tuple(
        "*"
        if (i == 1 and loc[0] == "labels")
        or (i == 2 and loc[:2] == ("costs", "propositions"))
        or isinstance(x, int)
        else str(x)
        for i, x in enumerate(loc)
    )
    return ENV_MODELS.get(key, EnvWorldFile)


def _message(kind: str, msg: str, value: object, ctx: dict[str, Any]) -> str:
    got = show(value)
    simple = {
        "missing": "required field is missing",
        "model_type": f"expected a mapping, got {got}",
        "model_attributes_type": f"expected a mapping, got {got}",
        "dict_type": f"expected a mapping, got {got}",
        "list_type": f"expected a list, got {got}",
        "string_type": f"expected a string, got {got}",
        "invalid_key": f"expected a field name (a string), got {got}",
    }
    if kind in simple:
        return simple[kind]
    if kind == "too_short":
        return f"expected at least {ctx['min_length']} item, got {got}"
    if kind == "literal_error":
        return f"expected {ctx['expected']}, got {got}"
    return msg if "got " in msg or kind.startswith("motion_") else f"{msg}, got {got}"


def read_world_file(path: str | Path) -> WorldFile:
    """The validated contents of the grid world file at ``path`` (shape and whole-file
    checks), ``training`` settings included; a :class:`WorldError` with every problem if it is
    bad, or if it is an env world file (see :func:`read_any_world_file`)."""
    return _read(Path(path))[0]


def read_any_world_file(path: str | Path) -> WorldFile | EnvWorldFile | PlaneWorldFile:
    """The validated contents of the world file at ``path``, a grid world, an env world (the
    env is not made: see :func:`load_world`) or a plane world; a :class:`WorldError` if it is
    bad."""
    path = Path(path)
    source = _mapping(path)
    if is_plane_file(source.data):
        return _read_plane(path, source)
    if is_env_file(source.data):
        return _read_env(path, source)
    return _read_grid(path, source)[0]


def kind_of(path: str | Path) -> Literal["grid", "env", "plane"]:
    """The kind of world the file at ``path`` declares: a grid (``grid:``), a gymnasium env
    (``env:``) or a continuous world (``plane:``); a :class:`WorldError` if it is not a
    readable mapping."""
    data = _mapping(Path(path)).data
    return "plane" if is_plane_file(data) else "env" if is_env_file(data) else "grid"


def is_env_world(path: str | Path) -> bool:
    """Whether the world file at ``path`` names a gymnasium env (a :class:`WorldError` if it is
    not a readable mapping)."""
    return is_env_file(_mapping(Path(path)).data)


def is_env_file(data: object) -> bool:
    """Whether a world file's YAML (its value) names a gymnasium env (``env:``) rather than a
    grid."""
    return isinstance(data, dict) and "env" in data


def is_plane_world(path: str | Path) -> bool:
    """Whether the world file at ``path`` declares a continuous world (``plane:``; a
    :class:`WorldError` if it is not a readable mapping)."""
    return is_plane_file(_mapping(Path(path)).data)


def is_plane_file(data: object) -> bool:
    """Whether a world file's YAML (its value) declares a continuous world (``plane:``)."""
    return isinstance(data, dict) and "plane" in data


def _mapping(path: Path) -> _Source:
    """The world file's YAML, which must be a mapping."""
    filename = str(path)
    source = read_yaml(path, filename)
    if not isinstance(source.data, dict):
        got = "an empty file" if source.data is None else show(source.data)
        problem = Problem(f"expected a mapping of the world's fields, got {got}")
        raise WorldError(filename, [source.locate((), problem.message)])
    return source


def _read(path: Path) -> tuple[WorldFile, Layout, _Source]:
    source = _mapping(path)
    if is_env_file(source.data):
        message = "this is a gymnasium env world, where a grid world (grid: ...) is needed"
        raise WorldError(str(path), [source.locate(("env",), message, key=True)])
    if is_plane_file(source.data):
        message = "this is a continuous world, where a grid world (grid: ...) is needed"
        raise WorldError(str(path), [source.locate(("plane",), message, key=True)])
    return _read_grid(path, source)


def _read_grid(path: Path, source: _Source) -> tuple[WorldFile, Layout, _Source]:
    filename = str(path)
    try:
        world = WorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = [source.locate(p, m, key=k) for p, m, k in from_pydantic(err)]
        raise WorldError(filename, problems) from None
    layout, found = check(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world, layout, source


def _read_env(path: Path, source: _Source) -> EnvWorldFile:
    """An env world file's shape and whole-file checks (:func:`gym_world.check_file`)."""
    filename = str(path)
    try:
        world = EnvWorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = []
        for p, m, k in from_pydantic(err, env=True):
            if p == ("grid",) and m.startswith("unknown field"):
                m = "a world has either grid: or env:, not both"
            problems.append(source.locate(p, m, key=k))
        raise WorldError(filename, problems) from None
    found = gym_world.check_file(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world


def _read_plane(path: Path, source: _Source) -> PlaneWorldFile:
    """A plane world file's shape and whole-file checks (:func:`plane_schema.check_file`)."""
    filename = str(path)
    try:
        world = PlaneWorldFile.model_validate(source.data)
    except ValidationError as err:
        problems = []
        for p, m, k in _plane_problems(err):
            if p in (("grid",), ("env",)) and m.startswith("unknown field"):
                m = "a world has one of grid:, env: or plane:, not two"
            problems.append(source.locate(p, m, key=k))
        raise WorldError(filename, problems) from None
    found = plane_schema.check_file(world)
    if found:
        raise WorldError(filename, [source.locate(p, m) for p, m in found])
    return world


def _plane_problems(error: ValidationError) -> list[tuple[FieldPath, str, bool]]:
    """:func:`from_pydantic` for a plane world file: its unions' tags dropped from the path."""
    found = []
    for item in error.errors():
        loc, kind, ctx = item["loc"], item["type"], item.get("ctx") or {}
        at_key = loc[-1] == "[key]"
        tags = plane_schema.tag_positions(loc)
        path = tuple(x for i, x in enumerate(loc) if i not in tags and x != "[key]")
        if kind == "extra_forbidden":
            found.append((path, plane_schema.unknown_field(path), True))
        else:
            found.append((path, _message(kind, item["msg"], item.get("input"), ctx), at_key))
    return found


def _load_plane(path: Path, source: _Source, task: str | None) -> PlaneWorld:
    """Build the world of a plane world file."""
    world = _read_plane(path, source)
    spec, spec_source, propositions = _load_spec(world, path, source, task)
    missing = [p for p in propositions if p not in world.labels]
    _require_labelled(path, source, (spec, spec_source), missing, world.labels, "labels no region")
    return build_plane_world(
        world,
        name=world.name or path.stem,
        spec=spec,
        spec_source=spec_source,
        propositions=propositions,
    )


def load_plane_world(path: str | Path, spec: str | None = None) -> PlaneWorld:
    """Load, validate and build the continuous world (``plane:``) at ``path``; a
    :class:`WorldError` if it is bad or not a plane world. ``spec`` replaces the file's task, as
    for :func:`load_world`."""
    path = Path(path)
    source = _mapping(path)
    if not is_plane_file(source.data):
        kind = "a gymnasium env world" if is_env_file(source.data) else "a grid world"
        message = f"this is {kind}, where a continuous world (plane: ...) is needed"
        raise WorldError(str(path), [source.locate((), message)])
    return _load_plane(path, source, spec)


NOT_FINITE_PLANE = (
    "a continuous world is not a finite world: it cannot be checked exactly (learn it through "
    "the task wrapper: mitlc.worlds.plane_env.make_plane_env)"
)
"""Why :func:`load_world` refuses a valid plane world."""


def _load_env_world(path: Path, source: _Source, task: str | None) -> World:
    """Build the world of an env world file: make the env and convert it."""
    filename = str(path)
    world = _read_env(path, source)
    spec, spec_source, propositions = _load_spec(world, path, source, task)
    missing = [p for p in propositions if p not in world.labels]
    _require_labelled(path, source, (spec, spec_source), missing, world.labels, "holds in no state")
    costs, propositions = _world_costs(world, path, source, propositions, None)
    try:
        env = gym_world.make_env(world.env, path.parent)
        try:
            built = gym_world.build_world(
                world,
                env,
                name=world.name or path.stem,
                spec=spec,
                spec_source=spec_source,
                propositions=propositions,
            )
        finally:
            env.close()
    except gym_world.GymWorldError as err:
        raise WorldError(filename, [source.locate(p, m) for p, m in err.found]) from None
    if costs is None:
        return built
    found = action_problems(costs, built.actions)
    if found:
        raise WorldError(filename, [source.locate(p, m, d) for p, m, d in found])
    return replace(built, costs=costs)


def _world_costs(
    world: WorldFile | EnvWorldFile,
    path: Path,
    source: _Source,
    task: tuple[str, ...],
    actions: Sequence[str] | None,
) -> tuple[Costs | None, tuple[str, ...]]:
    """The file's costs (:func:`mitlc.worlds.costs.read_costs`; a :class:`WorldError` with
    every problem), and the world's propositions: the ``task``'s and those the costs read."""
    if world.costs is None:
        return None, task

    def where(field: FieldPath) -> str:
        return source.locate(field, "").render(str(path)).removesuffix(": ")

    costs, found = read_costs(world.costs, world.labels.keys(), task, actions, where)
    if found:
        raise WorldError(str(path), [source.locate(p, m, d) for p, m, d in found])
    return costs, tuple(sorted(set(task) | costs.atoms()))


def load_world(path: str | Path, spec: str | None = None) -> World:
    """Load, validate and build the world at ``path``; a :class:`WorldError` if it is bad.

    ``spec`` (a formula's text, which must parse: a :class:`mitlc.errors.SpecError` otherwise)
    replaces the file's task; its propositions are labelled from the file's ``labels`` as the
    file's own spec's would be.

    A world file naming a gymnasium env (``env:``) is converted by
    :mod:`mitlc.worlds.gym_world`: an env without a transition table is a :class:`WorldError`
    at ``env.id`` (not a finite world). A continuous world (``plane:``) is a
    :class:`WorldError` at ``plane``, once every problem of the file is reported: it is not
    finite (:func:`load_plane_world` loads it)."""
    path = Path(path)
    source = _mapping(path)
    if is_plane_file(source.data):
        _load_plane(path, source, spec)
        raise WorldError(str(path), [source.locate(("plane",), NOT_FINITE_PLANE, key=True)])
    if is_env_file(source.data):
        return _load_env_world(path, source, spec)
    world, layout, source = _read_grid(path, source)
    spec, spec_source, propositions = _load_spec(world, path, source, spec)
    cells = layout.cells()
    labelled = {p: set(world.labels.get(p, ())) for p in propositions}
    missing = [p for p in propositions if not labelled[p]]
    _require_labelled(path, source, (spec, spec_source), missing, world.labels, "labels no cell")
    costs, propositions = _world_costs(world, path, source, propositions, world.actions)
    labelled = {p: set(world.labels.get(p, ())) for p in propositions}
    letters = [
        sum(1 << i for i, p in enumerate(propositions) if cell in labelled[p]) for cell in cells
    ]
    observations: Observations | None = None
    if isinstance(world.observation, LocalPattern):
        observations = local_pattern(layout)
    elif world.observation is not None:
        observations = noisy_cell(
            layout, world.observation.correct, world.observation.neighbourhood
        )
    reward = world.reward
    return World(
        name=world.name or path.stem,
        rows=layout.rows,
        cols=layout.cols,
        cells=cells,
        actions=tuple(world.actions),
        start=cells.index(world.start),
        transitions=transitions(layout, world.actions, world.motion),
        propositions=propositions,
        letters=np.asarray(letters, dtype=np.int64),
        spec=spec,
        spec_source=spec_source,
        horizon=world.horizon,
        discount=world.discount,
        rewards=reward.rewards(),
        observations=observations,
        costs=costs,
    )


def _require_labelled(
    path: Path,
    source: _Source,
    task: tuple[str, str],
    missing: list[str],
    labels: Iterable[str],
    where: str,
) -> None:
    """A :class:`WorldError` naming each proposition of the task (``(text, source)``) that no
    label declares (``where``: "labels no cell", ...): at the file's ``spec`` field, or, for a
    task given in its place, naming that task."""
    if not missing:
        return
    spec, spec_source = task
    known = ", ".join(sorted(labels)) or "none"
    problems = []
    for p in missing:
        what = f"proposition {p!r} {where} (labels: {known})"
        if spec_source == "<spec>":
            problems.append(Problem(f"the task {spec!r}: {what}"))
        else:
            problems.append(source.locate(("spec",), what))
    raise WorldError(str(path), problems)


def _reason(err: OSError | ValueError) -> str:
    return (err.strerror if isinstance(err, OSError) else None) or str(err)


def _load_spec(
    world: WorldFile | EnvWorldFile | PlaneWorldFile,
    path: Path,
    source: _Source,
    task: str | None = None,
) -> tuple[str, str, tuple[str, ...]]:
    """The spec's text, where it came from, and its propositions (sorted); ``task``, when given,
    in place of the file's."""
    filename = str(path)
    if task is not None:
        return task, "<spec>", atoms(parse(task, "<spec>"))
    if isinstance(world.spec, str):
        where: FieldPath = ("spec",)
        try:
            inside = inside_folder(path.parent, world.spec)  # never read where it is not
        except OutsideError as err:
            message = f"the spec file {show(world.spec)} is refused: {err}"
            raise WorldError(filename, [source.locate(where, message)]) from None
        spec_path = path.parent / world.spec  # as written, for the messages
        try:
            text = read_spec(inside)
            formula = parse(text, str(spec_path))
        except (OSError, ValueError) as err:  # ValueError: a NUL in the path
            reason = "not found" if isinstance(err, FileNotFoundError) else _reason(err)
            shown = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(spec_path))
            message = f"cannot read the spec file {show(world.spec)} ({shown}): {reason}"
            raise WorldError(filename, [source.locate(where, message)]) from None
        except SpecError as err:
            problem = source.locate(
                where, f"the spec file {show(world.spec)} does not parse", err.render()
            )
            raise WorldError(filename, [problem]) from None
        return text, str(spec_path), atoms(formula)
    text, where = world.spec.formula, ("spec", "formula")
    try:
        formula = parse(text, "<spec.formula>")
    except SpecError as err:
        problem = source.locate(where, "the formula does not parse", err.render())
        raise WorldError(filename, [problem]) from None
    return text, "<inline>", atoms(formula)
