"""The parser: the syntax table of DESIGN.md, precedence, intervals, spans."""

from __future__ import annotations

import pytest

from mitlc.syntax import (
    FALSE,
    TRUE,
    UNBOUNDED,
    Always,
    And,
    Atom,
    Eventually,
    Iff,
    Implies,
    Interval,
    Next,
    Not,
    Or,
    Release,
    Until,
    atoms,
    parse,
    to_text,
)

a, b, c, d = Atom("a"), Atom("b"), Atom("c"), Atom("d")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("true", TRUE),
        ("1", TRUE),
        ("⊤", TRUE),
        ("false", FALSE),
        ("0", FALSE),
        ("⊥", FALSE),
        ("printer", Atom("printer")),
        ("room_2", Atom("room_2")),
        ("trueish", Atom("trueish")),
        ("!a", Not(a)),
        ("¬a", Not(a)),
        ("~a", Not(a)),
        ("a & b", And(a, b)),
        ("a && b", And(a, b)),
        ("a ∧ b", And(a, b)),
        ("a | b", Or(a, b)),
        ("a || b", Or(a, b)),
        ("a ∨ b", Or(a, b)),
        ("a -> b", Implies(a, b)),
        ("a → b", Implies(a, b)),
        ("a <-> b", Iff(a, b)),
        ("a ↔ b", Iff(a, b)),
        ("X a", Next(a)),
        ("○ a", Next(a)),
        ("F a", Eventually(UNBOUNDED, a)),
        ("◇ a", Eventually(UNBOUNDED, a)),
        ("G a", Always(UNBOUNDED, a)),
        ("□ a", Always(UNBOUNDED, a)),
        ("F[5,10] a", Eventually(Interval(5, 10), a)),
        ("F[5..10] a", Eventually(Interval(5, 10), a)),
        ("F[5:10] a", Eventually(Interval(5, 10), a)),
        ("F[2..] a", Eventually(Interval(2, None), a)),
        ("F[2:] a", Eventually(Interval(2, None), a)),
        ("F[5,inf) a", Eventually(Interval(5, None), a)),
        ("F[5,∞) a", Eventually(Interval(5, None), a)),
        ("F[5,infty] a", Eventually(Interval(5, None), a)),
        ("F_[5,10] a", Eventually(Interval(5, 10), a)),
        ("◇_[5,10] a", Eventually(Interval(5, 10), a)),
        ("G[0,4] !a", Always(Interval(0, 4), Not(a))),
        ("F[5,10) a", Eventually(Interval(5, 9), a)),
        ("F(5,10] a", Eventually(Interval(6, 10), a)),
        ("F(5,10) a", Eventually(Interval(6, 9), a)),
        ("F(5,inf) a", Eventually(Interval(6, None), a)),
        ("F[ 5 , 10 ] a", Eventually(Interval(5, 10), a)),
        ("!a U[5,10] a", Until(Interval(5, 10), Not(a), a)),
        ("!a U_[5,10] a", Until(Interval(5, 10), Not(a), a)),
        ("a U b", Until(UNBOUNDED, a, b)),
        ("a R[0,3] b", Release(Interval(0, 3), a, b)),
        ("a R b", Release(UNBOUNDED, a, b)),
        ("GFa", Always(UNBOUNDED, Eventually(UNBOUNDED, a))),
        ("F(a)", Eventually(UNBOUNDED, a)),
        ("F (1 | a)", Eventually(UNBOUNDED, Or(TRUE, a))),
        ("a # a comment\n & b", And(a, b)),
    ],
)
def test_syntax_table(text: str, expected: object) -> None:
    assert parse(text) == expected


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        # loosest to tightest: <->, ->, |, &, U/R, unary
        ("a <-> b -> c", Iff(a, Implies(b, c))),
        ("a -> b <-> c", Iff(Implies(a, b), c)),
        ("a -> b | c", Implies(a, Or(b, c))),
        ("a | b & c", Or(a, And(b, c))),
        ("a & b U c", And(a, Until(UNBOUNDED, b, c))),
        ("!a U b", Until(UNBOUNDED, Not(a), b)),
        ("F a U b", Until(UNBOUNDED, Eventually(UNBOUNDED, a), b)),
        ("X a & b", And(Next(a), b)),
        # associativity
        ("a -> b -> c", Implies(a, Implies(b, c))),
        ("a U b U c", Until(UNBOUNDED, a, Until(UNBOUNDED, b, c))),
        ("a R b U c", Release(UNBOUNDED, a, Until(UNBOUNDED, b, c))),
        ("a & b & c", And(And(a, b), c)),
        ("a | b | c", Or(Or(a, b), c)),
        ("a <-> b <-> c", Iff(Iff(a, b), c)),
        ("a & b | c & d", Or(And(a, b), And(c, d))),
    ],
)
def test_precedence_and_associativity(text: str, expected: object) -> None:
    assert parse(text) == expected


def test_paper_task() -> None:
    formula = parse("(!a U[5,10] a) & (!b U[15,20] b)")
    assert formula == And(Until(Interval(5, 10), Not(a), a), Until(Interval(15, 20), Not(b), b))
    assert atoms(formula) == ("a", "b")


def test_spans_point_into_the_source() -> None:
    text = "G (req -> F[0,5] done)"
    formula = parse(text)
    assert isinstance(formula, Always)
    implies = formula.operand
    assert isinstance(implies, Implies)
    assert text[implies.span.start : implies.span.end] == "req -> F[0,5] done"
    eventually = implies.right
    assert text[eventually.span.start : eventually.span.end] == "F[0,5] done"
    assert (eventually.span.line, eventually.span.column) == (1, 11)


def test_spans_do_not_affect_equality() -> None:
    assert parse("a&b") == parse("  (a) & (b)  ")
    assert hash(parse("a&b")) == hash(parse("  (a) & (b)  "))


def test_interval_validates_itself() -> None:
    with pytest.raises(ValueError):
        Interval(5, 4)
    with pytest.raises(ValueError):
        Interval(-1, 4)
    assert 7 in Interval(5, 10) and 11 not in Interval(5, 10) and 10**9 in Interval(5, None)


@pytest.mark.parametrize(
    ("text", "canonical"),
    [
        ("(!a U[5,10] a) & (!b U[15,20] b)", "(!a U[5,10] a) & (!b U[15,20] b)"),
        ("G(req -> F[0,5] done)", "G (req -> F[0,5] done)"),
        ("□◇ a", "G F a"),
        ("F[2..5] a", "F[2,5] a"),
        ("F[5,10) a", "F[5,9] a"),
        ("F[0,inf) a", "F a"),
        ("a U[0,∞) b", "a U b"),
        ("¬a ∧ b → ○ c ↔ d", "!a & b -> X c <-> d"),
        ("a & (b & c)", "a & (b & c)"),
        ("(a U b) U c", "(a U b) U c"),
        ("(a -> b) -> c", "(a -> b) -> c"),
        ("!(a & b)", "!(a & b)"),
        ("F (a U b)", "F (a U b)"),
        ("1 & 0", "true & false"),
    ],
)
def test_canonical_text(text: str, canonical: str) -> None:
    assert to_text(parse(text)) == canonical
    assert parse(canonical) == parse(text)
