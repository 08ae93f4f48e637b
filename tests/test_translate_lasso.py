"""The correctness gate of the translation: the automaton accepts a lasso iff the formula holds.

Seeded random (formula, lasso) pairs from :mod:`tests.strategies`, in several families (bounded
formulas, formulas with unbounded operators, G F / F G / response patterns, deep nesting with
small bounds). Each formula is translated once, checked structurally (a deterministic complete
table, jumps only from the initial to the accepting component, a closed accepting component, at
most one violated state, satisfied and violated states true to their verdicts) and against
:func:`mitlc.semantics.holds_lasso` on about ten lassos. A failure is shrunk, greedily, to a
smaller formula and a shorter lasso that still fail, which the assertion message shows.

The default run checks 18,000 pairs (six families of 300 formulas on 10 lassos each); the
``slow`` test (``make verify``) checks 240,000 more, from another seed.
"""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import pytest

from mitlc.automata.digital import DigitalAutomaton
from mitlc.automata.runs import accepts_lasso
from mitlc.semantics import Lasso, Letter, holds_lasso
from mitlc.syntax import ast, to_text
from tests.strategies import ATOMS, random_formula, random_lasso

try:
    from mitlc.automata.ldba import TranslationError, translate
except ModuleNotFoundError as error:  # the translation is not written yet
    if error.name != "mitlc.automata.ldba":
        raise
    pytest.skip("mitlc.automata.ldba is not there yet", allow_module_level=True)

MAX_STATES = 50_000
"""Formulas whose automaton grows past this are skipped (and counted)."""

# --- formula families --------------------------------------------------------------------------


def _small(rng: random.Random) -> ast.Formula:
    """A small operand for the patterns: an atom, or a formula of depth 1 or 2."""
    return random_formula(rng, rng.choice((0, 0, 1, 2)), ATOMS, rng.random() < 0.7, 3)


def _interval(rng: random.Random) -> ast.Interval:
    lo = rng.randint(0, 3)
    kind = rng.random()
    if kind < 0.4:
        return ast.UNBOUNDED
    if kind < 0.6:
        return ast.Interval(lo, None)
    return ast.Interval(lo, rng.randint(lo, 4))


def _pattern(rng: random.Random) -> ast.Formula:
    """One of the usual specification shapes, around small random operands."""
    p, q, r = _small(rng), _small(rng), _small(rng)
    i, u = _interval(rng), ast.UNBOUNDED
    shapes: list[ast.Formula] = [
        ast.Always(u, ast.Eventually(i, p)),
        ast.Eventually(i, ast.Always(u, p)),
        ast.Always(i, ast.Implies(p, ast.Eventually(_interval(rng), q))),
        ast.Always(u, ast.Implies(p, ast.Next(q))),
        ast.And(ast.Always(u, ast.Eventually(u, p)), ast.Always(u, ast.Eventually(u, q))),
        ast.Or(ast.Eventually(u, ast.Always(u, p)), ast.Always(u, ast.Eventually(u, q))),
        ast.Implies(ast.Always(u, ast.Eventually(u, p)), ast.Always(u, ast.Eventually(i, q))),
        ast.Until(i, p, q),
        ast.Release(i, p, q),
        ast.Next(ast.Next(ast.Until(i, p, q))),
        ast.Always(u, ast.Implies(p, ast.Until(i, q, r))),
        ast.Eventually(u, ast.And(p, ast.Next(ast.Always(i, q)))),
        ast.Not(ast.Always(u, ast.Eventually(u, ast.Release(i, p, q)))),
        ast.And(ast.Eventually(i, p), ast.Always(_interval(rng), q)),
        ast.Until(u, ast.Always(u, ast.Eventually(u, p)), q),
    ]
    return rng.choice(shapes)


def _liveness(rng: random.Random, depth: int = 3) -> ast.Formula:
    """A formula whose temporal operators are mostly unbounded: nested G, F, U, R, X."""
    if depth <= 0 or rng.random() < 0.15:
        return ast.Atom(rng.choice(ATOMS)) if rng.random() < 0.9 else ast.Bool(rng.random() < 0.5)

    def sub() -> ast.Formula:
        return _liveness(rng, depth - 1)

    kind = rng.randrange(10)
    if kind < 2:
        return rng.choice((ast.Always, ast.Eventually))(_interval(rng), sub())
    if kind < 4:
        return rng.choice((ast.Until, ast.Release))(_interval(rng), sub(), sub())
    if kind < 6:
        outer, inner = rng.choice(((ast.Always, ast.Eventually), (ast.Eventually, ast.Always)))
        return outer(_interval(rng), inner(_interval(rng), sub()))
    if kind == 6:
        return rng.choice((ast.Not, ast.Next))(sub())
    return rng.choice((ast.And, ast.Or, ast.Implies, ast.Iff))(sub(), sub())


FAMILIES: dict[str, Callable[[random.Random], ast.Formula]] = {
    "bounded": lambda rng: random_formula(rng, 3, ATOMS, True, 4),
    "unbounded": lambda rng: random_formula(rng, 3, ATOMS, False, 4),
    "patterns": _pattern,
    "deep": lambda rng: random_formula(rng, 4, ATOMS, False, 2),
    "liveness": _liveness,
    "mixed": lambda rng: random_formula(rng, rng.randint(2, 4), ATOMS, rng.random() < 0.5, 3),
}


def _lassos(rng: random.Random, count: int) -> list[Lasso]:
    """``count`` random lassos over a, b, c: mostly short, some longer."""
    result = []
    for k in range(count):
        longer = k >= count - 3
        prefix_len = rng.randint(0, 8 if longer else 4)
        loop_len = rng.randint(1, 6 if longer else 3)
        result.append(random_lasso(rng, prefix_len, loop_len, ATOMS))
    return result


# --- checks ------------------------------------------------------------------------------------


def table_problems(aut: DigitalAutomaton) -> list[str]:
    """What keeps ``aut`` from being a deterministic complete table (empty when nothing does)."""
    n, letters = len(aut.states), aut.num_letters
    problems = []
    if not 0 <= aut.initial < n:
        problems.append(f"initial state {aut.initial} of {n}")
    if len(aut.delta) != n or len(aut.marks) != n:
        return [*problems, f"{len(aut.delta)} delta rows, {len(aut.marks)} mark rows, {n} states"]
    for s, (row, mark_row) in enumerate(zip(aut.delta, aut.marks, strict=True)):
        if len(row) != letters or len(mark_row) != letters:
            problems.append(
                f"state {s}: {len(row)} targets, {len(mark_row)} marks, {letters} letters"
            )
            continue
        problems += [
            f"delta[{s}][{x}] = {t} is not a state" for x, t in enumerate(row) if not 0 <= t < n
        ]
        problems += [
            f"marks[{s}][{x}] = {m} with {aut.num_sets} sets"
            for x, m in enumerate(mark_row)
            if not 0 <= m <= aut.all_sets
        ]
    problems += [
        f"jump {j} is not between states" for j in aut.epsilon if not all(0 <= s < n for s in j)
    ]
    return problems


def shape_problems(aut: DigitalAutomaton) -> list[str]:
    """What is wrong with the components and verdicts of the well-formed table ``aut``."""
    states = aut.states
    problems = []
    for s, row in enumerate(aut.delta):
        if states[s].component != "accepting":
            continue
        for x, t in enumerate(row):
            # The one rejecting sink is shared by both components.
            if states[t].component == "initial" and states[t].verdict != "violated":
                problems.append(
                    f"delta[{s}][{x}] = {t} leaves the accepting component for the initial "
                    f"{states[t].verdict} state {t} ({states[t].obligation})"
                )
    for s, t in aut.epsilon:
        if states[s].component != "initial" or states[t].component != "accepting":
            problems.append(f"jump ({s}, {t}) is {states[s].component} -> {states[t].component}")
    violated = [s for s, st in enumerate(states) if st.verdict == "violated"]
    if len(violated) > 1:
        problems.append(f"{len(violated)} violated states {violated[:5]}")
    return problems


def verdict_problems(aut: DigitalAutomaton, lassos: Sequence[Lasso]) -> list[str]:
    """Satisfied states that reject, or violated states that accept, one of ``lassos``."""
    problems = []
    for s, st in enumerate(aut.states):
        if st.verdict == "pending":
            continue
        started = dataclasses.replace(aut, initial=s)
        for word in lassos:
            if accepts_lasso(started, word) != (st.verdict == "satisfied"):
                problems.append(f"{st.verdict} state {s} ({st.obligation}) on {lasso_text(word)}")
                break
    return problems


def lasso_text(word: Lasso) -> str:
    def letter(x: Letter) -> str:
        return "{" + ",".join(sorted(x)) + "}"

    return (
        f"prefix [{' '.join(map(letter, word.prefix))}] loop [{' '.join(map(letter, word.loop))}]"
    )


# --- one failing pair, and its shrinking ---------------------------------------------------------

Outcome = tuple[str, ...]
"""``()`` when a pair is fine; otherwise ``(kind, detail...)``; shrinking keeps ``kind``."""


Translator = Callable[..., DigitalAutomaton]


@dataclass
class Checker:
    """Translates (once per formula) and tells what goes wrong on a pair."""

    translator: Translator = translate
    cache: dict[ast.Formula, DigitalAutomaton | Exception] = field(default_factory=dict)

    def automaton(self, formula: ast.Formula) -> DigitalAutomaton | Exception:
        found = self.cache.get(formula)
        if found is None:
            try:
                found = self.translator(formula, max_states=MAX_STATES)
            except TranslationError as error:
                found = error
            except Exception as error:  # a crash is a failure too; shrink it like the others
                found = RuntimeError(f"{type(error).__name__}: {error}")
            self.cache[formula] = found
        return found

    def outcome(self, formula: ast.Formula, word: Lasso | None) -> Outcome:
        """With ``word``, the failure of the pair; without, that of the automaton's shape."""
        aut = self.automaton(formula)
        if isinstance(aut, TranslationError):
            return ()
        if isinstance(aut, Exception):
            return ("crash", str(aut))
        problems = table_problems(aut)
        if problems:
            return ("table", "; ".join(problems[:3]))
        if word is None:
            problems = shape_problems(aut)
            return ("shape", "; ".join(problems[:2])) if problems else ()
        got, expected = accepts_lasso(aut, word), holds_lasso(formula, word)
        if got != expected:
            verb = {True: "accepts", False: "rejects"}
            return ("disagree", f"automaton {verb[got]}, semantics says {expected}")
        problems = verdict_problems(aut, [word])
        return ("verdict", problems[0]) if problems else ()


def _with_children(f: ast.Formula, kids: Sequence[ast.Formula]) -> ast.Formula:
    names = [fl.name for fl in dataclasses.fields(f) if fl.name not in ("span", "interval")]
    return dataclasses.replace(f, **dict(zip(names, kids, strict=True)))  # type: ignore[arg-type]


def _weight(f: ast.Formula) -> tuple[int, int]:
    """The order shrinking descends: size first, then bounds and atom names."""
    bounds = sum(i.lo + (50 if i.hi is None else i.hi) for i in ast.intervals(f))
    names = sum(ATOMS.index(x.name) + 1 for x in ast.subformulas(f) if isinstance(x, ast.Atom))
    return ast.size(f), bounds + names


def formula_candidates(f: ast.Formula) -> Iterator[ast.Formula]:
    """Formulas a little simpler than ``f``: a leaf, a child, a plainer operator, smaller bounds,
    or one child simplified."""
    yield ast.TRUE
    yield ast.FALSE
    for name in ATOMS:
        yield ast.Atom(name)
    kids = ast.children(f)
    yield from kids
    match f:
        case ast.Until(i, _, right):
            yield ast.Eventually(i, right)
        case ast.Release(i, _, right):
            yield ast.Always(i, right)
        case ast.Implies(left, right) | ast.Iff(left, right):
            yield ast.Or(ast.Not(left), right)
            yield ast.And(left, right)
    if isinstance(f, ast.Eventually | ast.Always | ast.Until | ast.Release):
        lo, hi = f.interval.lo, f.interval.hi
        options = [ast.UNBOUNDED, ast.Interval(lo, lo), ast.Interval(0, hi)]
        if hi is not None and hi > lo:
            options.append(ast.Interval(lo, hi - 1))
        if lo > 0:
            options.append(ast.Interval(lo - 1, hi))
        if hi is None:
            options += [ast.Interval(lo, lo + 1), ast.Interval(0, 0)]
        for interval in options:
            if interval != f.interval:
                yield dataclasses.replace(f, interval=interval)
    for k, kid in enumerate(kids):
        for smaller in formula_candidates(kid):
            yield _with_children(f, [*kids[:k], smaller, *kids[k + 1 :]])


def lasso_candidates(word: Lasso) -> Iterator[Lasso]:
    """Lassos a little shorter or plainer than ``word``."""
    u, v = word.prefix, word.loop
    for k in range(len(u)):
        yield Lasso(u[:k] + u[k + 1 :], v)
    for k in range(len(v)):
        if len(v) > 1:
            yield Lasso(u, v[:k] + v[k + 1 :])
    if u and u[-1] == v[-1]:
        yield Lasso(u[:-1], (v[-1], *v[:-1]))  # the same word, the loop entered earlier
    for k in range(len(v) if len(v) > 1 else 0):
        yield Lasso(u + v[:k], v[k : k + 1])  # a shorter loop, what came before it in the prefix
    for k, x in enumerate(u + v):
        for p in sorted(x):
            smaller = x - {p}
            letters = (*(u + v)[:k], smaller, *(u + v)[k + 1 :])
            yield Lasso(letters[: len(u)], letters[len(u) :])


def _lasso_weight(word: Lasso) -> tuple[int, int, int]:
    return word.size, len(word.loop), sum(len(x) for x in word.letters)


def shrink(
    checker: Checker, formula: ast.Formula, word: Lasso | None, budget: int = 4000
) -> tuple[ast.Formula, Lasso | None, Outcome]:
    """Greedily simplify the failing pair, keeping the kind of failure, within ``budget`` tries."""
    outcome = checker.outcome(formula, word)
    kind = outcome[0]
    progress = True
    while progress and budget > 0:
        progress = False
        for f in formula_candidates(formula):
            budget -= 1
            if budget <= 0:
                break
            if _weight(f) < _weight(formula):
                found = checker.outcome(f, word)
                if found and found[0] == kind:
                    formula, outcome, progress = f, found, True
                    break
        if word is None:
            continue
        for w in lasso_candidates(word):
            budget -= 1
            if budget <= 0:
                break
            if _lasso_weight(w) < _lasso_weight(word):
                found = checker.outcome(formula, w)
                if found and found[0] == kind:
                    word, outcome, progress = w, found, True
                    break
    return formula, word, outcome


# --- the run -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Example:
    """A shrunk failure, and the pair it was shrunk from."""

    kind: str
    detail: str
    formula: ast.Formula
    word: Lasso | None
    original: ast.Formula
    original_word: Lasso | None

    def __str__(self) -> str:
        def on(word: Lasso | None) -> str:
            return f" on {lasso_text(word)}" if word else ""

        return (
            f"  [{self.kind}] formula {to_text(self.formula)!r}{on(self.word)}: {self.detail}\n"
            f"      (from {to_text(self.original)!r}{on(self.original_word)})"
        )


@dataclass
class Report:
    """What one family's run checked and the shrunk counterexamples it found."""

    family: str
    pairs: int = 0
    formulas: int = 0
    skipped: int = 0
    failing_pairs: int = 0
    failures: list[Example] = field(default_factory=list)

    def message(self) -> str:
        head = (
            f"{self.family}: {self.failing_pairs} failing of {self.pairs} pairs "
            f"({self.formulas} formulas, {self.skipped} too large); shrunk counterexamples:"
        )
        return "\n".join([head, *map(str, self.failures)])


def check_family(
    family: str,
    seed: int,
    num_formulas: int,
    lassos_per_formula: int,
    max_failures: int = 3,
    translator: Translator = translate,
) -> Report:
    """Check ``num_formulas`` formulas of ``family`` on ``lassos_per_formula`` lassos each,
    keeping up to ``max_failures`` shrunk counterexamples of each kind of failure."""
    rng = random.Random(f"{family}/{seed}")
    make = FAMILIES[family]
    checker = Checker(translator)
    report = Report(family)
    while report.formulas < num_formulas:
        formula = make(rng)
        lassos = _lassos(rng, lassos_per_formula)
        if isinstance(checker.automaton(formula), TranslationError):
            report.skipped += 1
            continue
        report.formulas += 1
        failing: list[tuple[Lasso | None, Outcome]] = []
        shape = checker.outcome(formula, None)
        if shape:
            failing.append((None, shape))
        if not shape or shape[0] == "shape":
            for word in lassos:
                report.pairs += 1
                found = checker.outcome(formula, word)
                if found:
                    report.failing_pairs += 1
                    failing.append((word, found))
        for failed, found in failing:
            if sum(e.kind == found[0] for e in report.failures) >= max_failures:
                continue
            small_f, small_w, small_o = shrink(checker, formula, failed)
            if any(e.formula == small_f and e.word == small_w for e in report.failures):
                continue
            example = Example(small_o[0], small_o[1], small_f, small_w, formula, failed)
            report.failures.append(example)
    return report


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_translation_agrees_with_semantics(family: str) -> None:
    report = check_family(family, seed=0, num_formulas=300, lassos_per_formula=10)
    assert not report.failures, report.message()
    assert report.pairs >= 3000
    assert report.skipped <= report.formulas // 20, f"{report.skipped} formulas too large"


@pytest.mark.slow
@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_translation_agrees_with_semantics_slow(family: str) -> None:
    report = check_family(family, seed=1, num_formulas=4000, lassos_per_formula=10)
    assert not report.failures, report.message()
    assert report.pairs >= 40_000
    assert report.skipped <= report.formulas // 20, f"{report.skipped} formulas too large"


def _without_jumps(formula: ast.Formula, max_states: int) -> DigitalAutomaton:
    return dataclasses.replace(translate(formula, max_states=max_states), epsilon=())


def _with_wider_bounds(formula: ast.Formula, max_states: int) -> DigitalAutomaton:
    """The automaton of ``formula`` with every bounded interval ``[lo, hi]``, ``hi >= 3``, one
    wider."""

    def widen(f: ast.Formula) -> ast.Formula:
        kids = ast.children(f)
        if kids:
            f = _with_children(f, [widen(k) for k in kids])
        if isinstance(f, ast.Eventually | ast.Always | ast.Until | ast.Release):
            lo, hi = f.interval.lo, f.interval.hi
            if hi is not None and hi >= 3:
                f = dataclasses.replace(f, interval=ast.Interval(lo, hi + 1))
        return f

    return translate(widen(formula), max_states=max_states)


@pytest.mark.parametrize(
    ("family", "planted"), [("patterns", _without_jumps), ("bounded", _with_wider_bounds)]
)
def test_the_gate_catches_and_shrinks_planted_bugs(family: str, planted: Translator) -> None:
    """A translation that drops its jumps, or one off by one in a bound, fails the gate, and
    shrinking brings its counterexamples down to a few operators and letters."""
    report = check_family(
        family, seed=0, num_formulas=60, lassos_per_formula=10, translator=planted
    )
    disagreements = [e for e in report.failures if e.kind == "disagree"]
    assert disagreements, report.message()
    smallest = min(disagreements, key=lambda e: ast.size(e.formula))
    assert ast.size(smallest.formula) <= 4, report.message()
    assert smallest.word is not None and smallest.word.size <= 6, report.message()
