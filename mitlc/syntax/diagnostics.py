"""Turning Lark's parse errors into mitlc's: a location and a message saying what was expected.

Lark reports the terminals the parser would have accepted; this module names them the way a
person reads the grammar ("a formula", "an interval bound", "')'"), finds the opening
parenthesis an unexpected end of input leaves unclosed, and points at the offending character.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

import lark
from lark import Token

from mitlc.errors import SourceLocation, SpecSyntaxError, locate
from mitlc.syntax.grammar import lalr_parser

_FORMULA_START = frozenset({"TRUE", "FALSE", "ATOM", "LPAR", "NOT", "NEXT", "EVENTUALLY", "ALWAYS"})
_BINARY = frozenset({"AND", "OR", "IMPLIES", "IFF", "UNTIL", "RELEASE"})
_BOUND = frozenset({"INT", "INF"})

_NAMES = {
    "RPAR": "')'",
    "RSQB": "']'",
    "SEP": "',' or '..' between the bounds",
    "LSQB": "an interval such as [5,10]",
    "LOPEN": "an interval such as [5,10]",
    "$END": "the end of the formula",
}


def describe_expected(expected: Iterable[str]) -> str:
    """A phrase naming the terminals in ``expected``, e.g. "a formula" or "')' or an operator"."""
    names = set(expected)
    phrases: list[str] = []
    if names & _FORMULA_START:
        phrases.append("a formula")
        names -= _FORMULA_START | {"LSQB", "LOPEN"}
    if names & _BOUND:
        phrases.append("an interval bound (an integer or 'inf')")
        names -= _BOUND
    if {"RPAR", "RSQB"} <= names and "SEP" not in names and not names & _BINARY:
        phrases.append("']' or ')' to close the interval")
        names -= {"RPAR", "RSQB"}
    if names & _BINARY:
        phrases.append("a binary operator (&, |, ->, <->, U, R)")
        names -= _BINARY
    end = "$END" in names
    names.discard("$END")
    phrases.extend(_NAMES.get(n, n) for n in sorted(names))
    if end:
        phrases.append(_NAMES["$END"])
    return " or ".join(phrases) if phrases else "nothing more"


def describe_token(token: Token) -> str:
    """How a token is named in a message: its text in quotes, or "the end of the formula"."""
    if token.type == "$END":
        return "the end of the formula"
    return f"'{token}'"


def syntax_error(err: lark.exceptions.UnexpectedInput, text: str, filename: str) -> SpecSyntaxError:
    """mitlc's error for one of Lark's."""
    if isinstance(err, lark.exceptions.UnexpectedCharacters):
        return _unexpected_character(err, text, filename)
    if isinstance(err, lark.exceptions.UnexpectedToken):
        return _unexpected_token(err, text, filename)
    if isinstance(err, lark.exceptions.UnexpectedEOF):  # pragma: no cover - Earley only
        return SpecSyntaxError(
            f"unexpected end of the formula; expected {describe_expected(err.expected)}",
            locate(text, len(text.rstrip()), filename),
        )
    raise TypeError(f"unknown Lark error {err!r}")  # pragma: no cover


def empty_spec_error(text: str, filename: str) -> SpecSyntaxError:
    """The error for a spec that holds no formula (empty, blank, or only comments)."""
    return SpecSyntaxError(
        "empty specification: expected a formula", locate(text, len(text.rstrip()), filename)
    )


def _unexpected_character(
    err: lark.exceptions.UnexpectedCharacters, text: str, filename: str
) -> SpecSyntaxError:
    char = err.char
    position = err.pos_in_stream or 0
    location = locate(text, position, filename)
    if char.isalpha() and char.isupper():
        hint = (
            f"'{char}' is not an operator (X, F, G, U, R); propositions start with a "
            "lowercase letter"
        )
        return SpecSyntaxError(f"unexpected character '{char}': {hint}", location)
    shown = f"'{char}'" if char.isprintable() else f"U+{ord(char):04X}"
    allowed = describe_expected(_accepted_after(text[:position], err.allowed or ()))
    return SpecSyntaxError(f"unexpected character {shown}; expected {allowed}", location)


def _accepted_after(prefix: str, fallback: Iterable[str]) -> set[str]:
    """The terminals the parser accepts after ``prefix``, computed exactly (LALR's merged
    states make Lark's own ``expected`` sets too large: ')' where no '(' is open)."""
    try:
        parser = lalr_parser().parse_interactive(prefix)
        parser.exhaust_lexer()
        return _accepts(parser)
    except lark.exceptions.LarkError:
        return set(fallback)


def _accepts(parser: lark.parsers.lalr_interactive_parser.InteractiveParser) -> set[str]:
    accepted: set[str] = parser.accepts()  # type: ignore[no-untyped-call]
    return set(accepted)


def _unexpected_token(
    err: lark.exceptions.UnexpectedToken, text: str, filename: str
) -> SpecSyntaxError:
    token = err.token
    accepted = _accepted(err)
    expected = describe_expected(accepted)
    if token.type == "$END":
        if not _has_tokens(err):
            return empty_spec_error(text, filename)
        opener = _unclosed_paren(err)
        if opener is not None and "RPAR" in accepted:
            return SpecSyntaxError(
                f"unclosed '(' at line {opener.line}, column {opener.column}: expected "
                f"{expected} before the end of the formula",
                _end_location(token, text, filename),
            )
        return SpecSyntaxError(
            f"unexpected end of the formula; expected {expected}",
            _end_location(token, text, filename),
        )
    location = locate(text, token.start_pos or 0, filename)
    message = f"expected {expected}, found {describe_token(token)}"
    return SpecSyntaxError(message + _capital_hint(token, text), location)


_OPERATOR_LETTERS = frozenset({"UNTIL", "RELEASE", "NEXT", "EVENTUALLY", "ALWAYS"})
_WORD = re.compile(r"[A-Za-z0-9_]*")


def _capital_hint(token: Token, text: str) -> str:
    """A hint for `Req`: a capital operator letter glued to a word meant as a proposition."""
    if token.type not in _OPERATOR_LETTERS or token.end_pos is None:
        return ""
    rest = _WORD.match(text, token.end_pos)
    if rest is None or not rest.group():
        return ""
    word = str(token) + rest.group()
    return (
        f" ('{word}' reads as the operator {token} and then '{rest.group()}': "
        "propositions start with a lowercase letter)"
    )


def _accepted(err: lark.exceptions.UnexpectedToken) -> set[str]:
    parser = getattr(err, "interactive_parser", None)
    if parser is None:
        return set(err.expected)
    try:
        return _accepts(parser)
    except lark.exceptions.LarkError:  # pragma: no cover - defensive
        return set(err.expected)


def _end_location(token: Token, text: str, filename: str) -> SourceLocation:
    """Just after the last token, where the formula ended too soon."""
    return locate(text, token.end_pos if token.end_pos is not None else len(text), filename)


def _value_stack(err: lark.exceptions.UnexpectedToken) -> list[object]:
    parser = getattr(err, "interactive_parser", None)
    if parser is None:
        return []
    return list(parser.parser_state.value_stack)


def _has_tokens(err: lark.exceptions.UnexpectedToken) -> bool:
    return bool(_value_stack(err))


def _unclosed_paren(err: lark.exceptions.UnexpectedToken) -> Token | None:
    """The innermost '(' still open when the input ended, if any."""
    opened = [v for v in _value_stack(err) if isinstance(v, Token) and v.type == "LPAR"]
    return opened[-1] if opened else None
