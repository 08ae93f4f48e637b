"""Symbolic letters: the translation's decision diagrams against the explicit per-letter
translation (``tests/explicit_oracle.py``), letter by letter, and the letter sets of labels."""

from __future__ import annotations

import random

import pytest

from mitlc.automata.classes import Shapes
from mitlc.automata.digital import DigitalAutomaton, DigitalState, Row, _table_row
from mitlc.automata.keys import SINK, Key, Rules
from mitlc.automata.labels import Letters, cube_text, label_text, minimal_cover, submasks
from mitlc.automata.ldba import StateLimitError, Translation, translate_terms
from mitlc.syntax import ast, parse
from tests.explicit_oracle import explicit_rules
from tests.strategies import random_formula

ATOMS = tuple(f"p{i}" for i in range(1, 21))


def _agrees(formula: ast.Formula, translation: Translation, rules: Rules, key_of: int,
            letter: int) -> None:  # fmt: skip
    """The translation's transition of state ``key_of`` on ``letter`` is the oracle's."""
    automaton, keys = translation.automaton, translation.keys
    target, marks = automaton.successor(key_of, letter)
    expected, expected_marks = rules.successor(keys[key_of], letter)
    assert marks == expected_marks, (str(formula), key_of, letter)
    if keys[target] != expected:  # a dead successor: merged into the sink
        assert keys[target] == SINK and expected not in set(keys), (str(formula), key_of, letter)


def _formula(rng: random.Random, atoms: tuple[str, ...]) -> ast.Formula:
    return random_formula(rng, rng.randint(2, 4), atoms, bounded=rng.random() < 0.5, max_bound=4)


@pytest.mark.parametrize(
    ("count", "least"),
    [(500, 25_000), pytest.param(2000, 100_000, marks=pytest.mark.slow)],
)
def test_symbolic_and_explicit_agree_on_every_letter_of_random_formulas(
    count: int, least: int
) -> None:
    """500 random formulas in the default run, the 2,000 (seed 15) in ``make verify``."""
    rng = random.Random(15)
    compared = 0
    for _ in range(count):
        atoms = ("a", "b", "c", "d", "e")[: rng.randint(1, 5)]
        formula = _formula(rng, atoms)
        try:
            translation = translate_terms(formula, max_states=2000, minimal=False)
        except StateLimitError:  # a few random formulas are too big to be worth it here
            continue
        rules = explicit_rules(formula, translation)
        automaton = translation.automaton
        for state in range(len(automaton.states)):
            for letter in range(automaton.num_letters):
                _agrees(formula, translation, rules, state, letter)
                compared += 1
    assert compared > least


def _walk(rng: random.Random, formula: ast.Formula, steps: int) -> int:
    try:
        translation = translate_terms(formula, max_states=20_000, minimal=False)
    except StateLimitError:
        return 0
    rules = explicit_rules(formula, translation)
    automaton, n = translation.automaton, len(translation.automaton.propositions)
    state, walked = automaton.initial, 0
    for _ in range(steps):
        jumps = automaton.jumps(state)
        if jumps and rng.random() < 0.3:
            state = rng.choice(jumps)
        letter = rng.getrandbits(n) if rng.random() < 0.5 else 1 << rng.randrange(max(n, 1))
        _agrees(formula, translation, rules, state, letter & ((1 << n) - 1))
        state = automaton.successor(state, letter)[0]
        walked += 1
    return walked


def test_symbolic_and_explicit_agree_on_random_letters_with_up_to_20_propositions() -> None:
    rng = random.Random(20)
    walked = 0
    for _ in range(300):
        atoms = tuple(rng.sample(ATOMS, rng.randint(6, 20)))
        walked += _walk(rng, _formula(rng, atoms), 40)
    assert walked >= 280 * 40


def _sequence(n: int) -> str:
    inner = f"!p{n} U[0,20] p{n}"
    for i in range(n - 1, 0, -1):
        inner = f"!p{i} U[0,20] (p{i} & X ({inner}))"
    return inner


@pytest.mark.parametrize(
    "text",
    [
        _sequence(20),
        "G (" + " & ".join(f"F p{i}" for i in range(1, 9)) + ")",
        "G (p1 -> F[0,10] (" + " | ".join(f"p{i}" for i in range(2, 11)) + "))",
        "G !(p1 | p2 | p3) & (!p4 U[0,5] (p4 & X (!p5 U[0,5] p5))) & G F p6 & F G !p7",
    ],
)
def test_large_alphabets_agree_on_random_letters(text: str) -> None:
    assert _walk(random.Random(text), parse(text), 400) == 400


def test_a_state_has_one_transition_per_class_it_tells_apart() -> None:
    translation = translate_terms(parse(_sequence(12)))
    automaton = translation.automaton
    assert len(automaton.propositions) == 12
    # each state waits for one room: it reads one or two propositions, never the other ten
    assert max(row.reads.bit_count() for row in automaton.rows) <= 2
    assert max(len(row.targets) for row in automaton.rows) <= 3


def test_rows_of_explicit_tables_round_trip() -> None:
    rng = random.Random(4)
    for n in range(4):
        states = (DigitalState("x", "initial", "pending"),) * 3
        delta = [[rng.randrange(3) for _ in range(1 << n)] for _ in range(3)]
        marks = [[rng.randrange(2) for _ in range(1 << n)] for _ in range(3)]
        built = DigitalAutomaton.from_table("x", "x", ATOMS[:n], states, 0, delta, marks, 1)
        assert [list(row) for row in built.delta] == delta
        assert [list(row) for row in built.marks] == marks
        for s in range(3):
            union = Letters.of(0, ())
            for target, mark, letters in built.edges(s):
                assert all((delta[s][m], marks[s][m]) == (target, mark) for m in letters.letters(n))
                assert (union & letters).is_empty
                union = union | letters
            assert union.letters(n) == list(range(1 << n))


def test_letter_sets_are_canonical_and_write_the_explicit_labels() -> None:
    rng = random.Random(6)
    names = ("a", "b", "c", "d", "e", "f")
    for _ in range(300):
        n = rng.randint(0, 6)
        wanted = {m for m in range(1 << n) if rng.random() < 0.4}
        mask = (1 << n) - 1
        letters = Letters.of(mask, wanted)
        assert set(letters.letters(n)) == wanted
        # the cover over the support is the minimal cover over every proposition
        for style in ("spec", "hoa"):
            whole = minimal_cover(wanted, n)
            expected = " | ".join(cube_text(c, names[:n], style) for c in whole)
            expected = expected or ("false" if style == "spec" else "f")
            assert letters.text(names[:n], style) == expected
            assert label_text(wanted, names[:n], style) == expected
        # canonical: the same set given over a larger support is the same value
        wider = Letters.of(mask | 1 << n, [m | x for m in wanted for x in (0, 1 << n)])
        assert wider == letters
        assert Letters.of_cubes([(mask, m) for m in wanted]) == letters
    assert Letters.of(3, submasks(3)).is_everything
    assert Letters.of(3, ()).is_empty


def test_keys_of_the_oracle_and_the_translation_compare() -> None:
    formula = parse("(!a U[2,4] a) & G F b")
    translation = translate_terms(formula)
    rules = explicit_rules(formula, translation)
    assert rules.start() == translation.keys[translation.automaton.initial]
    assert isinstance(rules.start(), Key)


def _random_row(rng: random.Random, num_props: int) -> Row:
    """A row over ``num_props`` propositions with a few transitions, reading some of them."""
    reads = rng.randrange(1 << num_props)
    outcomes = [(rng.randrange(3), 0) for _ in range(1 << num_props)]
    targets = [outcomes[letter & reads][0] for letter in range(1 << num_props)]
    return _table_row(targets, [0] * len(targets), num_props)


@pytest.mark.parametrize("num_props", [1, 3, 4, 6])
def test_classes_of_rows_taken_together_are_those_of_every_letter(num_props: int) -> None:
    """``Shapes.classes`` (one shape, letter by letter, or by diagrams) against the tuples of
    transitions read letter by letter: the same classes, by least letter, with their letters."""
    rng = random.Random(num_props)
    shapes = Shapes()
    for low, high in ((~0, ~1), (~1, ~0)):  # one test, its transitions either way round
        found = shapes.classes([Row(0, ((2, low, high),), (5, 6), (0, 0))])
        assert found.transitions == ((~low,), (~high,))
        assert found.letters == (Letters.of(4, [0]), Letters.of(4, [4]))
    assert shapes.classes([Row.constant(3)]).letters == (Letters.everything(),)
    for _ in range(60):
        rows = [_random_row(rng, num_props) for _ in range(rng.randint(1, 4))]
        rows += rng.sample(rows, rng.randint(0, len(rows)))  # some shapes twice
        found = shapes.classes(rows)
        expected: dict[tuple[int, ...], list[int]] = {}
        for letter in range(1 << num_props):
            expected.setdefault(tuple(row.transition(letter) for row in rows), []).append(letter)
        assert len(found.transitions) == len(expected)
        everything = (1 << num_props) - 1
        for each, cubes, label, (transitions, letters) in zip(
            found.transitions, found.cubes, found.letters, expected.items(), strict=True
        ):
            assert [each[p] for p in found.position] == list(transitions)
            assert Letters.of_cubes(cubes).letters(num_props) == letters
            assert label == Letters.of(everything, letters)
