"""The Spot gate: mitlc's automaton of a formula has the language of Spot's LTL translation.

Spot has no bounded operators, so :func:`to_spot` unrolls each into ``X`` by its definition
(``p U[a,b] q`` holds when ``q`` holds at some delay ``j`` in ``[a,b]`` and ``p`` at every delay
before ``j``). Each seeded formula is translated by mitlc (``translate`` → ``to_hoa`` →
``spot.automaton``) and by Spot; mitlc's automaton must meet no word of Spot's automaton for the
negation, and its complement none of Spot's for the formula. On a mismatch the test reports
both texts, the word, which side accepts it and what mitlc's reference semantics
(:func:`mitlc.semantics.holds_lasso`) says.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any

import pytest

from mitlc.automata.hoa import to_hoa
from mitlc.semantics import Lasso, holds_lasso
from mitlc.syntax import ast, parse, to_text
from mitlc.syntax.spot import to_spot
from tests.strategies import ATOMS, random_formula, random_lasso

spot = pytest.importorskip("spot")
buddy = pytest.importorskip("spot.buddy")
ldba = pytest.importorskip("mitlc.automata.ldba")

MAX_BOUND = 3
COMPLEMENT_LIMIT = 1000
"""mitlc automata with more states are complemented only when deterministic (see mismatch)."""


# --- the formulas ---------------------------------------------------------------------------------

Template = Callable[[ast.Formula, ast.Formula, ast.Interval], ast.Formula]

F, G, X, N = ast.Eventually, ast.Always, ast.Next, ast.Not
U, R, And, Or, Imp = ast.Until, ast.Release, ast.And, ast.Or, ast.Implies
INF = ast.UNBOUNDED

TEMPLATES: tuple[Template, ...] = (
    lambda p, q, i: G(INF, F(INF, p)),
    lambda p, q, i: F(INF, G(INF, p)),
    lambda p, q, i: G(INF, Imp(p, F(i, q))),
    lambda p, q, i: G(INF, Imp(p, X(q))),
    lambda p, q, i: U(INF, p, q),
    lambda p, q, i: R(INF, p, q),
    lambda p, q, i: F(INF, And(p, X(G(INF, q)))),
    lambda p, q, i: And(G(INF, F(INF, p)), F(INF, G(INF, q))),
    lambda p, q, i: Imp(G(INF, F(INF, p)), G(INF, F(INF, q))),
    lambda p, q, i: F(i, G(INF, p)),
    lambda p, q, i: G(i, F(INF, p)),
    lambda p, q, i: G(INF, F(i, p)),
    lambda p, q, i: F(INF, G(i, p)),
    lambda p, q, i: U(ast.Interval(i.lo, None), p, q),
    lambda p, q, i: R(ast.Interval(i.lo, None), p, q),
    lambda p, q, i: G(INF, Or(p, U(i, p, q))),
    lambda p, q, i: G(INF, Imp(p, R(i, q, p))),
    lambda p, q, i: U(INF, p, G(INF, q)),
    lambda p, q, i: R(INF, F(INF, p), q),
    lambda p, q, i: N(G(INF, F(i, Or(p, q)))),
    lambda p, q, i: G(INF, Imp(p, X(U(INF, p, q)))),
    lambda p, q, i: Or(F(INF, G(INF, p)), G(INF, F(i, q))),
)


def _small(rng: random.Random) -> ast.Formula:
    return random_formula(rng, rng.choice((1, 1, 2)), ATOMS, True, MAX_BOUND)


def _interval(rng: random.Random) -> ast.Interval:
    lo = rng.randint(0, MAX_BOUND)
    return ast.Interval(lo, rng.randint(lo, MAX_BOUND))


def _has_unbounded(formula: ast.Formula) -> bool:
    return any(i.is_unbounded for i in ast.intervals(formula))


def gate_formulas(seed: int, counts: dict[int, int]) -> list[ast.Formula]:
    """Seeded formulas with unbounded operators: ``counts[0]`` from the templates (``G F p``,
    ``G(p -> F[i,j] q)``, ...) over small random operands, then ``counts[d]`` random formulas
    of depth ``d`` for each other key (bounds up to 3)."""
    rng = random.Random(seed)
    out = [
        TEMPLATES[k % len(TEMPLATES)](_small(rng), _small(rng), _interval(rng))
        for k in range(counts.get(0, 0))
    ]
    for depth, count in sorted(counts.items()):
        drawn = 0
        while depth and drawn < count:
            formula = random_formula(rng, depth, ATOMS, False, MAX_BOUND)
            if _has_unbounded(formula):
                out.append(formula)
                drawn += 1
    return out


# --- the comparison -------------------------------------------------------------------------------


def _letter_of(cond: Any, aut: Any) -> frozenset[str]:
    """A letter (set of true atoms) satisfying the BDD ``cond`` over ``aut``'s atoms."""
    for m in range(1 << len(ATOMS)):
        text = " & ".join(a if m >> i & 1 else "!" + a for i, a in enumerate(ATOMS))
        minterm = spot.formula_to_bdd(spot.formula(text), aut.get_dict(), aut)
        if buddy.bdd_and(cond, minterm) != buddy.bddfalse:
            return frozenset(a for i, a in enumerate(ATOMS) if m >> i & 1)
    raise AssertionError("unsatisfiable letter in a word")


def _word_text(letters: tuple[frozenset[str], ...]) -> str:
    return "; ".join(" & ".join(a if a in s else "!" + a for a in ATOMS) for s in letters)


def claims_hold(text: str) -> bool:
    """Whether the HOA's ``deterministic``, ``semi-deterministic`` and ``complete`` claims hold,
    checked by Spot once it has forgotten them."""
    claims = next(line for line in text.splitlines() if line.startswith("properties:")).split()
    aut = spot.automaton(text)
    for prop in ("universal", "semi_deterministic", "complete"):
        getattr(aut, "prop_" + prop)(spot.trival.maybe())
    return (
        ("deterministic" not in claims or spot.is_deterministic(aut))
        and ("semi-deterministic" not in claims or spot.is_semi_deterministic(aut))
        and ("complete" not in claims or spot.is_complete(aut))
    )


def _describe(formula: ast.Formula, word: Any, mine: Any, theirs: Any) -> str:
    """A concrete lasso from Spot's ``word``, who accepts it, and the reference verdict."""
    word.simplify()
    prefix = tuple(_letter_of(c, mine) for c in word.prefix)
    cycle = tuple(_letter_of(c, mine) for c in word.cycle)
    lasso = (_word_text(prefix) + "; " if prefix else "") + "cycle{" + _word_text(cycle) + "}"
    concrete = spot.parse_word(lasso, mine.get_dict()).as_automaton()
    return (
        f"formula: {to_text(formula)}\n  spot: {spot.formula(to_spot(formula))}\n"
        f"  word: {lasso}\n  mitlc accepts: {mine.intersects(concrete)}"
        f"  spot accepts: {theirs.intersects(concrete)}"
        f"  reference semantics: {holds_lasso(formula, Lasso(prefix, cycle))}"
    )


def _mitlc(formula: ast.Formula) -> tuple[Any, str | None]:
    """mitlc's automaton read by Spot, and a complaint when a claimed property is false."""
    text = to_hoa(ldba.translate(formula))
    if not claims_hold(text):
        return None, f"formula: {to_text(formula)}\n  a property claimed in the HOA is false"
    return spot.automaton(text), None


def _complement(aut: Any) -> Any:
    """Spot's complement of ``aut``, or ``None`` when it is too costly: a nondeterministic
    automaton over :data:`COMPLEMENT_LIMIT` states, or one past Spot's 32-set limit."""
    if aut.num_states() > COMPLEMENT_LIMIT and not spot.is_deterministic(aut):
        return None
    try:
        return spot.complement(aut)
    except RuntimeError:
        return None


def mismatch(formula: ast.Formula) -> tuple[bool, str | None]:
    """``(full, problem)``: ``problem`` is ``None`` when mitlc and Spot agree on ``formula``,
    else a description of a word on which they differ.

    mitlc's automaton must meet no word of Spot's automaton for the negation (soundness), and
    its complement none of Spot's automaton for the formula (completeness). When the complement
    is too costly (``full`` is false) mitlc's automaton for the negation is checked for
    soundness instead."""
    mine, problem = _mitlc(formula)
    if problem is not None:
        return True, problem
    negation = ast.Not(formula)
    theirs, theirs_neg = spot.translate(to_spot(formula)), spot.translate(to_spot(negation))
    word = mine.intersecting_word(theirs_neg)
    if word is not None:
        return True, _describe(formula, word, mine, theirs)
    complement = _complement(mine)
    if complement is not None:
        word = theirs.intersecting_word(complement)
        return True, None if word is None else _describe(formula, word, mine, theirs)
    mine_neg, problem = _mitlc(negation)
    if problem is None:
        word = mine_neg.intersecting_word(theirs)
        problem = None if word is None else _describe(negation, word, mine_neg, theirs_neg)
    return False, problem


def test_unroller_matches_the_definitions() -> None:
    cases = {
        "F[1,2] a": "X(a | Xa)",
        "G[1,inf) a": "XGa",
        "a U[0,1] b": "b | (a & Xb)",
        "a U[2,inf) b": "a & X(a & X(a U b))",
        "a R[0,1] b": "b & (a | Xb)",
        "a R[1,inf) b": "a | X(a R b)",
    }
    for text, expected in cases.items():
        ours = spot.formula(to_spot(parse(text)))
        assert spot.are_equivalent(ours, spot.formula(expected)), text


def test_unroller_agrees_with_the_reference_semantics() -> None:
    """Spot's automaton of the unrolled formula accepts a lasso iff mitlc's semantics says the
    formula holds on it, so the gate compares the translation with the intended language."""
    rng = random.Random(5)
    for formula in gate_formulas(5, {0: 30, 3: 30}):
        theirs = spot.translate(to_spot(formula))
        for _ in range(15):
            lasso = random_lasso(rng, rng.randint(0, 3), rng.randint(1, 3), ATOMS)
            prefix = _word_text(lasso.prefix) + "; " if lasso.prefix else ""
            text = prefix + "cycle{" + _word_text(lasso.loop) + "}"
            word = spot.parse_word(text, theirs.get_dict()).as_automaton()
            assert theirs.intersects(word) == holds_lasso(formula, lasso), (to_text(formula), text)


def check(formulas: list[ast.Formula]) -> None:
    """Fail with the five shortest disagreements, if any, or when more than 2% of the formulas
    could only be checked in part."""
    results = [mismatch(f) for f in formulas]
    problems = sorted((p for _, p in results if p is not None), key=len)
    assert not problems, f"{len(problems)} disagreements, shortest first:\n" + "\n".join(
        problems[:5]
    )
    partial = sum(1 for full, _ in results if not full)
    assert partial <= len(formulas) // 50, f"{partial} of {len(formulas)} checked only in part"


@pytest.mark.parametrize("seed", range(4))
def test_translation_agrees_with_spot(seed: int) -> None:
    """250 formulas per seed (1000 in all): 100 from the templates, 100 random of depth 3 and
    50 of depth 4."""
    check(gate_formulas(seed, {0: 100, 3: 100, 4: 50}))


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(100, 104))
def test_translation_agrees_with_spot_at_length(seed: int) -> None:
    """The longer gate (make verify): 1500 formulas per seed, up to depth 5."""
    check(gate_formulas(seed, {0: 500, 3: 500, 4: 450, 5: 50}))


def test_unrolled_size_is_the_length_of_the_unrolled_text() -> None:
    from mitlc.syntax.spot import unrolled_size

    rng = random.Random(5)
    for _ in range(300):
        formula = random_formula(rng, rng.randint(1, 4), ATOMS, bounded=False, max_bound=5)
        assert unrolled_size(formula) == len(to_spot(formula)), to_text(formula)


@pytest.mark.parametrize("seed", range(2))
def test_nested_deadlines_agree_with_spot(seed: int) -> None:
    """100 formulas per seed of nested bounded operators with repeated subformulas under
    different windows (:func:`tests.test_minimize.nested`): what subsumption and the merging of
    bisimilar states act on."""
    from tests.test_minimize import nested

    rng = random.Random(1000 + seed)
    check([nested(rng) for _ in range(100)])
