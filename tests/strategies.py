"""Random formulas, traces and lassos for property tests: seeded generators and hypothesis
strategies. Test modules import these (``from tests.strategies import random_formula``).

The seeded generators (``random_formula``, ``random_trace``, ``random_lasso``) take a
``random.Random`` so a test that draws from one seed is deterministic; the hypothesis strategies
(``formulas``, ``traces``, ``lassos``) shrink failures to small examples.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence

from hypothesis import strategies as st

from mitlc.semantics import Lasso, Letter
from mitlc.syntax import ast

ATOMS: tuple[str, ...] = ("a", "b", "c")

_UNARY = ("not", "next", "eventually", "always")
_BINARY = ("and", "or", "implies", "iff", "until", "release")


# --- seeded generators ---------------------------------------------------------------------------


def random_interval(rng: random.Random, bounded: bool, max_bound: int) -> ast.Interval:
    """An interval with bounds in ``[0, max_bound]``; when not ``bounded``, a third are
    unbounded, half of those ``[0,inf)``."""
    if not bounded and rng.random() < 1 / 3:
        return ast.Interval(0 if rng.random() < 0.5 else rng.randint(1, max(1, max_bound)), None)
    lo = rng.randint(0, max_bound)
    return ast.Interval(lo, rng.randint(lo, max_bound))


def random_formula(
    rng: random.Random, depth: int, atoms: Sequence[str], bounded: bool, max_bound: int
) -> ast.Formula:
    """A random formula of depth at most ``depth`` over ``atoms``.

    Every operator of the AST appears; leaves are atoms, now and then ``true`` or ``false``.
    With ``bounded`` every interval is ``[lo,hi]`` with ``hi <= max_bound``; without it some
    intervals are ``[lo,inf)``.
    """
    if depth <= 0 or rng.random() < 0.2:
        if rng.random() < 0.1:
            return ast.Bool(rng.random() < 0.5)
        return ast.Atom(rng.choice(list(atoms)))

    def sub() -> ast.Formula:
        return random_formula(rng, depth - 1, atoms, bounded, max_bound)

    if rng.random() < 0.4:
        return _unary(rng.choice(_UNARY), sub(), lambda: random_interval(rng, bounded, max_bound))
    return _binary(
        rng.choice(_BINARY), sub(), sub(), lambda: random_interval(rng, bounded, max_bound)
    )


def _unary(kind: str, operand: ast.Formula, interval: Callable[[], ast.Interval]) -> ast.Formula:
    match kind:
        case "not":
            return ast.Not(operand)
        case "next":
            return ast.Next(operand)
        case "eventually":
            return ast.Eventually(interval(), operand)
        case _:
            return ast.Always(interval(), operand)


def _binary(
    kind: str, left: ast.Formula, right: ast.Formula, interval: Callable[[], ast.Interval]
) -> ast.Formula:
    match kind:
        case "and":
            return ast.And(left, right)
        case "or":
            return ast.Or(left, right)
        case "implies":
            return ast.Implies(left, right)
        case "iff":
            return ast.Iff(left, right)
        case "until":
            return ast.Until(interval(), left, right)
        case _:
            return ast.Release(interval(), left, right)


def random_letter(rng: random.Random, atoms: Sequence[str]) -> Letter:
    """A letter in which each atom holds with probability 1/2."""
    return frozenset(a for a in atoms if rng.random() < 0.5)


def random_trace(rng: random.Random, length: int, atoms: Sequence[str]) -> tuple[Letter, ...]:
    """A finite trace of ``length`` random letters."""
    return tuple(random_letter(rng, atoms) for _ in range(length))


def random_lasso(rng: random.Random, prefix_len: int, loop_len: int, atoms: Sequence[str]) -> Lasso:
    """A lasso with a random prefix of ``prefix_len`` and loop of ``loop_len >= 1`` letters."""
    return Lasso(random_trace(rng, prefix_len, atoms), random_trace(rng, loop_len, atoms))


def horizon(formula: ast.Formula) -> int | None:
    """How many positions after ``i`` the truth at ``i`` can depend on: ``X`` counts 1, a bounded
    operator its upper bound, summed along nesting; ``None`` when an interval is unbounded."""
    match formula:
        case ast.Bool() | ast.Atom():
            return 0
        case ast.Next(operand):
            inner = horizon(operand)
            return None if inner is None else inner + 1
    own = 0
    if isinstance(formula, ast.Eventually | ast.Always | ast.Until | ast.Release):
        if formula.interval.hi is None:
            return None
        own = formula.interval.hi
    inner_horizons = [horizon(child) for child in ast.children(formula)]
    if any(h is None for h in inner_horizons):
        return None
    return own + max(h for h in inner_horizons if h is not None)


# --- hypothesis strategies -----------------------------------------------------------------------


def intervals(bounded: bool = True, max_bound: int = 4) -> st.SearchStrategy[ast.Interval]:
    """Intervals with bounds in ``[0, max_bound]``, some ``[lo,inf)`` unless ``bounded``."""
    closed = st.integers(0, max_bound).flatmap(
        lambda lo: st.builds(ast.Interval, st.just(lo), st.integers(lo, max_bound))
    )
    if bounded:
        return closed
    return closed | st.builds(ast.Interval, st.integers(0, max_bound), st.none())


def formulas(
    atoms: Sequence[str] = ATOMS,
    bounded: bool = True,
    max_bound: int = 4,
    max_leaves: int = 10,
) -> st.SearchStrategy[ast.Formula]:
    """Formulas over ``atoms`` with every operator of the AST (see :func:`random_formula`)."""
    leaves: st.SearchStrategy[ast.Formula] = st.sampled_from(list(atoms)).map(ast.Atom) | st.builds(
        ast.Bool, st.booleans()
    )
    interval = intervals(bounded, max_bound)

    def extend(sub: st.SearchStrategy[ast.Formula]) -> st.SearchStrategy[ast.Formula]:
        return st.one_of(
            st.builds(ast.Not, sub),
            st.builds(ast.Next, sub),
            st.builds(ast.Eventually, interval, sub),
            st.builds(ast.Always, interval, sub),
            st.builds(ast.And, sub, sub),
            st.builds(ast.Or, sub, sub),
            st.builds(ast.Implies, sub, sub),
            st.builds(ast.Iff, sub, sub),
            st.builds(ast.Until, interval, sub, sub),
            st.builds(ast.Release, interval, sub, sub),
        )

    return st.recursive(leaves, extend, max_leaves=max_leaves)


def letters(atoms: Sequence[str] = ATOMS) -> st.SearchStrategy[Letter]:
    """Letters over ``atoms``."""
    return st.frozensets(st.sampled_from(list(atoms)))


def traces(
    atoms: Sequence[str] = ATOMS, min_size: int = 1, max_size: int = 12
) -> st.SearchStrategy[tuple[Letter, ...]]:
    """Finite traces of ``min_size .. max_size`` letters."""
    return st.lists(letters(atoms), min_size=min_size, max_size=max_size).map(tuple)


def lassos(
    atoms: Sequence[str] = ATOMS, max_prefix: int = 4, max_loop: int = 4
) -> st.SearchStrategy[Lasso]:
    """Lassos with up to ``max_prefix`` prefix letters and ``1 .. max_loop`` loop letters."""
    return st.builds(
        Lasso,
        st.lists(letters(atoms), max_size=max_prefix).map(tuple),
        st.lists(letters(atoms), min_size=1, max_size=max_loop).map(tuple),
    )
