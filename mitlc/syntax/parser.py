"""Parse MITL text into the AST: ``parse(text) -> Formula``.

Three passes, as in the field's parsers: Lark's LALR(1) parser builds a parse tree; a separate
pass checks and normalises the intervals (half-open to closed, reversed or negative bounds,
``inf`` as a lower bound); a transformer builds the immutable AST with source spans. Lark's
errors are wrapped in :class:`~mitlc.errors.SpecSyntaxError` with a location and a message that
says what was expected (see :mod:`mitlc.syntax.diagnostics`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lark
from lark import Token, Transformer, Tree, v_args

from mitlc.errors import SpecSemanticError, SpecSyntaxError, locate
from mitlc.syntax import ast
from mitlc.syntax.diagnostics import empty_spec_error, syntax_error
from mitlc.syntax.grammar import lalr_parser

DEFAULT_FILENAME = "<formula>"


def parse(text: str, filename: str = DEFAULT_FILENAME) -> ast.Formula:
    """Parse one MITL formula.

    Raises :class:`SpecSyntaxError` when ``text`` is not a formula, and
    :class:`SpecSemanticError` when an interval is reversed, negative or empty.
    """
    try:
        tree = lalr_parser().parse(text)
    except lark.exceptions.UnexpectedInput as err:
        raise syntax_error(err, text, filename) from None
    except lark.exceptions.LarkError as err:  # pragma: no cover - Lark's own failures
        raise SpecSyntaxError(str(err), locate(text, 0, filename)) from None
    intervals = {
        _offset(_raw(node).opener): _check_interval(node, text, filename)
        for node in tree.find_data("interval")
    }
    return _ToAst(intervals).transform(tree)


def parse_bytes(data: bytes, filename: str = DEFAULT_FILENAME) -> ast.Formula:
    """Parse a formula from UTF-8 bytes; bytes that are not UTF-8 are a syntax error."""
    return parse(decode(data, filename), filename)


def parse_file(path: str | Path) -> ast.Formula:
    """Parse the spec file at ``path``."""
    path = Path(path)
    return parse_bytes(path.read_bytes(), str(path))


def decode(data: bytes, filename: str) -> str:
    """Decode UTF-8 (a leading byte-order mark is dropped), locating the first bad byte."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        good = data[: err.start].decode("utf-8", errors="replace")
        shown = good + data[err.start :].decode("utf-8", errors="replace")
        location = locate(shown, len(good), filename)
        raise SpecSyntaxError(
            f"invalid UTF-8: byte 0x{data[err.start]:02x} cannot start or continue a character; "
            "specs must be UTF-8 text",
            location,
        ) from None
    if not text.strip():
        raise empty_spec_error(text, filename)
    return text


# --- the interval pass ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _RawInterval:
    tree: Tree[Token]
    opener: Token
    lo: Token
    sep: Token
    hi: Token | None
    closer: Token


def _raw(node: Tree[Token]) -> _RawInterval:
    opener, lo, sep, hi, closer = node.children
    assert isinstance(opener, Token) and isinstance(lo, Token) and isinstance(sep, Token)
    assert isinstance(closer, Token) and (hi is None or isinstance(hi, Token))
    return _RawInterval(node, opener, lo, sep, hi, closer)


def _bound_value(token: Token, text: str, filename: str) -> int:
    value = int("".join(str(token).split()))
    if value < 0:
        raise SpecSemanticError(
            f"interval bounds must be non-negative integers, found {value}",
            locate(text, _offset(token), filename),
        )
    return value


def _offset(token: Token) -> int:
    return token.start_pos if token.start_pos is not None else 0


def _check_interval(node: Tree[Token], text: str, filename: str) -> ast.Interval:
    """Check one parsed interval and normalise it to a closed integer :class:`ast.Interval`."""
    raw = _raw(node)
    if raw.lo.type == "INF":
        raise SpecSemanticError(
            "'inf' cannot be a lower bound; write [a,inf) for 'from a on'",
            locate(text, _offset(raw.lo), filename),
        )
    lo = _bound_value(raw.lo, text, filename)
    if raw.hi is None and str(raw.sep) == ",":
        raise SpecSemanticError(
            f"expected an interval bound (an integer or 'inf'), found '{raw.closer}'",
            locate(text, _offset(raw.closer), filename),
        )
    hi: int | None = None
    if raw.hi is not None and raw.hi.type == "INT":
        hi = _bound_value(raw.hi, text, filename)
        if hi < lo:
            raise SpecSemanticError(
                f"reversed interval bounds: the lower bound {lo} exceeds the upper bound {hi}",
                locate(text, _offset(raw.lo), filename),
            )
    if raw.opener.type == "LOPEN":
        lo += 1
    if hi is not None and raw.closer.type == "RPAR":
        hi -= 1
    if hi is not None and hi < lo:
        written = text[_offset(raw.opener) : raw.closer.end_pos]
        raise SpecSemanticError(
            f"empty interval '{written}': it contains no integer delay",
            locate(text, _offset(raw.opener), filename),
        )
    return ast.Interval(lo, hi)


# --- the AST transformer -------------------------------------------------------------------------


def _span(meta: Any) -> ast.Span:
    if getattr(meta, "empty", True):
        return ast.NO_SPAN
    return ast.Span(meta.start_pos, meta.end_pos, meta.line, meta.column)


def _token_span(token: Token) -> ast.Span:
    return ast.Span(_offset(token), token.end_pos or 0, token.line or 0, token.column or 0)


@v_args(meta=True)
class _ToAst(Transformer[Token, ast.Formula]):
    """Builds the AST from the parse tree; intervals come from the interval pass."""

    def __init__(self, intervals: dict[int, ast.Interval]) -> None:
        super().__init__(visit_tokens=False)
        self._intervals = intervals  # keyed by the offset of the interval's opening bracket

    @staticmethod
    def _interval(node: ast.Interval | None) -> ast.Interval:
        return ast.UNBOUNDED if node is None else node

    def interval(self, meta: Any, children: list[Any]) -> ast.Interval:
        return self._intervals[_offset(children[0])]

    def start(self, meta: Any, children: list[ast.Formula]) -> ast.Formula:
        return children[0]

    def group(self, meta: Any, children: list[Any]) -> ast.Formula:
        formula: ast.Formula = children[1]
        return formula

    def true(self, meta: Any, children: list[Token]) -> ast.Formula:
        return ast.Bool(True, _token_span(children[0]))

    def false(self, meta: Any, children: list[Token]) -> ast.Formula:
        return ast.Bool(False, _token_span(children[0]))

    def atom(self, meta: Any, children: list[Token]) -> ast.Formula:
        return ast.Atom(str(children[0]), _token_span(children[0]))

    def not_(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Not(children[1], _span(meta))

    def next_(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Next(children[1], _span(meta))

    def eventually(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Eventually(self._interval(children[1]), children[2], _span(meta))

    def always(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Always(self._interval(children[1]), children[2], _span(meta))

    def until(self, meta: Any, children: list[Any]) -> ast.Formula:
        left, _, interval, right = children
        return ast.Until(self._interval(interval), left, right, _span(meta))

    def release(self, meta: Any, children: list[Any]) -> ast.Formula:
        left, _, interval, right = children
        return ast.Release(self._interval(interval), left, right, _span(meta))

    def and_(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.And(children[0], children[2], _span(meta))

    def or_(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Or(children[0], children[2], _span(meta))

    def implies(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Implies(children[0], children[2], _span(meta))

    def iff(self, meta: Any, children: list[Any]) -> ast.Formula:
        return ast.Iff(children[0], children[2], _span(meta))
