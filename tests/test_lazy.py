"""The lazy automaton against the eager translation: same states, marks, jumps and verdicts.

Obligations are compared through their normal form in one shared term store: the two
translations intern the same formulas in different orders, so a conjunction may be printed
with its conjuncts in another order (about one state in four thousand), while its normal form
is the same.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterator

import pytest

from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.keys import Key, Rules
from mitlc.automata.lazy import LazyAutomaton
from mitlc.automata.ldba import StateLimitError, TranslationError, translate
from mitlc.automata.normalize import normalize
from mitlc.automata.runs import run_states
from mitlc.automata.terms import TermStore
from mitlc.semantics import Lasso, holds_lasso
from mitlc.syntax import ast, parse
from mitlc.syntax.parser import read_spec
from tests.test_translate_lasso import FAMILIES

MAX_STATES = 3_000
PAPER_SPECS = ("case1", "case1-literal", "case1-patrol", "case2", "case3")
EXTRA = (
    "F G a",
    "G F a",
    "G F a & G F b",
    "F G a | G F b",
    "a U b",
    "a R b",
    "G (a -> F[0,3] b)",
    "F[2,5] G[0,2] a",
    "G F[1,3] a & F G !b",
    "(a U[0,4] b) R (F c)",
    "X X (a U G b)",
    "G (F a -> F[0,2] c)",
    "F G (a | X b) & G F c",
)


def _formulas() -> Iterator[tuple[str, ast.Formula]]:
    """(group, formula): the paper's tasks and hand-picked shapes, then random families."""
    for name in PAPER_SPECS:
        yield "paper", parse(read_spec(f"specs/paper/{name}.mitl"))
    for text in EXTRA:
        yield "paper", parse(text)
    for name, family in FAMILIES.items():
        rng = random.Random(f"lazy-{name}")
        for _ in range(40):
            yield name, family(rng)


def _canon(propositions: tuple[str, ...]) -> Callable[[str], int]:
    store = TermStore(propositions)
    return lambda text: normalize(parse(text), store)


def _matching_jump(
    eager: DigitalAutomaton, lazy: LazyAutomaton, e: int, lz: int, canon: Callable[[str], int]
) -> dict[int, int]:
    """The eager jumps of ``e`` paired with those of ``lz`` whose obligation no other shares."""
    ej, lj = eager.jumps_from(e), lazy.jumps(lz)
    assert len(ej) == len(lj)
    eager_forms = [canon(eager.states[t].obligation) for t in ej]
    lazy_forms = [canon(lazy.obligation(t)) for t in lj]
    assert sorted(eager_forms) == sorted(lazy_forms)
    return {
        t: lj[lazy_forms.index(form)]
        for t, form in zip(ej, eager_forms, strict=True)
        if eager_forms.count(form) == 1
    }


def _same_state(
    eager: DigitalAutomaton, lazy: LazyAutomaton, e: int, lz: int, canon: Callable[[str], int]
) -> None:
    state = eager.states[e]
    assert lazy.verdict(lz) == state.verdict
    assert lazy.component(lz) == state.component
    obligation = lazy.obligation(lz)
    assert obligation == state.obligation or canon(obligation) == canon(state.obligation)


def _isomorphic(formula: ast.Formula, eager: DigitalAutomaton, lazy: LazyAutomaton) -> None:
    """Breadth-first over every letter and jump: eager and lazy states pair one to one."""
    canon = _canon(eager.propositions)
    pair = {eager.initial: lazy.initial}
    back = {lazy.initial: eager.initial}
    frontier = [eager.initial]
    while frontier:
        e = frontier.pop()
        lz = pair[e]
        _same_state(eager, lazy, e, lz, canon)
        moves = [
            (eager.delta[e][x], *lazy.successor(lz, x), eager.marks[e][x])
            for x in range(eager.num_letters)
        ]
        moves += [(t, u, 0, 0) for t, u in _matching_jump(eager, lazy, e, lz, canon).items()]
        for et, lt, lazy_marks, eager_marks in moves:
            assert lazy_marks == eager_marks, formula
            if et not in pair:
                assert lt not in back, formula
                pair[et], back[lt] = lt, et
                frontier.append(et)
            assert pair[et] == lt, formula
    assert lazy.num_states == len(pair)


def _walk(eager: DigitalAutomaton, lazy: LazyAutomaton, rng: random.Random, steps: int) -> None:
    """A random run of letters and jumps, taken in both automata."""
    canon = _canon(eager.propositions)
    e, lz = eager.initial, lazy.initial
    for _ in range(steps):
        _same_state(eager, lazy, e, lz, canon)
        jumps = _matching_jump(eager, lazy, e, lz, canon)
        if jumps and rng.random() < 0.3:
            e = rng.choice(sorted(jumps))
            lz = jumps[e]
            continue
        letter = rng.randrange(eager.num_letters)
        lz, marks = lazy.successor(lz, letter)
        assert marks == eager.marks[e][letter]
        e = eager.delta[e][letter]


def _translated() -> Iterator[tuple[str, ast.Formula, DigitalAutomaton]]:
    for group, formula in _formulas():
        try:
            yield group, formula, translate(formula, max_states=MAX_STATES)
        except TranslationError:
            continue


CASES = list(_translated())


@pytest.mark.parametrize("group", ["paper", *FAMILIES])
def test_lazy_walks_like_eager(group: str) -> None:
    rng = random.Random(group)
    cases = [case for case in CASES if case[0] == group]
    assert len(cases) >= 10
    for _, formula, eager in cases:
        lazy = LazyAutomaton(formula)
        assert lazy.propositions == eager.propositions
        assert lazy.num_sets == eager.num_sets
        for _ in range(4):
            _walk(eager, lazy, rng, 40)


def test_lazy_is_isomorphic_to_eager() -> None:
    for _, formula, eager in CASES:
        if len(eager.states) <= 400:
            _isomorphic(formula, eager, LazyAutomaton(formula))


def test_successor_reads_only_its_mask() -> None:
    """``successor(key, letter) == successor(key, letter & reads(key))``, for every key."""
    for _, formula, eager in CASES[:150]:
        rules = Rules.of(formula)
        seen: set[Key] = {rules.start()}
        frontier = [rules.start()]
        while frontier and len(seen) < 300:
            key = frontier.pop()
            mask = rules.reads(key)
            for letter in range(eager.num_letters):
                target = rules.successor(key, letter)
                assert target == rules.successor(key, letter & mask), (formula, key)
                for found in (target[0], *rules.jumps(key)):
                    if found not in seen:
                        seen.add(found)
                        frontier.append(found)


# --- beyond the eager table ------------------------------------------------------------------


def _sequence(n: int, window: int) -> ast.Formula:
    """``!p1 U[0,w] (p1 & X (!p2 U[0,w] (p2 & X (... (!pn U[0,w] pn)))))``."""
    interval = ast.Interval(0, window)
    inner: ast.Formula = ast.Until(interval, ast.Not(ast.Atom(f"p{n}")), ast.Atom(f"p{n}"))
    for i in range(n - 1, 0, -1):
        p = ast.Atom(f"p{i}")
        inner = ast.Until(interval, ast.Not(p), ast.And(p, ast.Next(inner)))
    return inner


def _run_lazy(lazy: LazyAutomaton, word: list[frozenset[str]]) -> list[str]:
    state, verdicts = lazy.initial, [str(lazy.verdict(lazy.initial))]
    index = {p: i for i, p in enumerate(lazy.propositions)}
    for letter in word:
        state, _ = lazy.successor(state, sum(1 << index[p] for p in letter))
        verdicts.append(lazy.verdict(state))
    return verdicts


def test_twenty_propositions_deadline_sequence() -> None:
    formula = _sequence(20, 20)
    eager = translate(formula)  # symbolic letters: twenty propositions compile eagerly too
    lazy = LazyAutomaton(formula)

    def _run(lazy: LazyAutomaton, word: list[frozenset[str]]) -> list[str]:
        verdicts = _run_lazy(lazy, word)
        assert verdicts == [eager.states[s].verdict for s in run_states(eager, word)]
        return verdicts

    assert len(lazy.propositions) == 20
    rng = random.Random(3)
    empty: frozenset[str] = frozenset()
    visits = [frozenset({f"p{i}"}) for i in range(1, 21)]
    good: list[frozenset[str]] = []
    for visit in visits:
        good += [empty] * rng.randint(0, 20) + [visit]
    verdicts = _run(lazy, good)
    assert verdicts[-1] == "satisfied" and set(verdicts[:-1]) == {"pending"}
    assert holds_lasso(formula, Lasso(tuple(good), (empty,)))

    # p1..p6 in time, then p7 missing for 21 steps: violated on the 21st, not before
    prefix = good[: good.index(visits[5]) + 1]
    late = prefix + [empty] * 21
    verdicts = _run(lazy, late)
    assert verdicts[-1] == "violated" and set(verdicts[:-1]) == {"pending"}
    for tail in [empty, *visits]:
        assert not holds_lasso(formula, Lasso(tuple(late), (tail,)))
    in_time = prefix + [empty] * 20 + visits[6:]
    assert holds_lasso(formula, Lasso(tuple(in_time), (empty,)))
    assert _run(lazy, in_time)[-1] == "satisfied"
    assert lazy.num_states <= 20 * 21 + 2


def test_state_limit() -> None:
    with pytest.raises(StateLimitError):
        LazyAutomaton(_sequence(5, 10), max_states=5)
    assert LazyAutomaton(parse("F[0,3] a"), max_states=10).num_states == 1


def test_live_states_are_decided_without_the_whole_automaton() -> None:
    """A live state is proved live by a short accepting cycle, not its whole closure: the
    eager automaton of ``G F p1 & ... & G F pn`` has 3^n states (6561 for n = 8)."""
    lazy = LazyAutomaton(parse(" & ".join(f"G F p{i}" for i in range(1, 21))))
    state, rounds = lazy.initial, [0] * 10
    for step in range(200):
        state, marks = lazy.successor(state, 1 << step % 20)
        assert lazy.verdict(state) == "pending"
        rounds[step // 20] |= marks
    assert rounds[1:] == [(1 << 20) - 1] * 9  # visiting every room in turn: a round each time
    assert lazy.num_explored < 100
    bounded = LazyAutomaton(parse("F[0,100000] a"))
    state = bounded.initial
    for _ in range(50):
        state, _ = bounded.successor(state, 0)
    assert bounded.verdict(state) == "pending"
    assert bounded.num_explored < 60
