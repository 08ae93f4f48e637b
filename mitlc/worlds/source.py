"""Reading a world file: its YAML, its problems with line and column, and what every kind of
world reads the same way (its task, its labels, its costs).

Three passes, each reporting every problem it finds before giving up: read the YAML (syntax
errors and duplicate keys, with line and column; :func:`read_yaml`), check its shape with the
pydantic models of its kind (:func:`from_pydantic` turns their errors into field paths), then
check what needs the whole file (cells inside the grid and free, adjacent sides, the spec and
its propositions: :func:`task_of`, :func:`require_labelled`). Every problem names the file, the
line and column, the field's path and the offending value:
``case1.yaml:4:13: labels.a[0]: cell [7, 2] is outside the 5x5 grid``. The kinds of world
(:mod:`mitlc.worlds.kinds`) read their files through these; :mod:`mitlc.worlds.door` is the
one door every command enters by.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from pydantic import BaseModel, ValidationError

from mitlc.errors import MitlcError, SpecError, locate
from mitlc.inputs import bad_utf8, read_head
from mitlc.limits import MAX_WORLD_BYTES
from mitlc.syntax import atoms, parse, read_spec
from mitlc.worlds import safe_yaml
from mitlc.worlds.costs import Costs, read_costs
from mitlc.worlds.env_schema import ENV_MODELS, EnvWorldFile
from mitlc.worlds.grid import FieldPath, render
from mitlc.worlds.schema import LABEL_TAGS, MODELS, OBSERVATION_TYPES, START_TAGS, WorldFile, show
from mitlc.worlds.trust import OutsideError, inside_folder

if TYPE_CHECKING:
    from mitlc.worlds.plane_schema import PlaneWorldFile


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
class Source:
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


def _marks(node: yaml.Node, path: FieldPath, source: Source, active: set[int]) -> None:
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


def read_yaml(path: Path, filename: str, kind: str = "world file") -> Source:
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
    source = Source(value, {}, {})
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
    ``env``: the error is of an env world file (:class:`~mitlc.worlds.env_schema.EnvWorldFile`)."""
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
            found.append((path, message_of(kind, item["msg"], item.get("input"), ctx), at_key))
    return found


def _grid_key(loc: tuple[str | int, ...]) -> tuple[str, ...]:
    """The key of :data:`~mitlc.worlds.schema.MODELS` at ``loc``: a list index, a label's or a
    priced proposition's name, as ``*``."""
    return tuple(
        "*"
        if isinstance(x, int)
        or (i == 2 and loc[:2] == ("costs", "propositions"))
        or (i == 1 and loc[0] == "labels")
        else x
        for i, x in enumerate(loc)
    )


def _is_tag(loc: tuple[str | int, ...], i: int) -> bool:
    """Whether ``loc[i]`` names a member of a union (pydantic puts it in the location)."""
    return (
        i == 1
        and loc[0] in ("observation", "spec")
        and loc[1] in (*OBSERVATION_TYPES, "path", "inline")
    ) or (
        (i == 1 and loc[0] == "start" and loc[1] in START_TAGS)
        or (i == 2 and loc[0] == "labels" and loc[2] in LABEL_TAGS)
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


def message_of(kind: str, msg: str, value: object, ctx: dict[str, Any]) -> str:
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


def read_mapping(path: Path) -> Source:
    """The world file's YAML, which must be a mapping."""
    filename = str(path)
    source = read_yaml(path, filename)
    if not isinstance(source.data, dict):
        got = "an empty file" if source.data is None else show(source.data)
        problem = Problem(f"expected a mapping of the world's fields, got {got}")
        raise WorldError(filename, [source.locate((), problem.message)])
    return source


def world_costs(
    world: WorldFile | EnvWorldFile,
    path: Path,
    source: Source,
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


def require_labelled(
    path: Path,
    source: Source,
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


def task_of(
    world: WorldFile | EnvWorldFile | PlaneWorldFile | Any,
    path: Path,
    source: Source,
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
