"""Recorded traces for ``mitlc monitor``: the propositions true at each step, from CSV or JSONL.

CSV: a header row naming the propositions (a ``step`` or ``time`` column is ignored), then one
row per step with ``1``/``0`` or ``true``/``false``. JSON Lines: one value per step, either an
array of the true propositions (``["a"]``) or an object of truth values (``{"a": true}``).

Both forms follow one rule: a header or a step names a proposition at most once, and, read for
a spec (``propositions``), only the spec's propositions; a CSV trace, which declares its
propositions in its header, must also have a column for each of the spec's.

A trace is held to :data:`~mitlc.limits.MAX_TRACE_BYTES` (read no further),
:data:`~mitlc.limits.MAX_TRACE_STEPS` and, for JSON Lines,
:data:`~mitlc.limits.MAX_TRACE_JSON_DEPTH` (checked before a line is parsed); numbers are never
converted (no step holds one). Every error names the file, and the line where there is one.
"""

from __future__ import annotations

import csv
import io
import json
import operator
import re
from collections.abc import Collection, Iterable, Iterator
from itertools import accumulate, count
from pathlib import Path

from mitlc.errors import MitlcError
from mitlc.inputs import bad_utf8, read_head
from mitlc.limits import MAX_TRACE_BYTES, MAX_TRACE_JSON_DEPTH, MAX_TRACE_STEPS

_TRUE = {"1", "true", "yes", "t"}
_FALSE = {"0", "false", "no", "f", ""}
_IGNORED = {"step", "time", "t"}
_JSON_SUFFIXES = (".jsonl", ".json", ".ndjson")


class TraceError(MitlcError):
    """A trace file that cannot be read as CSV or JSON Lines."""


def read_trace_text(path: Path) -> str:
    """The text of the trace file at ``path``: read only as far as the size limit, UTF-8 (a
    byte-order mark is dropped)."""
    try:
        data, more = read_head(path, MAX_TRACE_BYTES)
    except OSError as err:
        raise TraceError(f"{path}: cannot read the trace: {err.strerror or err}") from None
    if more:
        raise TraceError(
            f"{path}: the trace is too large: more than {MAX_TRACE_BYTES:,} bytes (mitlc's limit)"
        )
    bad = bad_utf8(data, str(path))
    if bad is not None:
        message, at = bad
        raise TraceError(f"{path}:{at.line}:{at.column}: {message}; traces must be UTF-8 text")
    return data.decode("utf-8-sig")


def read_trace(
    path: Path, text: str | None = None, propositions: Collection[str] | None = None
) -> list[frozenset[str]]:
    """The letters of a trace file (JSON Lines when it ends in ``.jsonl``/``.json``, else CSV);
    ``text`` is the file's text when it has been read already. With ``propositions`` (a spec's),
    the trace may name no other, and a CSV trace needs a column for each."""
    if text is None:
        text = read_trace_text(path)
    known = None if propositions is None else frozenset(propositions)
    if path.suffix.lower() in _JSON_SUFFIXES:
        return _read_jsonl(path, text, known)
    return _read_csv(path, text, known)


def trace_columns(path: Path, text: str) -> set[str] | None:
    """The propositions a CSV trace declares (None for JSON Lines, which lists true ones)."""
    if path.suffix.lower() in _JSON_SUFFIXES:
        return None
    header = next(_csv_rows(path, text), (1, []))[1]
    return {name.strip() for name in header if not _ignored(name.strip())}


def _ignored(name: str) -> bool:
    """Whether the CSV column ``name`` is a step or time column, not a proposition."""
    return name.lower() in _IGNORED


def _check_names(
    path: Path, line: int, names: Iterable[str], known: frozenset[str] | None, what: str
) -> None:
    """The rule of both forms: ``names`` (those of a header or a step, line ``line``) name each
    proposition once, and only propositions in ``known`` (when given)."""
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise TraceError(f"{path}:{line}: {what} names {_shown(name)} twice")
        seen.add(name)
        if known is not None and name not in known:
            listed = f"its propositions: {', '.join(sorted(known))}" if known else "it has none"
            raise TraceError(
                f"{path}:{line}: {_shown(name)} is not a proposition of the spec ({listed})"
            )


class _Pairs:
    """A JSON object as its key-value pairs in order (a repeated key kept), never a step's
    dict until the keys are checked."""

    def __init__(self, pairs: list[tuple[str, object]]) -> None:
        self.pairs = pairs


class _Number:
    """What a JSON number becomes: never converted, and never a valid step."""


def _number(_: str) -> _Number:
    return _Number()


def _read_jsonl(path: Path, text: str, known: frozenset[str] | None) -> list[frozenset[str]]:
    letters: list[frozenset[str]] = []
    for number, line in enumerate(text.split("\n"), start=1):
        if not line.strip():
            continue
        if len(letters) == MAX_TRACE_STEPS:
            raise _too_many_steps(path, number)
        if _json_depth(line) > MAX_TRACE_JSON_DEPTH:
            raise TraceError(
                f"{path}:{number}: nested more than {MAX_TRACE_JSON_DEPTH} levels deep (mitlc's "
                "limit); a step is a list of true propositions or an object of true/false values"
            )
        try:
            value = json.loads(
                line,
                parse_int=_number,
                parse_float=_number,
                parse_constant=_number,
                object_pairs_hook=_Pairs,
            )
        except json.JSONDecodeError as err:
            raise TraceError(f"{path}:{number}: not JSON: {err.msg}") from None
        letters.append(_json_step(path, number, value, known))
    return letters


def _json_step(
    path: Path, number: int, value: object, known: frozenset[str] | None
) -> frozenset[str]:
    """The true propositions of the JSON Lines step ``value`` on line ``number``."""
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        names, true = value, value
    elif isinstance(value, _Pairs) and all(isinstance(v, bool) for _, v in value.pairs):
        names = [k for k, _ in value.pairs]
        true = [k for k, v in value.pairs if v]
    else:
        raise TraceError(
            f"{path}:{number}: expected a list of true propositions or an object of "
            "true/false values"
        )
    _check_names(path, number, names, known, "the step")
    return frozenset(true)


_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"')
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")
_STEPS = str.maketrans({"[": "\x02", "{": "\x02", "]": "\x00", "}": "\x00"})


def _json_depth(line: str) -> int:
    """How deep the brackets of a JSON line nest (strings aside), computed without recursion
    and without a Python loop over the characters."""
    if line.count("[") + line.count("{") <= MAX_TRACE_JSON_DEPTH:
        return 0  # too few to nest too deeply
    brackets = _NOT_BRACKET.sub("", _STRING.sub("", line)).translate(_STEPS).encode()
    # After k brackets the depth is opened - closed = 2 * opened - k = (sum of the codes) - k.
    return max(map(operator.sub, accumulate(brackets), count(1)), default=0)


def _csv_rows(path: Path, text: str) -> Iterator[tuple[int, list[str]]]:
    """The rows of a CSV trace with their line numbers; CSV errors become trace errors."""
    reader = csv.reader(io.StringIO(text, newline=""))
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as err:
            raise TraceError(f"{path}:{reader.line_num}: not CSV: {err}") from None
        yield reader.line_num, row


def _read_csv(path: Path, text: str, known: frozenset[str] | None) -> list[frozenset[str]]:
    rows = _csv_rows(path, text)
    first = next(rows, None)
    if first is None:
        raise TraceError(f"{path}: empty trace: expected a header row of propositions")
    header = [name.strip() for name in first[1]]
    _check_header(path, first[0], header, known)
    letters: list[frozenset[str]] = []
    for number, row in rows:
        if not any(cell.strip() for cell in row):
            continue
        if len(letters) == MAX_TRACE_STEPS:
            raise _too_many_steps(path, number)
        if len(row) != len(header):
            raise TraceError(f"{path}:{number}: {len(row)} values for {len(header)} columns")
        true = set()
        for name, cell in zip(header, row, strict=True):
            value = cell.strip().lower()
            if _ignored(name):
                continue
            if value in _TRUE:
                true.add(name)
            elif value not in _FALSE:
                raise TraceError(
                    f"{path}:{number}: column {_shown(name)}: expected 0/1, got {_shown(cell)}"
                )
        letters.append(frozenset(true))
    return letters


def _check_header(path: Path, line: int, header: list[str], known: frozenset[str] | None) -> None:
    """The header (ending on line ``line``) names each column once, a column for each of the
    spec's propositions (``known``, when given), and no proposition the spec does not have."""
    _check_names(path, line, header, None, "the header")
    if known is None:
        return
    columns = [name for name in header if not _ignored(name)]
    missing = sorted(known - set(columns))
    if missing:
        raise TraceError(f"{path}: no column for the spec's proposition(s) {', '.join(missing)}")
    _check_names(path, line, columns, known, "the header")


def _shown(text: str) -> str:
    """``text`` quoted as Python would, cut short when long."""
    return repr(text) if len(text) <= 40 else repr(text[:37]) + "..."


def _too_many_steps(path: Path, number: int) -> TraceError:
    return TraceError(
        f"{path}:{number}: the trace is too long: more than {MAX_TRACE_STEPS:,} steps "
        "(mitlc's limit)"
    )
