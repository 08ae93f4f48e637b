"""Parse MITL text into the AST: ``parse(text) -> Formula``.

Three passes, as in the field's parsers: Lark's LALR(1) parser builds a parse tree; a separate
pass checks and normalises the intervals (half-open to closed, reversed or negative bounds,
``inf`` as a lower bound); a transformer builds the immutable AST with source spans. Before
and between them :mod:`mitlc.syntax.guard` holds the text to the limits of :mod:`mitlc.limits`
(length, nesting depth, size of a bound), so no later pass meets a recursion it cannot finish.
Lark's errors are wrapped in :class:`~mitlc.errors.SpecSyntaxError` with a location and a
message that says what was expected (see :mod:`mitlc.syntax.diagnostics`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import lark
from lark import Token, Transformer, Tree, v_args

from mitlc.errors import SourceLocation, SpecError, SpecSemanticError, SpecSyntaxError, locate
from mitlc.inputs import bad_utf8, read_head
from mitlc.limits import MAX_BATCH_BYTES, MAX_BATCH_FORMULAS
from mitlc.syntax import ast
from mitlc.syntax.diagnostics import empty_spec_error, syntax_error
from mitlc.syntax.grammar import lalr_parser
from mitlc.syntax.guard import MAX_SPEC_BYTES, bound_value, check_depth, check_length, too_long

DEFAULT_FILENAME = "<formula>"


def parse(text: str, filename: str = DEFAULT_FILENAME) -> ast.Formula:
    """Parse one MITL formula.

    Raises :class:`SpecSyntaxError` when ``text`` is not a formula (or is longer or nested
    deeper than :mod:`mitlc.limits` allows), and :class:`SpecSemanticError` when an interval is
    reversed, negative, empty or has a bound past :data:`~mitlc.limits.MAX_BOUND`.
    """
    check_length(text, filename)
    try:
        tree = lalr_parser().parse(text)
    except lark.exceptions.UnexpectedInput as err:
        raise syntax_error(err, text, filename) from None
    except lark.exceptions.LarkError as err:  # pragma: no cover - Lark's own failures
        raise SpecSyntaxError(str(err), locate(text, 0, filename)) from None
    check_depth(tree, text, filename)
    intervals = {
        _offset(_raw(node).opener): _check_interval(node, text, filename)
        for node in tree.find_data("interval")
    }
    return _ToAst(intervals).transform(tree)


def parse_bytes(data: bytes, filename: str = DEFAULT_FILENAME) -> ast.Formula:
    """Parse a formula from UTF-8 bytes; bytes that are not UTF-8 are a syntax error."""
    return parse(decode(data, filename), filename)


def parse_file(path: str | Path) -> ast.Formula:
    """Parse the spec file at ``path`` (an :class:`OSError` if it cannot be read)."""
    return parse(read_spec(path), str(path))


def read_spec(source: str | Path | BinaryIO, filename: str | None = None) -> str:
    """The text of a spec file (or of a binary stream, such as standard input), read only as
    far as the length limit: a :class:`SpecSyntaxError` if it is too long, not UTF-8, or
    empty; an :class:`OSError` if it cannot be read."""
    name = filename if filename is not None else str(source)
    data, more = read_head(source, MAX_SPEC_BYTES)
    if more:
        raise too_long(data.decode("utf-8-sig", errors="replace"), name)
    return decode(data, name)


def decode(data: bytes, filename: str) -> str:
    """Decode UTF-8 (a leading byte-order mark is dropped), locating the first bad byte."""
    if len(data) > MAX_SPEC_BYTES:
        raise too_long(data[:MAX_SPEC_BYTES].decode("utf-8-sig", errors="replace"), filename)
    bad = bad_utf8(data, filename)
    if bad is not None:
        message, location = bad
        raise SpecSyntaxError(message + "; specs must be UTF-8 text", location)
    text = data.decode("utf-8-sig")
    if not text.strip():
        raise empty_spec_error(text, filename)
    return text


def parse_batch_file(path: str | Path) -> list[ast.Formula]:
    """The formulas of the ``compile --batch`` file at ``path`` (see :func:`parse_lines`), read
    only as far as :data:`~mitlc.limits.MAX_BATCH_BYTES`."""
    data, more = read_head(path, MAX_BATCH_BYTES)
    if more:
        text = data.decode("utf-8-sig", errors="replace")
        raise SpecSyntaxError(
            f"the batch file is too large: more than {MAX_BATCH_BYTES:,} bytes (mitlc's limit)",
            locate(text, len(text), str(path)),
        )
    return parse_lines(data, str(path))


def parse_lines(data: bytes, filename: str) -> list[ast.Formula]:
    """The formulas of a ``compile --batch`` file: one a line, blank lines and lines starting
    with ``#`` skipped. Errors give the file's line number (lines end at ``\\n``)."""
    bad = bad_utf8(data, filename)
    if bad is not None:
        message, location = bad
        raise SpecSyntaxError(message + "; batch files must be UTF-8 text", location)
    formulas: list[ast.Formula] = []
    for number, line in enumerate(data.decode("utf-8-sig").split("\n"), start=1):
        line = line.removesuffix("\r")
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if len(formulas) == MAX_BATCH_FORMULAS:
            raise SpecSyntaxError(
                f"too many formulas: more than {MAX_BATCH_FORMULAS:,} in a batch file (mitlc's "
                "limit)",
                SourceLocation(filename, number, 1, line),
            )
        try:
            formulas.append(parse(line, filename))
        except SpecError as err:
            loc = err.location
            moved = SourceLocation(loc.filename, number, loc.column, loc.line_text)
            raise type(err)(err.message, moved) from None
    return formulas


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
    lo = bound_value(raw.lo, text, filename)
    if raw.hi is None and str(raw.sep) == ",":
        raise SpecSemanticError(
            f"expected an interval bound (an integer or 'inf'), found '{raw.closer}'",
            locate(text, _offset(raw.closer), filename),
        )
    hi: int | None = None
    if raw.hi is not None and raw.hi.type == "INT":
        hi = bound_value(raw.hi, text, filename)
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
