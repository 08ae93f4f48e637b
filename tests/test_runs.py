"""Unit tests of :mod:`mitlc.automata.runs` on hand-built automata with hand-known answers,
and an exhaustive cross-check of each automaton against the reference semantics."""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence

import pytest

from mitlc.automata.digital import Component, DigitalAutomaton, DigitalState, Verdict
from mitlc.automata.runs import accepts_lasso, run_states
from mitlc.semantics import Lasso, holds_lasso
from mitlc.syntax import parse

E: frozenset[str] = frozenset()
A = frozenset({"a"})
B = frozenset({"b"})
AB = frozenset({"a", "b"})


def automaton(
    formula: str,
    propositions: tuple[str, ...],
    states: Sequence[tuple[str, Component, Verdict]],
    delta: Sequence[Sequence[int]],
    marks: Sequence[Sequence[int]],
    num_sets: int,
    epsilon: tuple[tuple[int, int], ...] = (),
    initial: int = 0,
) -> DigitalAutomaton:
    return DigitalAutomaton.from_table(
        source=formula,
        formula=formula,
        propositions=propositions,
        states=tuple(DigitalState(*s) for s in states),
        initial=initial,
        delta=tuple(tuple(row) for row in delta),
        marks=tuple(tuple(row) for row in marks),
        num_sets=num_sets,
        epsilon=epsilon,
    )


# Letters over ("a",): 0 = {}, 1 = {a}. Over ("a", "b"): 0 = {}, 1 = {a}, 2 = {b}, 3 = {a, b}.

GF_A = automaton("G F a", ("a",), [("G F a", "accepting", "pending")], [[0, 0]], [[0, 1]], 1)

FG_A = automaton(
    "F G a",
    ("a",),
    [
        ("F G a", "initial", "pending"),
        ("G a", "accepting", "pending"),
        ("false", "accepting", "violated"),
    ],
    [[0, 0], [2, 1], [2, 2]],
    [[0, 0], [0, 1], [0, 0]],
    1,
    epsilon=((0, 1),),
)

G_A = automaton(
    "G a",
    ("a",),
    [("G a", "initial", "pending"), ("false", "initial", "violated")],
    [[1, 0], [1, 1]],
    [[0, 0], [0, 0]],
    0,
)

# G a again, with a useless jump to a copy: exercises the general (non-deterministic) search.
G_A_JUMP = automaton(
    "G a",
    ("a",),
    [
        ("G a", "initial", "pending"),
        ("G a", "accepting", "pending"),
        ("false", "accepting", "violated"),
    ],
    [[2, 0], [2, 1], [2, 2]],
    [[0, 0], [0, 0], [0, 0]],
    0,
    epsilon=((0, 1),),
)

GF_A_GF_B = automaton(
    "G F a & G F b",
    ("a", "b"),
    [("G F a & G F b", "accepting", "pending")],
    [[0] * 4],
    [[0, 1, 2, 3]],
    2,
)

# Eventually a alternates: the jump must land in the state matching the loop's phase.
FG_ALT = automaton(
    "F G (a <-> X !a)",
    ("a",),
    [
        ("F G (a <-> X !a)", "initial", "pending"),
        ("a & G (a <-> X !a)", "accepting", "pending"),
        ("!a & G (a <-> X !a)", "accepting", "pending"),
        ("false", "accepting", "violated"),
    ],
    [[0, 0], [3, 2], [1, 3], [3, 3]],
    [[0, 0], [0, 1], [1, 0], [0, 0]],
    1,
    epsilon=((0, 1), (0, 2)),
)

ALL = [GF_A, FG_A, G_A, G_A_JUMP, GF_A_GF_B, FG_ALT]


def lasso(prefix: Sequence[frozenset[str]], loop: Sequence[frozenset[str]]) -> Lasso:
    return Lasso(tuple(prefix), tuple(loop))


@pytest.mark.parametrize(
    ("aut", "prefix", "loop", "expected"),
    [
        # G F a: only the loop matters.
        (GF_A, [], [A], True),
        (GF_A, [A, A, A], [E], False),
        (GF_A, [E, E], [E, E, A], True),
        (GF_A, [A], [E, E], False),
        # F G a: needs the jump, at a position from which a holds forever.
        (FG_A, [], [A], True),
        (FG_A, [E, E, A, E], [A], True),
        (FG_A, [E], [A, A, E], False),
        (FG_A, [A, A], [E], False),
        (FG_A, [A, E], [A, A], True),
        # G a: safety with a violated sink (whose self-loop must not count).
        (G_A, [], [A], True),
        (G_A, [A, A, A], [A, A], True),
        (G_A, [A, E], [A], False),
        (G_A, [A], [A, E], False),
        (G_A, [], [E], False),
        (G_A_JUMP, [A, A], [A], True),
        (G_A_JUMP, [A], [A, A, E], False),
        (G_A_JUMP, [E], [A], False),
        # G F a & G F b: both sets, possibly on different transitions of the loop.
        (GF_A_GF_B, [], [AB], True),
        (GF_A_GF_B, [], [A, B], True),
        (GF_A_GF_B, [], [A, E, E, B], True),
        (GF_A_GF_B, [AB, AB], [A], False),
        (GF_A_GF_B, [AB], [B, E], False),
        (GF_A_GF_B, [], [E], False),
        # F G (a <-> X !a): the accepting cycle exists only in the loop, at the right phase.
        (FG_ALT, [A, A], [A, E], True),
        (FG_ALT, [A], [E, A], True),
        (FG_ALT, [A, E], [A, A, E], False),
        (FG_ALT, [], [A, E, A], False),
        (FG_ALT, [E, E, E], [A, E, A, E], True),
    ],
)
def test_hand_known(
    aut: DigitalAutomaton, prefix: list[frozenset[str]], loop: list[frozenset[str]], expected: bool
) -> None:
    assert accepts_lasso(aut, lasso(prefix, loop)) is expected


def all_lassos(propositions: tuple[str, ...], max_prefix: int, max_loop: int) -> Iterator[Lasso]:
    letters = [
        frozenset(p for i, p in enumerate(propositions) if n >> i & 1)
        for n in range(1 << len(propositions))
    ]
    for prefix_len in range(max_prefix + 1):
        for loop_len in range(1, max_loop + 1):
            for prefix in itertools.product(letters, repeat=prefix_len):
                for loop in itertools.product(letters, repeat=loop_len):
                    yield Lasso(prefix, loop)


@pytest.mark.parametrize("aut", ALL, ids=lambda a: f"{a.formula}/{a.num_sets}")
def test_agrees_with_semantics_exhaustively(aut: DigitalAutomaton) -> None:
    formula = parse(aut.formula)
    bound = 4 if len(aut.propositions) == 1 else 2
    for word in all_lassos(aut.propositions, bound, bound):
        assert accepts_lasso(aut, word) == holds_lasso(formula, word), word


def test_violated_initial_state_rejects_everything() -> None:
    false = automaton("false", ("a",), [("false", "initial", "violated")], [[0, 0]], [[0, 0]], 0)
    assert not accepts_lasso(false, lasso([], [A]))
    assert not accepts_lasso(false, lasso([A], [E]))


def test_true_with_zero_sets_accepts_everything() -> None:
    true = automaton("true", ("a",), [("true", "initial", "satisfied")], [[0, 0]], [[0, 0]], 0)
    assert accepts_lasso(true, lasso([], [A]))
    assert accepts_lasso(true, lasso([E, A], [E]))


def test_jump_at_the_last_canonical_position() -> None:
    # The loop is a single letter repeated; the jump must happen inside the loop part.
    assert accepts_lasso(FG_A, lasso([E, E, E], [A]))
    assert not accepts_lasso(FG_A, lasso([E, E, E], [E]))


def test_run_states() -> None:
    assert run_states(G_A, []) == [0]
    assert run_states(G_A, [A, A, E, A]) == [0, 0, 0, 1, 1]
    assert run_states(FG_A, [A, E]) == [0, 0, 0]
    assert run_states(FG_ALT, [A]) == [0, 0]
