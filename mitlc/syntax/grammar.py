"""Loading the grammar ``grammars/mitl.lark``, the one copy, shipped inside the wheel.

Building Lark's LALR(1) tables from the grammar takes about 30 ms, a sixth of the command
line's start-up. ``grammars/mitl.lalr.json`` holds those tables as plain JSON data (Lark's own
serialisation of the built parser, which names only Lark's classes; never a pickle), stamped
with a hash of the grammar's text, Lark's version and the parser options. A parser is loaded
from them only when the stamp matches; otherwise it is built from the grammar, so a stale file
costs time, never correctness. ``tests/test_syntax.py`` holds the file equal to what the
grammar gives (rewritten with ``pytest --update-golden``).
"""

from __future__ import annotations

import functools
import hashlib
import json
from pathlib import Path
from typing import Any

import lark

GRAMMAR_NAME = "mitl.lark"
TABLES_NAME = "mitl.lalr.json"
OPTIONS: dict[str, Any] = {
    "parser": "lalr",
    "lexer": "contextual",
    "propagate_positions": True,
    "maybe_placeholders": True,
}
_TUPLE, _INT_KEYS = "\u0000tuple", "\u0000int-keys"
"""Markers of what JSON has not: a tuple, and a dict with integer keys."""


def grammar_path() -> Path:
    """Where the grammar is read from: inside the installed package, else the source checkout.

    The wheel carries ``grammars/mitl.lark`` as ``mitlc/grammars/mitl.lark``; an editable
    install or a plain checkout reads the top-level ``grammars/`` directory. (The package's
    directory is found from this file, as ``importlib.resources`` would, without importing it:
    part of the command line's start-up.)
    """
    packaged = Path(__file__).parents[1] / "grammars" / GRAMMAR_NAME
    if packaged.is_file():
        return packaged
    checkout = Path(__file__).resolve().parents[2] / "grammars" / GRAMMAR_NAME
    if checkout.is_file():
        return checkout
    raise FileNotFoundError(f"the MITL grammar {GRAMMAR_NAME} is missing from the installation")


def grammar_text() -> str:
    """The text of the grammar."""
    return grammar_path().read_text(encoding="utf-8")


def _stamp(text: str) -> str:
    """What the tables depend on: the grammar, Lark's version and the options."""
    basis = json.dumps([text, lark.__version__, OPTIONS], sort_keys=True)
    return hashlib.sha256(basis.encode()).hexdigest()


def build_parser() -> lark.Lark:
    """The LALR(1) parser built from the grammar's text."""
    return lark.Lark(grammar_text(), **OPTIONS)


def tables_text(parser: lark.Lark) -> str:
    """The JSON text of ``parser``'s tables, stamped for the current grammar."""
    data, memo = parser.memo_serialize([lark.lexer.TerminalDef, lark.grammar.Rule])
    stamped = {"stamp": _stamp(grammar_text()), "data": data, "memo": memo}
    return json.dumps(_encode(stamped), indent=None, separators=(",", ":")) + "\n"


def _encode(value: Any) -> Any:
    if isinstance(value, tuple):
        return {_TUPLE: [_encode(v) for v in value]}
    if isinstance(value, list):
        return [_encode(v) for v in value]
    if isinstance(value, dict):
        if any(not isinstance(k, str) for k in value):
            return {_INT_KEYS: [[k, _encode(v)] for k, v in value.items()]}
        return {k: _encode(v) for k, v in value.items()}
    return value


def _decode(value: dict[str, Any]) -> Any:
    if _TUPLE in value:
        return tuple(value[_TUPLE])
    if _INT_KEYS in value:
        return {int(k): v for k, v in value[_INT_KEYS]}
    return value


@functools.cache
def lalr_parser() -> lark.Lark:
    """The LALR(1) parser of the grammar (made once per process): loaded from the stored tables
    when they are the grammar's (module docstring), else built."""
    tables = grammar_path().with_name(TABLES_NAME)
    if tables.is_file():
        stored = json.loads(tables.read_text(encoding="utf-8"), object_hook=_decode)
        if stored.get("stamp") == _stamp(grammar_text()):
            parser: lark.Lark = lark.Lark._load_from_dict(  # type: ignore[no-untyped-call]
                stored["data"], stored["memo"]
            )
            return parser
    return build_parser()
