"""Round trips through the canonical printer, property-tested with hypothesis.

Two sources of formulas: random ASTs (every node kind, every interval shape), and strings drawn
from the grammar itself (``hypothesis.extra.lark``), with every spelling the grammar accepts.
"""

from __future__ import annotations

import random

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.lark import from_lark

from mitlc.errors import SpecError
from mitlc.syntax import ast, parse, to_text
from mitlc.syntax.grammar import build_parser
from tests import strategies
from tests.grammar_walk import check_spellings, random_text

BUILT = build_parser()
"""The parser built from the grammar (with its grammar object, which a loaded one lacks)."""

# Every node kind, bounded and unbounded intervals, and names that look like keywords.
formulas = strategies.formulas(
    atoms=["a", "b", "req", "done", "room_2", "x1", "trueish", "fa"],
    bounded=False,
    max_bound=30,
    max_leaves=12,
)


@settings(max_examples=500, deadline=None)
@given(formulas)
def test_printed_ast_parses_back_to_itself(formula: ast.Formula) -> None:
    text = to_text(formula)
    assert parse(text) == formula, text


@settings(max_examples=300, deadline=None)
@given(formulas)
def test_printing_is_a_fixpoint(formula: ast.Formula) -> None:
    text = to_text(formula)
    assert to_text(parse(text)) == text


GRAMMAR_STRINGS = from_lark(
    BUILT,
    start="start",
    explicit={
        "TRUE": st.sampled_from(["true", "1", "⊤"]),
        "FALSE": st.sampled_from(["false", "0", "⊥"]),
        "ATOM": st.sampled_from(["a", "b", "req", "x1", "trueish", "f", "ab_2"]),
        "INT": st.integers(0, 40).map(str),
        "INF": st.sampled_from(["inf", "infty", "∞"]),
        "LSQB": st.sampled_from(["[", "_["]),
        "LOPEN": st.sampled_from(["(", "_("]),
        "WS": st.sampled_from([" ", "  ", "\n", "\t"]),
        "COMMENT": st.just("# note\n"),
    },
)


@settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(GRAMMAR_STRINGS)
def test_grammar_strings_parse_or_fail_cleanly_and_round_trip(text: str) -> None:
    # A grammar string can still be rejected: two adjacent tokens may lex as one (`a` `b`
    # drawn without a space is the proposition `ab`), or an interval may be reversed or start
    # at inf. Such strings must fail with mitlc's located error, never another exception.
    try:
        formula = parse(text)
    except SpecError as err:
        assert err.location.line >= 1 and err.location.column >= 1
        return
    canonical = to_text(formula)
    assert parse(canonical) == formula, (text, canonical)
    assert to_text(parse(canonical)) == canonical


def test_grammar_strings_are_mostly_accepted() -> None:
    """The property above is not vacuous: a fixed sample of grammar strings mostly parses."""
    accepted = rejected = 0

    @settings(
        max_examples=40,
        database=None,
        derandomize=True,
        deadline=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(GRAMMAR_STRINGS)
    def count(text: str) -> None:
        nonlocal accepted, rejected
        try:
            parse(text)
            accepted += 1
        except SpecError:
            rejected += 1

    count()
    assert accepted + rejected == 40
    assert accepted >= 5, (accepted, rejected)


def test_walker_spellings_cover_the_grammar() -> None:
    check_spellings()


def test_grammar_walk_round_trips() -> None:
    """3,000 seeded grammar strings: each parses and round-trips, or fails with a located error."""
    rng = random.Random(20261122)
    accepted = 0
    for _ in range(3000):
        text = random_text(rng)
        try:
            formula = parse(text)
        except SpecError as err:
            assert err.location.line >= 1 and err.location.column >= 1
            continue
        accepted += 1
        canonical = to_text(formula)
        assert parse(canonical) == formula, (text, canonical)
        assert to_text(parse(canonical)) == canonical
    assert accepted >= 800, accepted
