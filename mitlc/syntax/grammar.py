"""Loading the grammar ``grammars/mitl.lark``, the one copy, shipped inside the wheel."""

from __future__ import annotations

import functools
from pathlib import Path

import lark

GRAMMAR_NAME = "mitl.lark"


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


@functools.cache
def lalr_parser() -> lark.Lark:
    """The LALR(1) parser built from the grammar (built once per process)."""
    return lark.Lark(
        grammar_text(),
        parser="lalr",
        lexer="contextual",
        propagate_positions=True,
        maybe_placeholders=True,
    )
