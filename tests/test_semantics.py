"""The reference semantics: hand-worked finite traces and lassos, and properties.

Traces are written one string per letter, each character an atom: ``w("a", "", "ab")`` is
``{a} {} {a,b}``. Expected truth is one character per position: ``"TFT"``.
"""

from __future__ import annotations

import functools
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mitlc.errors import MitlcError
from mitlc.semantics import (
    Lasso,
    Letter,
    SemanticsError,
    evaluate_finite,
    evaluate_lasso,
    holds_finite,
    holds_lasso,
)
from mitlc.syntax import ast, parse, to_text
from tests.strategies import (
    formulas,
    horizon,
    intervals,
    lassos,
    random_formula,
    random_lasso,
    traces,
)

PROPERTY = settings(
    max_examples=300,
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


def w(*letters: str) -> tuple[Letter, ...]:
    """A trace, one string of atom characters per letter."""
    return tuple(frozenset(letter) for letter in letters)


def lasso(prefix: tuple[str, ...], loop: tuple[str, ...]) -> Lasso:
    return Lasso(w(*prefix), w(*loop))


def truth(text: str) -> tuple[bool, ...]:
    assert set(text) <= {"T", "F"}
    return tuple(c == "T" for c in text)


# --- finite traces, by hand ----------------------------------------------------------------------

FINITE_CASES = [
    # Boolean connectives, pointwise.
    ("a", w("a", "b", "ab", ""), "TFTF"),
    ("!a", w("a", "b", "ab", ""), "FTFT"),
    ("a & b", w("a", "b", "ab", ""), "FFTF"),
    ("a | b", w("a", "b", "ab", ""), "TTTF"),
    ("a -> b", w("a", "b", "ab", ""), "FTTT"),
    ("a <-> b", w("a", "b", "ab", ""), "FFTT"),
    ("true", w("", "a"), "TT"),
    ("false", w("", "a"), "FF"),
    # X: true at the last position, and negation is exact there.
    ("X a", w("", "a", ""), "TFF"),  # LTLf's strong next: false at the last position
    ("!X a", w("", "a", ""), "FTT"),
    ("X false", w("", ""), "FF"),
    ("X X a", w("a", "a", ""), "FFF"),
    ("X true", w("", ""), "TF"),
    ("G[1,1] a", w("", ""), "FT"),  # a window past the end holds, a single point too
    ("F[1,1] a", w("", "a"), "TF"),
    # F and G: a max / min over the window cut to the trace; none left: false / true.
    ("F[1,2] a", w("a", "", "", "a", ""), "FTTFF"),
    ("F a", w("", "a", ""), "TTF"),
    ("F[0,0] a", w("a", ""), "TF"),
    ("G[1,2] a", w("", "a", "a", "", "a"), "TFFTT"),
    ("G a", w("a", "", "a", "a"), "FFTT"),
    ("G[0,0] a", w("a", ""), "TF"),
    ("F[1,5] a", w("", "a"), "TF"),
    ("G[1,5] a", w("a", ""), "FT"),
    ("F[3,5] a", w("a", "a"), "FF"),
    ("G[3,5] !a", w("a", "a"), "TT"),
    ("F[2,inf) a", w("", "a", "", "a", ""), "TTFFF"),
    ("G[1,inf) a", w("", "a", "", "a", "a"), "FFTTT"),
    # U: a witness j in the window and inside the trace, p on [i, j).
    ("a U[1,2] b", w("a", "a", "b", "", "b"), "TTFFF"),
    ("a U b", w("a", "a", "b", ""), "TTTF"),
    ("a U b", w("a", "a", "a"), "FFF"),
    ("a U[0,0] b", w("a", "b", ""), "FTF"),
    ("a U[3,5] a", w("a", "a"), "FF"),
    ("a U[1,inf) b", w("b", "ab", "a", "b"), "FTTF"),
    # R, the dual: every j in the window has q, or p before it; none left: true.
    ("a R[1,2] b", w("", "b", "ab", "", ""), "TTTFT"),
    ("a R b", w("b", "ab", "", ""), "TTFF"),
    ("a R b", w("b", "b"), "TT"),
    ("a R[3,5] !a", w("a", "a"), "TT"),
    # Nested: the end of the trace propagates.
    ("G[0,1] F[1,2] a", w("", "a", "", "a", "a"), "TTTFF"),
    ("G (a -> X b)", w("a", "b", "a"), "FFF"),  # the last request has no next letter
    ("G (a -> X b)", w("a", "b", ""), "TTT"),
    ("G (a -> X b)", w("a", "", "a"), "FFF"),
]


@pytest.mark.parametrize(("text", "trace", "expected"), FINITE_CASES)
def test_finite_by_hand(text: str, trace: tuple[Letter, ...], expected: str) -> None:
    assert evaluate_finite(parse(text), trace) == truth(expected)


def test_holds_finite_reads_one_position() -> None:
    trace = w("", "a", "")
    assert holds_finite(parse("X a"), trace)
    assert not holds_finite(parse("X a"), trace, 1)
    assert not holds_finite(parse("X a"), trace, 2)


# --- lassos, by hand -----------------------------------------------------------------------------

EVERY_OTHER = lasso(("",), ("a", ""))  # {} ({a} {})^omega
SEVEN = ("a", "", "", "", "", "", "")

LASSO_CASES = [
    ("a", EVERY_OTHER, "FTF"),
    ("X a", EVERY_OTHER, "TFT"),  # the loop's last letter is followed by its first
    ("G F a", EVERY_OTHER, "TTT"),
    ("F G a", EVERY_OTHER, "FFF"),
    ("G F !a", EVERY_OTHER, "TTT"),
    ("F G a", lasso(("",), ("a",)), "TT"),
    ("G a", lasso(("",), ("a",)), "FT"),
    ("a U b", lasso(("a", "a"), ("b",)), "TTT"),
    ("a U b", lasso(("a",), ("a",)), "FF"),
    ("a U b", lasso(("a", ""), ("b",)), "FFT"),
    ("a U[1,inf) b", lasso(("b",), ("a", "b")), "FTF"),
    ("G (a -> F b)", lasso((), ("a", "", "b")), "TTT"),
    ("G (a -> F b)", lasso((), ("a", "")), "FF"),
    ("G (a -> F b)", lasso(("a", ""), ("",)), "FTT"),
    ("G F[5,10] a", lasso((), ("a", "", "", "", "", "")), "TTTTTT"),  # period 6 fits the window
    ("G F[5,10] a", lasso((), SEVEN), "FFFFFFF"),  # period 7 does not
    ("F[5,10] a", lasso((), SEVEN), "TTTFTTT"),
    ("F[2,inf) a", lasso(("", "", "a"), ("",)), "TFFF"),
    ("F[2,inf) a", lasso(("a",), ("",)), "FF"),
    ("F[2,inf) a", lasso((), ("a", "")), "TT"),
    ("G[2,inf) a", lasso(("", "", "a"), ("a",)), "TTTT"),
    ("G[2,inf) a", lasso(("", "", ""), ("a",)), "FTTT"),
    ("a R b", lasso((), ("b",)), "T"),
    ("a R b", lasso((), ("b", "")), "FF"),
    ("a R b", lasso(("b", "ab"), ("",)), "TTF"),
    ("a R[2,3] b", lasso((), ("b", "b", "", "")), "FFTF"),
    ("a R[1,inf) b", lasso(("",), ("b",)), "TT"),
    ("a R[1,inf) b", lasso(("", "b"), ("a",)), "FFT"),
    ("G (a -> X (!a U b))", lasso((), ("a", "", "b")), "TTT"),
    ("G (a -> X (!a U b))", lasso((), ("a", "", "a", "b")), "FFFF"),
    ("G F (a & X a)", lasso((), ("a", "a", "")), "TTT"),
    ("G F (a & X a)", lasso((), ("a", "")), "FF"),
    ("F G (a U[0,2] b)", lasso(("",), ("a", "a", "b")), "TTTT"),
    ("F G (a U[0,1] b)", lasso(("",), ("a", "a", "b")), "FFFF"),
    # Huge bounds cost O(period), not O(bound).
    ("F[500,inf) a", EVERY_OTHER, "TTT"),
    ("G[0,1000] (a | X a)", EVERY_OTHER, "TTT"),
    ("F[1000,1000] a", lasso((), ("a", "")), "TF"),
    ("G[1000000000,2000000000] F[0,1] a", EVERY_OTHER, "TTT"),
    ("a U[999999999,inf) b", lasso(("a",), ("a", "ab")), "TTT"),
]


@pytest.mark.parametrize(("text", "word", "expected"), LASSO_CASES)
def test_lasso_by_hand(text: str, word: Lasso, expected: str) -> None:
    assert evaluate_lasso(parse(text), word) == truth(expected)


def test_holds_lasso_at_any_position() -> None:
    word = lasso((), ("a", ""))
    formula = parse("F[1000,1000] a")
    assert holds_lasso(formula, word, 10**12)
    assert not holds_lasso(formula, word, 10**12 + 1)
    assert holds_lasso(parse("X a"), EVERY_OTHER, 2)
    assert not holds_lasso(parse("a"), EVERY_OTHER, 4)


def test_lasso_positions_and_unrolling() -> None:
    word = lasso(("a", "b"), ("", "a", "ab"))
    assert word.size == 5
    assert [word.canonical(i) for i in range(11)] == [0, 1, 2, 3, 4, 2, 3, 4, 2, 3, 4]
    assert word.letter(7) == frozenset("ab")
    assert word.unroll(7) == w("a", "b", "", "a", "ab", "", "a")
    assert word.letters == w("a", "b", "", "a", "ab")


# --- errors and deep formulas --------------------------------------------------------------------


def test_errors_are_typed() -> None:
    assert issubclass(SemanticsError, ValueError) and issubclass(SemanticsError, MitlcError)
    with pytest.raises(SemanticsError, match="at least one letter"):
        evaluate_finite(parse("a"), ())
    with pytest.raises(SemanticsError, match="loop"):
        Lasso(w("a"), ())
    with pytest.raises(SemanticsError, match="negative"):
        holds_lasso(parse("a"), EVERY_OTHER, -1)
    with pytest.raises(SemanticsError, match="outside"):
        holds_finite(parse("a"), w("a", "b"), 2)
    with pytest.raises(SemanticsError, match="outside"):
        holds_finite(parse("a"), w("a"), -1)


def _nested_next(depth: int) -> ast.Formula:
    formula: ast.Formula = ast.Atom("a")
    for _ in range(depth):
        formula = ast.Next(formula)
    return formula


def test_deep_formulas() -> None:
    deep = _nested_next(200)
    assert evaluate_lasso(deep, lasso((), ("a", ""))) == truth("TF")
    assert evaluate_finite(deep, w("", "", "")) == truth("FFF")  # X past the end: false
    mixed: ast.Formula = ast.Atom("a")
    for k in range(60):
        layers: list[ast.Formula] = [
            ast.Next(mixed),
            ast.Eventually(ast.Interval(0, 2), mixed),
            ast.Until(ast.Interval(1, 3), ast.Atom("b"), mixed),
            ast.Not(mixed),
        ]
        mixed = layers[k % 4]
    trace = w("ab", "b", "a", "", "ab", "b", "b", "a")
    assert evaluate_finite(mixed, trace) == tuple(
        naive_finite(mixed, trace, i) for i in range(len(trace))
    )
    word = Lasso(trace[:3], trace[3:])
    assert evaluate_lasso(mixed, word) == tuple(
        naive_lasso(mixed, word, i) for i in range(word.size)
    )


def test_equal_subformulas_are_shared() -> None:
    spanned = parse("F a & F a")  # equal subformulas with different spans
    assert isinstance(spanned, ast.And) and spanned.left == spanned.right
    assert evaluate_finite(spanned, w("", "a")) == truth("TT")


# --- independent oracles: the definitions, position by position ----------------------------------


def _window(i: int, interval: ast.Interval, last: int) -> range:
    """The positions ``j`` with ``j - i`` in ``interval`` and ``j <= last``."""
    hi = last if interval.hi is None else min(i + interval.hi, last)
    return range(i + interval.lo, hi + 1)


def naive_finite(formula: ast.Formula, trace: tuple[Letter, ...], i: int) -> bool:
    """The definition with rtamt's conventions, each operator on its own, no sharing."""
    n = len(trace)

    def at(f: ast.Formula, k: int) -> bool:
        return naive_finite(f, trace, k)

    match formula:
        case ast.Bool(value):
            return value
        case ast.Atom(name):
            return name in trace[i]
        case ast.Not(p):
            return not at(p, i)
        case ast.And(p, q):
            return at(p, i) and at(q, i)
        case ast.Or(p, q):
            return at(p, i) or at(q, i)
        case ast.Implies(p, q):
            return not at(p, i) or at(q, i)
        case ast.Iff(p, q):
            return at(p, i) == at(q, i)
        case ast.Next(p):
            return i + 1 < n and at(p, i + 1)  # strong
        case ast.Eventually(interval, q):
            return any(at(q, j) for j in _window(i, interval, n - 1))
        case ast.Always(interval, q):
            return all(at(q, j) for j in _window(i, interval, n - 1))
        case ast.Until(interval, p, q):
            return any(
                at(q, j) and all(at(p, k) for k in range(i, j)) for j in _window(i, interval, n - 1)
            )
        case ast.Release(interval, p, q):
            return all(
                at(q, j) or any(at(p, k) for k in range(i, j)) for j in _window(i, interval, n - 1)
            )
    raise TypeError(formula)


def naive_lasso(formula: ast.Formula, word: Lasso, position: int) -> bool:
    """The definition on the infinite word, at absolute positions. A window is cut at
    ``max(i + lo, len(prefix)) + len(loop) - 1``: a later ``j`` repeats one before it, whose
    condition on the positions in between is weaker."""
    period, start = len(word.loop), len(word.prefix)

    @functools.cache
    def at(f: ast.Formula, i: int) -> bool:
        def window(interval: ast.Interval) -> range:
            return _window(i, interval, max(i + interval.lo, start) + period - 1)

        match f:
            case ast.Bool(value):
                return value
            case ast.Atom(name):
                return name in word.letter(i)
            case ast.Not(p):
                return not at(p, i)
            case ast.And(p, q):
                return at(p, i) and at(q, i)
            case ast.Or(p, q):
                return at(p, i) or at(q, i)
            case ast.Implies(p, q):
                return not at(p, i) or at(q, i)
            case ast.Iff(p, q):
                return at(p, i) == at(q, i)
            case ast.Next(p):
                return at(p, i + 1)
            case ast.Eventually(interval, q):
                return any(at(q, j) for j in window(interval))
            case ast.Always(interval, q):
                return all(at(q, j) for j in window(interval))
            case ast.Until(interval, p, q):
                return any(
                    at(q, j) and all(at(p, k) for k in range(i, j)) for j in window(interval)
                )
            case ast.Release(interval, p, q):
                return all(at(q, j) or any(at(p, k) for k in range(i, j)) for j in window(interval))
        raise TypeError(f)

    return at(formula, position)


# --- properties ----------------------------------------------------------------------------------


@PROPERTY
@given(formulas(bounded=False), traces())
def test_finite_agrees_with_the_definition(formula: ast.Formula, trace: tuple[Letter, ...]) -> None:
    expected = tuple(naive_finite(formula, trace, i) for i in range(len(trace)))
    assert evaluate_finite(formula, trace) == expected, to_text(formula)


@PROPERTY
@given(formulas(bounded=False), lassos())
def test_lasso_agrees_with_the_definition(formula: ast.Formula, word: Lasso) -> None:
    result = evaluate_lasso(formula, word)
    for i in range(word.size):
        assert result[i] == naive_lasso(formula, word, i), (to_text(formula), i)
        later = i + len(word.loop) * (3 if i >= len(word.prefix) else 0)
        assert holds_lasso(formula, word, later) == naive_lasso(formula, word, later)


def test_bounded_lasso_truth_is_finite_truth_on_a_long_unrolling() -> None:
    """With bounded intervals the truth at ``i`` depends on ``i .. i + horizon`` only, so the
    finite semantics on an unrolling that long agrees, whatever its end conventions."""
    rng = random.Random(1729)
    checked = 0
    for _ in range(500):
        formula = random_formula(rng, rng.randint(1, 4), "abc", bounded=True, max_bound=4)
        word = random_lasso(rng, rng.randint(0, 4), rng.randint(1, 4), "abc")
        reach = horizon(formula)
        assert reach is not None
        result = evaluate_lasso(formula, word)
        for i in range(word.size):
            finite = evaluate_finite(formula, word.unroll(i + reach + 1))
            assert result[i] == finite[i], (to_text(formula), word, i)
            checked += 1
    assert checked > 2000


def _dualities(
    p: ast.Formula, q: ast.Formula, interval: ast.Interval
) -> list[tuple[ast.Formula, ast.Formula]]:
    return [
        (ast.Always(interval, p), ast.Not(ast.Eventually(interval, ast.Not(p)))),
        (ast.Release(interval, p, q), ast.Not(ast.Until(interval, ast.Not(p), ast.Not(q)))),
        (ast.Eventually(interval, q), ast.Until(interval, ast.TRUE, q)),
    ]


@PROPERTY
@given(
    formulas(bounded=False, max_leaves=5),
    formulas(bounded=False, max_leaves=5),
    intervals(bounded=False),
    traces(),
    lassos(),
)
def test_dualities(
    p: ast.Formula,
    q: ast.Formula,
    interval: ast.Interval,
    trace: tuple[Letter, ...],
    word: Lasso,
) -> None:
    for left, right in _dualities(p, q, interval):
        assert evaluate_finite(left, trace) == evaluate_finite(right, trace)
        assert evaluate_lasso(left, word) == evaluate_lasso(right, word)


@PROPERTY
@given(st.integers(0, 6), st.integers(1, 6), st.integers(0, 10**6))
def test_unbounded_eventually_on_lassos_is_scale_free(
    prefix_len: int, loop_len: int, lo: int
) -> None:
    """``F[lo,inf) a`` at ``i`` holds iff ``a`` occurs in the loop or at a prefix position
    ``>= i + lo``; a huge ``lo`` costs nothing."""
    rng = random.Random(prefix_len * 1000 + loop_len)
    word = random_lasso(rng, prefix_len, loop_len, "a")
    result = evaluate_lasso(ast.Eventually(ast.Interval(lo, None), ast.Atom("a")), word)
    in_loop = any("a" in letter for letter in word.loop)
    for i in range(word.size):
        later = any("a" in letter for letter in word.prefix[i + lo :])
        assert result[i] == (in_loop or later)
