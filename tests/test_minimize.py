"""Small automata for nested deadlines (issue 25): subsumption in the store, bisimilar states
merged, and the sizes that follow (quadratic in the bound, Spot's where compared)."""

from __future__ import annotations

import random

import pytest

from mitlc.automata import StateLimitError, compile_formula
from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.ldba import translate, translate_terms
from mitlc.automata.minimize import bisimulation
from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, RELEASE, UNTIL, TermStore
from mitlc.semantics import Lasso, holds_lasso
from mitlc.syntax import ast, parse, to_text
from tests.strategies import ATOMS, random_formula, random_lasso

F, G, X, N = ast.Eventually, ast.Always, ast.Next, ast.Not
U, R, And, Or, Imp = ast.Until, ast.Release, ast.And, ast.Or, ast.Implies
MAX_BOUND = 4


def nested(rng: random.Random) -> ast.Formula:
    """A formula of nested bounded operators with a subformula repeated under different
    windows (what subsumption and merging act on)."""

    def small() -> ast.Formula:
        return random_formula(rng, rng.choice((0, 1, 1, 2)), ATOMS, True, 2)

    def window() -> ast.Interval:
        lo = rng.randint(0, 2)
        return ast.Interval(lo, rng.randint(max(lo, 1), MAX_BOUND))

    p, q, r = small(), small(), small()
    i, j, k = window(), window(), window()
    shapes = (
        lambda: F(i, And(p, F(j, q))),
        lambda: G(ast.Interval(0, None), Imp(p, F(i, And(q, F(j, r))))),
        lambda: Or(F(i, p), F(j, p)),
        lambda: Or(G(i, p), G(j, p)),
        lambda: And(G(i, p), G(j, p)),
        lambda: Or(U(i, p, q), U(j, p, q)),
        lambda: And(R(i, p, q), R(j, p, q)),
        lambda: F(i, G(j, p)),
        lambda: F(i, And(p, X(F(j, And(q, X(F(k, r))))))),
        lambda: Or(G(ast.Interval(0, None), F(i, p)), F(ast.Interval(0, None), G(j, q))),
        lambda: U(i, p, And(q, F(j, Or(p, r)))),
    )
    return rng.choice(shapes)()


# --- subsumption in the store ---------------------------------------------------------------------


def test_a_disjunct_implied_by_another_is_dropped() -> None:
    store = TermStore(("a", "b"))
    a, b = store.literal(0, True), store.literal(1, True)
    late, early = store.temporal(EVENTUALLY, 0, 3, a), store.temporal(EVENTUALLY, 0, 2, a)
    assert store.or_(late, early) == late
    shifted = store.temporal(EVENTUALLY, 1, 2, a)
    assert store.or_(late, shifted) == late
    g5, g4 = store.temporal(ALWAYS, 0, 5, a), store.temporal(ALWAYS, 0, 4, a)
    assert store.or_(g5, g4) == g4 and store.and_(g5, g4) == g5
    u3, u2 = store.temporal(UNTIL, 0, 3, a, b), store.temporal(UNTIL, 0, 2, a, b)
    assert store.or_(u3, u2) == u3 and store.and_(u3, u2) == u2
    r3, r2 = store.temporal(RELEASE, 0, 3, a, b), store.temporal(RELEASE, 0, 2, a, b)
    assert store.or_(r3, r2) == r2 and store.and_(r3, r2) == r3
    # with the rest of the cube alike: (b & F[0,2] a) | (b & F[0,3] a) is b & F[0,3] a
    assert store.or_(store.and_(b, early), store.and_(b, late)) == store.and_(b, late)
    # windows apart, or of different operands, stay
    apart = store.temporal(EVENTUALLY, 4, 5, a)
    assert len(store.forms[store.or_(early, apart)]) == 2
    assert len(store.forms[store.or_(early, store.temporal(EVENTUALLY, 0, 3, b))]) == 2


def test_a_delay_is_dropped_for_a_window_of_its_strength_only() -> None:
    """The strong delay ``F[2,2] G a`` implies ``F[1,3] G a`` on finite traces too (both fail
    at the end): the disjunction is the window. The weak ``G[2,2] G a`` holds at the end where
    ``F[1,3] G a`` fails, so both stay; it is implied by ``G[1,3] G a``."""
    store = TermStore(("a",))
    always = store.temporal(ALWAYS, 0, INF, store.literal(0, True))
    strong, window = store.delay(2, always), store.temporal(EVENTUALLY, 1, 3, always)
    assert store.or_(strong, window) == window
    weak = store.delay(2, always, strong=False)
    assert len(store.forms[store.or_(weak, window)]) == 2
    assert store.or_(weak, store.temporal(ALWAYS, 1, 3, always)) == weak


# --- merging bisimilar states ---------------------------------------------------------------------


def assert_bisimulation(automaton: DigitalAutomaton, block: list[int]) -> None:
    """Every two states of a block agree on component, verdict and end, on every letter's
    marks and target block, and on their jumps' target blocks, in order."""
    first: dict[int, int] = {}
    for s, b in enumerate(block):
        first.setdefault(b, s)
    for s, b in enumerate(block):
        t = first[b]
        one, other = automaton.states[s], automaton.states[t]
        assert (one.component, one.verdict, one.end) == (other.component, other.verdict, other.end)
        for letter in range(automaton.num_letters):
            (u, m), (v, n) = automaton.successor(s, letter), automaton.successor(t, letter)
            assert m == n and block[u] == block[v], (automaton.source, s, t, letter)
        assert [block[j] for j in automaton.jumps(s)] == [block[j] for j in automaton.jumps(t)]


def words_agree(full: DigitalAutomaton, small: DigitalAutomaton, rng: random.Random) -> None:
    """Both automata read random words in lockstep with the same verdicts, ends and marks."""
    for _ in range(20):
        s, t = full.initial, small.initial
        for _ in range(rng.randint(1, 15)):
            letter = rng.randrange(full.num_letters)
            (s, m), (t, n) = full.successor(s, letter), small.successor(t, letter)
            assert m == n
            assert (full.verdict(s), full.end(s)) == (small.verdict(t), small.end(t))


@pytest.mark.parametrize("seed", range(3))
def test_merged_states_are_bisimilar_and_keep_the_words(seed: int) -> None:
    rng = random.Random(seed)
    merged = 0
    for _ in range(60):
        formula = nested(rng)
        full = translate(formula, minimal=False)
        block = bisimulation(full)
        assert_bisimulation(full, block)
        small = translate(formula)
        assert len(small.states) == len(set(block)) <= len(full.states)
        merged += len(small.states) < len(full.states)
        words_agree(full, small, rng)
        for _ in range(5):
            lasso = random_lasso(rng, rng.randint(0, 3), rng.randint(1, 3), ATOMS)
            assert _accepts(small, lasso) == holds_lasso(formula, lasso) or small.epsilon
    assert merged > 0


def coarsest(automaton: DigitalAutomaton) -> int:
    """The number of classes of the coarsest bisimulation, by the textbook refinement: every
    state against every letter, from the partition by component, verdict and end."""
    n, letters = len(automaton.states), range(automaton.num_letters)
    block = [hash((s.component, s.verdict, s.end)) for s in automaton.states]
    while True:
        signatures = [
            (
                block[s],
                tuple((block[t], m) for t, m in (automaton.successor(s, x) for x in letters)),
                tuple(block[j] for j in automaton.jumps(s)),
            )
            for s in range(n)
        ]
        ids: dict[object, int] = {}
        refined = [ids.setdefault(x, len(ids)) for x in signatures]
        if len(ids) == len(set(block)):
            return len(ids)
        block = refined


def test_the_merge_is_the_coarsest_bisimulation() -> None:
    """On 300 random formulas (half nested deadlines, half of any shape), as many classes as
    the textbook refinement finds."""
    rng = random.Random(7)
    compared = 0
    for i in range(300):
        formula = nested(rng) if i % 2 else random_formula(rng, 3, ATOMS, False, 3)
        try:
            full = translate(formula, minimal=False, max_states=3000)
        except StateLimitError:
            continue
        if full.num_letters <= 16:
            assert len(set(bisimulation(full))) == coarsest(full), to_text(formula)
            compared += 1
    assert compared > 250


def _accepts(automaton: DigitalAutomaton, lasso: Lasso) -> bool:
    """Whether a deterministic automaton accepts the lasso: its run enters the loop's cycle
    of (state, position) pairs and sees every acceptance set there."""
    letters = [automaton.letter_index(set(x)) for x in (*lasso.prefix, *lasso.loop)]
    start, state, seen = len(lasso.prefix), automaton.initial, {}
    position, marks = 0, []
    while True:
        if position >= start and (state, position) in seen:
            cycle = marks[seen[(state, position)] :]
            union = 0
            for m in cycle:
                union |= m
            if automaton.num_sets == 0:
                return automaton.verdict(state) != "violated"
            return union == automaton.all_sets
        if position >= start:
            seen[(state, position)] = len(marks)
        state, m = automaton.successor(state, letters[position])
        marks.append(m)
        position = position + 1 if position + 1 < len(letters) else start


def test_the_quotient_is_what_the_folding_and_the_product_read() -> None:
    """``translate_terms`` gives the merged automaton with the key of each kept state, which
    the folding reads: ``F[0,k] G[0,k] a`` folds into 7 locations and 2 clocks."""
    translation = translate_terms(parse("F[0,8] G[0,8] a"))
    assert len(translation.keys) == len(translation.automaton.states) == 47
    compiled = compile_formula(parse("F[0,8] G[0,8] a"))
    assert len(compiled.digital.states) == 47
    assert (len(compiled.timed.locations), len(compiled.timed.clock_bounds)) == (7, 2)


# --- the sizes ------------------------------------------------------------------------------------


def test_reach_a_then_b_within_k_grows_quadratically() -> None:
    """``F[0,k] (a & F[0,k] b)``: ``(k+1)(k+2)/2 + k + 2`` states (Spot's 15, 28, 55, 78 at
    k = 3, 5, 8, 10), where it was ``3 * 2^k``; 6 locations and 2 clocks for every k."""
    for k in (2, 3, 5, 8, 10, 20, 40):
        compiled = compile_formula(parse(f"F[0,{k}] (a & F[0,{k}] b)"))
        assert len(compiled.digital.states) == (k + 1) * (k + 2) // 2 + k + 2, k
        assert (len(compiled.timed.locations), len(compiled.timed.clock_bounds)) == (6, 2)


def test_bounded_response_keeps_three_locations() -> None:
    for k in (3, 10, 100):
        compiled = compile_formula(parse(f"G (a -> F[0,{k}] b)"))
        assert len(compiled.digital.states) == k + 2
        assert len(compiled.timed.locations) == 3
