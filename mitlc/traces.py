"""Recorded traces for ``mitlc monitor``: the propositions true at each step, from CSV or JSONL.

CSV: a header row naming the propositions (a ``step`` or ``time`` column is ignored), then one
row per step with ``1``/``0`` or ``true``/``false``. JSON Lines: one value per step, either an
array of the true propositions (``["a"]``) or an object of truth values (``{"a": true}``).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from mitlc.errors import MitlcError

_TRUE = {"1", "true", "yes", "t"}
_FALSE = {"0", "false", "no", "f", ""}
_IGNORED = {"step", "time", "t"}


class TraceError(MitlcError):
    """A trace file that cannot be read as CSV or JSON Lines."""


def read_trace(path: Path, text: str | None = None) -> list[frozenset[str]]:
    """The letters of a trace file (JSON Lines when it ends in ``.jsonl``/``.json``, else CSV)."""
    if text is None:
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as err:
            raise TraceError(f"{path}: not UTF-8 text ({err.reason})") from None
    if path.suffix.lower() in (".jsonl", ".json", ".ndjson"):
        return _read_jsonl(path, text)
    return _read_csv(path, text)


def _read_jsonl(path: Path, text: str) -> list[frozenset[str]]:
    letters = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            value = json.loads(line)
        except json.JSONDecodeError as err:
            raise TraceError(f"{path}:{number}: not JSON: {err.msg}") from None
        if isinstance(value, list) and all(isinstance(v, str) for v in value):
            letters.append(frozenset(value))
        elif isinstance(value, dict) and all(isinstance(v, bool) for v in value.values()):
            letters.append(frozenset(k for k, v in value.items() if v))
        else:
            raise TraceError(
                f"{path}:{number}: expected a list of true propositions or an object of "
                "true/false values"
            )
    return letters


def _read_csv(path: Path, text: str) -> list[frozenset[str]]:
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise TraceError(f"{path}: empty trace: expected a header row of propositions")
    header = [name.strip() for name in rows[0]]
    letters = []
    for number, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != len(header):
            raise TraceError(f"{path}:{number}: {len(row)} values for {len(header)} columns")
        true = set()
        for name, cell in zip(header, row, strict=True):
            value = cell.strip().lower()
            if name.lower() in _IGNORED:
                continue
            if value in _TRUE:
                true.add(name)
            elif value not in _FALSE:
                raise TraceError(f"{path}:{number}: column {name!r}: expected 0/1, got {cell!r}")
        letters.append(frozenset(true))
    return letters


def trace_columns(path: Path, text: str) -> set[str] | None:
    """The propositions a CSV trace declares (None for JSON Lines, which lists true ones)."""
    if path.suffix.lower() in (".jsonl", ".json", ".ndjson"):
        return None
    first = text.splitlines()[0] if text.strip() else ""
    return {name.strip() for name in next(csv.reader([first]))} - _IGNORED
