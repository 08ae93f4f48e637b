"""The lazy automaton against the eager translation: the same states (keys), transitions,
marks, verdicts, end values, and jumps in the same order.

States are paired by walking both automata from the initial state in one order (letters, then
jumps in their order), since the lazy one numbers states as they are asked for. Keys are
compared by structure, the two term stores numbering forms differently. Obligations are
compared through their normal form in one shared term store (or, where the keys are known
equal, as characters): the two translations intern the same formulas in different orders, so
a conjunction may be printed with its conjuncts in another order.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Hashable, Iterable, Iterator
from functools import cache

import pytest

from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.keys import Key, Rules
from mitlc.automata.lazy import LazyAutomaton
from mitlc.automata.ldba import (
    StateLimitError,
    Translation,
    TranslationError,
    translate,
    translate_terms,
)
from mitlc.automata.normalize import normalize
from mitlc.automata.runs import run_states
from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore
from mitlc.semantics import Lasso, holds_lasso
from mitlc.syntax import ast, parse
from mitlc.syntax.parser import read_spec
from tests.strategies import ATOMS, random_formula
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
ISSUE = "G[1,inf) F[1,4] (b R c) R[0,1] G[2,inf) F[1,inf) G[2,inf) F[3,3] b"
JUMPY = (
    "F G a",
    "G F a | F G b",
    "(G F a -> G F b)",
    "F G (a | X b)",
    "F G a & G F b",
    "F G (a U b) | G F c",
    "(a U b) R F G c",
    "G (F a | F G b)",
    "F G a | F G b | F G c",
    "G F[1,3] a -> F G !b",
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


def _key_shapes(store: TermStore) -> Callable[[Key], Hashable]:
    """A key's structure without the store's ids: each form as the set of its cubes, each
    cube the set of its atoms, each atom its operator, interval and operands' structures."""

    @cache
    def form(f: int) -> frozenset[frozenset[Hashable]]:
        return frozenset(frozenset(atom(a) for a in cube) for cube in store.forms[f])

    @cache
    def atom(a: int) -> Hashable:
        kind, x, y, left, right = store.atoms[a]
        if kind == LIT:
            return kind, store.propositions[x], y
        return kind, x, y, form(left), form(right) if kind in (UNTIL, RELEASE) else None

    def key(k: Key) -> Hashable:
        return k.kind, tuple(map(form, k.forms)), tuple((i, form(f)) for i, f in k.seeds)

    return key


def _same_state(
    eager: DigitalAutomaton,
    lazy: LazyAutomaton,
    e: int,
    lz: int,
    canon: Callable[[str], int] | None,
) -> None:
    """Same verdict, component, end value and obligation; the obligations compared through
    their normal form (``canon``), or, without it, as the same characters (the same formula
    printed with its conjuncts in another order, where the keys are known to be equal)."""
    state = eager.states[e]
    assert lazy.verdict(lz) == state.verdict
    assert lazy.component(lz) == state.component
    assert lazy.end(lz) == eager.end(e) == state.end
    obligation = lazy.obligation(lz)
    if obligation != state.obligation:
        if canon is None:
            assert sorted(obligation) == sorted(state.obligation)
        else:
            assert canon(obligation) == canon(state.obligation)


def _same_automaton(formula: ast.Formula, translation: Translation, lazy: LazyAutomaton) -> None:
    """Both automata walked breadth-first from the initial state, over every letter then the
    jumps in their order, pair their states one to one: the same key (structurally: the two
    stores number forms differently), verdict, component, end value and obligation (its
    characters: the print order of conjuncts follows the store), the same marks on every
    letter, and the same jump targets in the same order."""
    eager = translation.automaton
    eager_key, lazy_key = _key_shapes(translation.store), _key_shapes(lazy.store)
    pair, back, order = (
        {eager.initial: lazy.initial},
        {lazy.initial: eager.initial},
        [eager.initial],
    )
    for e in order:  # grows as new states are met
        lz = pair[e]
        assert eager_key(translation.keys[e]) == lazy_key(lazy.key(lz)), formula
        _same_state(eager, lazy, e, lz, None)
        moves = []
        for letter in range(eager.num_letters):
            (et, em), (lt, lm) = eager.successor(e, letter), lazy.successor(lz, letter)
            assert em == lm, formula
            moves.append((et, lt))
        eager_jumps, lazy_jumps = eager.jumps(e), lazy.jumps(lz)
        assert len(eager_jumps) == len(lazy_jumps), formula
        assert sorted(eager_jumps) == list(eager.jumps_from(e))
        moves += zip(eager_jumps, lazy_jumps, strict=True)
        for et, lt in moves:
            if et not in pair:
                assert lt not in back, formula
                pair[et], back[lt] = lt, et
                order.append(et)
            assert pair[et] == lt, formula
    assert lazy.num_states == len(pair), formula
    # the only eager state a walk may miss: a sink that only dead jump targets lead to
    missed = set(range(len(eager.states))) - set(pair)
    assert all(eager.states[s].verdict == "violated" for s in missed) and len(missed) <= 1


def _walk(eager: DigitalAutomaton, lazy: LazyAutomaton, rng: random.Random, steps: int) -> None:
    """A random run of letters and jumps (the same jump by its place), taken in both."""
    canon = _canon(eager.propositions)
    e, lz = eager.initial, lazy.initial
    for _ in range(steps):
        _same_state(eager, lazy, e, lz, canon)
        jumps = eager.jumps(e)
        assert len(jumps) == len(lazy.jumps(lz))
        if jumps and rng.random() < 0.3:
            place = rng.randrange(len(jumps))
            e, lz = jumps[place], lazy.jumps(lz)[place]
            continue
        letter = rng.randrange(eager.num_letters)
        lz, marks = lazy.successor(lz, letter)
        e, eager_marks = eager.successor(e, letter)
        assert marks == eager_marks


def _translated() -> Iterator[tuple[str, ast.Formula, DigitalAutomaton]]:
    for group, formula in _formulas():
        try:
            yield group, formula, translate(formula, max_states=MAX_STATES, minimal=False)
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


def test_lazy_is_the_eager_automaton() -> None:
    for _, formula, eager in CASES:
        if len(eager.states) <= 400:
            _same_automaton(
                formula, translate_terms(formula, minimal=False), LazyAutomaton(formula)
            )


def _sweep(seed: str, count: int) -> Iterator[ast.Formula]:
    """``count`` seeded random formulas: bounded ones, ones with some unbounded operators, and
    persistence ``F G φ`` joined to another (the shape that has epsilon jumps)."""
    rng = random.Random(seed)
    for k in range(count):
        formula = random_formula(rng, rng.randint(2, 4), ATOMS, k % 3 == 0, rng.randint(1, 4))
        if k % 3 == 2:
            unbounded = ast.Interval(0, None)
            persistence = ast.Eventually(unbounded, ast.Always(unbounded, formula))
            other = random_formula(rng, 2, ATOMS, False, 3)
            joined = (ast.Or(persistence, other), ast.And(persistence, other))
            formula = rng.choice((*joined, ast.Until(unbounded, other, persistence)))
        yield formula


def _compare_all(formulas: Iterable[ast.Formula], max_states: int) -> int:
    """Compare the automata of ``formulas`` (those the eager translation builds within
    ``max_states``); how many of them had jumps."""
    jumpy = 0
    for formula in formulas:
        try:
            translation = translate_terms(formula, max_states=max_states, minimal=False)
        except TranslationError:
            continue
        _same_automaton(formula, translation, LazyAutomaton(formula))
        jumpy += bool(translation.automaton.epsilon)
    return jumpy


def test_issue_formula_and_jumps_agree() -> None:
    """The formula of issue 22 (eager and lazy once had 34 and 35 states; 135 since issue 42
    keeps its weak delays ``G[k,k]`` apart from strong ones and keeps the states where a finite
    trace may stop with success), and shapes with epsilon jumps, whose order both automata
    take from the guesses."""
    issue = parse(ISSUE)
    translation = translate_terms(issue, minimal=False)
    assert len(translation.automaton.states) == 135
    _same_automaton(issue, translation, LazyAutomaton(issue))
    assert _compare_all(map(parse, JUMPY), MAX_STATES) == len(JUMPY)


def test_jumps_follow_the_guesses_not_the_numbering() -> None:
    """The eager automaton lists a state's jumps in the order of :meth:`Rules.jumps`, not by
    target id (the artifact's ``epsilon`` stays sorted)."""
    unsorted = 0
    for text in JUMPY:
        translation = translate_terms(parse(text), minimal=False)
        eager, rules = translation.automaton, Rules.of(parse(text), translation.store)
        for state, key in enumerate(translation.keys):
            index = {k: s for s, k in enumerate(translation.keys)}
            expected = [index[k] for k in rules.jumps(key) if k in index]
            assert list(eager.jumps(state)) == expected
            unsorted += expected != sorted(expected)
        assert list(eager.epsilon) == sorted(eager.epsilon)
    assert unsorted > 0


def test_store_forms_do_not_depend_on_the_order() -> None:
    """Either order of multiplying out ``(z | w) & (z | F[0,2] b) & F[0,3] b`` gives one form
    (a leftover cube that only implies another is subsumed); ``G[0,5] a | G[0,4] a`` is
    ``G[0,4] a``; a weak delay beside a window stays (the end values of ``G[2,2] G a`` and
    ``F[1,3] G a`` differ)."""
    store = TermStore(("a", "b", "w", "z"))
    a, b, w, z = (store.literal(i, True) for i in range(4))
    early, late = store.temporal(EVENTUALLY, 0, 2, b), store.temporal(EVENTUALLY, 0, 3, b)
    one = store.and_(store.and_(store.or_(z, w), store.or_(z, early)), late)
    other = store.and_(store.or_(z, w), store.and_(store.or_(z, early), late))
    assert one == other == store.or_(store.and_(z, late), store.and_(w, early))
    windows = store.or_(store.temporal(ALWAYS, 0, 5, a), store.temporal(ALWAYS, 0, 4, a))
    assert windows == store.temporal(ALWAYS, 0, 4, a)
    always_a = store.temporal(ALWAYS, 0, INF, a)
    delay = store.delay(2, always_a, strong=False)
    window = store.temporal(EVENTUALLY, 1, 3, always_a)
    shared = store.temporal(ALWAYS, 0, INF, b)
    ends = store.or_(store.and_(shared, delay), store.and_(shared, window))
    assert len(store.forms[ends]) == 2 and store.end_value(ends)


def test_random_formulas_agree() -> None:
    assert _compare_all(_sweep("lazy-eager", 300), 600) >= 40


@pytest.mark.slow
def test_many_random_formulas_agree() -> None:
    assert _compare_all(_sweep("lazy-eager-slow", 3000), 3_000) >= 400


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
    eager = translate(
        formula, minimal=False
    )  # symbolic letters: twenty propositions compile eagerly too
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


@pytest.mark.parametrize("n", [12, pytest.param(20, marks=pytest.mark.slow)])
def test_live_states_are_decided_without_the_whole_automaton(n: int) -> None:
    """A live state is proved live by a short accepting cycle, not its whole closure: the
    eager automaton of ``G F p1 & ... & G F pn`` has 3^n states (531,441 for n = 12, the
    default run; n = 20 under ``make verify``)."""
    lazy = LazyAutomaton(parse(" & ".join(f"G F p{i}" for i in range(1, n + 1))))
    state, rounds = lazy.initial, [0] * 10
    for step in range(10 * n):
        state, marks = lazy.successor(state, 1 << step % n)
        assert lazy.verdict(state) == "pending"
        rounds[step // n] |= marks
    assert rounds[1:] == [(1 << n) - 1] * 9  # visiting every room in turn: a round each time
    assert lazy.num_explored < 100
    bounded = LazyAutomaton(parse("F[0,100000] a"))
    state = bounded.initial
    for _ in range(50):
        state, _ = bounded.successor(state, 0)
    assert bounded.verdict(state) == "pending"
    assert bounded.num_explored < 60
