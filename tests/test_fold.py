"""Folding: the T-LDGBA simulates the digital automaton exactly, and folds the paper's tasks
into the paper's locations."""

from __future__ import annotations

import itertools
import random
from collections import deque

import pytest

from mitlc.automata.fold import fold
from mitlc.automata.ldba import Translation, translate_terms
from mitlc.automata.tldgba import Tldgba
from mitlc.syntax import parse, parse_file
from tests.conftest import ROOT
from tests.strategies import random_formula

PAPER = ROOT / "specs" / "paper"


def check_simulates(translation: Translation, timed: Tldgba) -> int:
    """:func:`simulate`; the number of pairs visited."""
    return len(simulate(translation, timed))


def simulate(translation: Translation, timed: Tldgba) -> dict[tuple[int, tuple[int, ...]], int]:
    """Run the T-LDGBA (clock semantics of DESIGN.md) in lockstep with the digital automaton
    from their initial states; every reachable (location, valuation) must stand for one digital
    state, with the same successors, marks and jumps. Returns the digital state each
    (location, values of its clocks) visited stands for."""
    digital = translation.automaton
    start = (timed.initial, tuple(0 for _ in timed.clock_bounds))
    stands_for: dict[tuple[int, tuple[int, ...]], int] = {}
    queue = deque([(start, digital.initial)])
    while queue:
        (loc, valuation), state = queue.popleft()
        used = timed.locations[loc].clocks
        key = (loc, tuple(valuation[c] for c in used))
        if key in stands_for:
            assert stands_for[key] == state, f"location {loc} at {key[1]} stands for two states"
            continue
        stands_for[key] = state
        assert timed.locations[loc].verdict == digital.states[state].verdict
        for letter in range(digital.num_letters):
            (edge,) = timed.enabled(loc, letter, valuation)  # exactly one edge: deterministic
            target = digital.delta[state][letter]
            marks = sum(1 << k for k in edge.acc)
            assert marks == digital.marks[state][letter], (loc, letter, valuation)
            queue.append(((edge.target, timed.advance(edge, valuation)), target))
        jumps = [j for j in timed.epsilon if j.source == loc]
        digital_jumps = digital.jumps_from(state)
        assert len(jumps) == len(set(digital_jumps)), (loc, state)
        for jump, target in zip(
            sorted(jumps, key=lambda j: j.target), sorted(digital_jumps), strict=False
        ):
            queue.append(((jump.target, timed.advance(jump, valuation)), target))
    return stands_for


def check_complete(timed: Tldgba) -> None:
    """Every location, letter and valuation of its clocks enables exactly one edge."""
    for location in timed.locations:
        ranges = [range(timed.clock_bounds[c] + 1) for c in location.clocks]
        assert len(location.clocks) <= 3
        for values in itertools.product(*ranges):
            valuation = [0] * len(timed.clock_bounds)
            for c, v in zip(location.clocks, values, strict=True):
                valuation[c] = v
            for letter in range(1 << len(timed.propositions)):
                edges = timed.enabled(location.id, letter, tuple(valuation))
                assert len(edges) == 1, (location.id, letter, valuation, edges)


@pytest.mark.parametrize(
    "text",
    [
        "(!a U[5,10] a) & (!b U[15,20] b)",
        "G (a -> F[0,5] b)",
        "G F[5,10] a",
        "G (a -> X X F b)",
        "F G a",
        "G F a | F G b",
        "(!printer U[5,inf) printer) & (!a U[10,inf) a) & (!a U printer)",
        "G (a -> F[2,4] b) & F G !c",
    ],
)
def test_fold_simulates_digital(text: str) -> None:
    translation = translate_terms(parse(text))
    timed = fold(translation)
    assert check_simulates(translation, timed) >= len(translation.automaton.states) - 1
    check_complete(timed)


def test_fold_random_formulas() -> None:
    rng = random.Random(11)
    for _ in range(150):
        formula = random_formula(rng, rng.randint(1, 4), ["a", "b"], bounded=False, max_bound=4)
        translation = translate_terms(formula)
        timed = fold(translation)
        check_simulates(translation, timed)
        check_complete(timed)
        assert len(timed.locations) <= len(translation.automaton.states)


def test_case1_folds_into_waiting_for_a_waiting_for_b_satisfied_and_sink() -> None:
    timed = fold(translate_terms(parse_file(PAPER / "case1.mitl")))
    assert len(timed.clock_bounds) == 1
    assert [loc.verdict for loc in timed.locations].count("pending") == 2
    assert {loc.verdict for loc in timed.locations} == {"pending", "satisfied", "violated"}
    assert len(timed.locations) == 4
    wait_a, wait_b = (loc for loc in timed.locations if loc.verdict == "pending")
    # The edge that reads a inside [5,10] goes from waiting for a to waiting for b.
    to_b = [e for e in timed.edges if e.source == wait_a.id and e.target == wait_b.id]
    assert [e.guard for e in to_b] == [((0, 5, 10),)]


def test_case1_patrol_folds_into_the_papers_three_locations() -> None:
    timed = fold(translate_terms(parse_file(PAPER / "case1-patrol.mitl")))
    assert len(timed.locations) == 3
    assert len(timed.clock_bounds) == 1
    assert sorted(loc.verdict for loc in timed.locations) == ["pending", "pending", "violated"]
    # Reading b inside [15,20] restarts the round: back to waiting for a, clock reset.
    back = [e for e in timed.edges if e.source != e.target and e.target == timed.initial]
    assert back and all(e.reset == (0,) and e.guard == ((0, 15, 20),) for e in back)


@pytest.mark.parametrize("k", [5, 40, 1000])
def test_response_keeps_a_constant_number_of_locations(k: int) -> None:
    timed = fold(translate_terms(parse(f"G (a -> F[0,{k}] b)")))
    assert len(timed.locations) == 3
    assert timed.clock_bounds == (k - 1,)  # reading a spawns F[0,k-1] b for the next step
