"""From the AST to the term store: negation normal form, and unbounded operators from 0.

``normalize(formula, store)`` pushes negations down to the literals (``!X p`` is the weak next
of ``!p``, true at the end of a trace where the strong ``X p`` is false; ``!F_I p = G_I !p``,
``!(p U_I q) = !p R_I !q``), expands ``->`` and ``<->``, and rewrites an unbounded operator
with a positive lower bound into a bounded one around an unbounded one from 0, so that
progression never shifts an unbounded interval:

* ``F[a,inf) p = X^a F p`` and ``G[a,inf) p = N^a G p`` (``N``: the weak next, a weak delay);
* ``p U[a,inf) q = G[0,a-1] p & X^a (p U q)`` and ``p R[a,inf) q = F[0,a-1] p | N^a (p R q)``.
"""

from __future__ import annotations

from functools import cache

from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, RELEASE, UNTIL, TermStore
from mitlc.syntax import ast


def normalize(formula: ast.Formula, store: TermStore) -> int:
    """The form id of ``formula`` in negation normal form (see the module docstring)."""
    index = {p: i for i, p in enumerate(store.propositions)}

    @cache
    def nnf(f: ast.Formula, positive: bool) -> int:
        match f:
            case ast.Bool(value):
                return store.true if value == positive else store.false
            case ast.Atom(name):
                return store.literal(index[name], positive)
            case ast.Not(operand):
                return nnf(operand, not positive)
            case ast.And(left, right) | ast.Or(left, right):
                conjunction = isinstance(f, ast.And) == positive
                combine = store.and_ if conjunction else store.or_
                return combine(nnf(left, positive), nnf(right, positive))
            case ast.Implies(left, right):
                if positive:
                    return store.or_(nnf(left, False), nnf(right, True))
                return store.and_(nnf(left, True), nnf(right, False))
            case ast.Iff(left, right):
                both = store.and_(nnf(left, True), nnf(right, positive))
                neither = store.and_(nnf(left, False), nnf(right, not positive))
                return store.or_(both, neither)
            case ast.Next(operand):  # LTLf: X is strong, so !X p is the weak next of !p
                return store.delay(1, nnf(operand, positive), strong=positive)
            case ast.Eventually(interval, operand) | ast.Always(interval, operand):
                kind = EVENTUALLY if isinstance(f, ast.Eventually) == positive else ALWAYS
                return temporal(store, kind, interval, nnf(operand, positive))
            case ast.Until(interval, left, right) | ast.Release(interval, left, right):
                kind = UNTIL if isinstance(f, ast.Until) == positive else RELEASE
                return temporal(store, kind, interval, nnf(left, positive), nnf(right, positive))
        raise TypeError(f"not a formula: {f!r}")

    return nnf(formula, True)


def temporal(store: TermStore, kind: str, interval: ast.Interval, left: int, right: int = 0) -> int:
    """A temporal operator on an interval, unbounded ones rewritten to start at 0."""
    lo = interval.lo
    if interval.hi is not None:
        return store.temporal(kind, lo, interval.hi, left, right)
    if lo == 0:
        return store.temporal(kind, 0, INF, left, right)
    strong = kind in (EVENTUALLY, UNTIL)
    if kind in (EVENTUALLY, ALWAYS):
        return store.delay(lo, store.temporal(kind, 0, INF, left), strong)
    tail = store.delay(lo, store.temporal(kind, 0, INF, left, right), strong)
    if kind == UNTIL:
        return store.and_(store.temporal(ALWAYS, 0, lo - 1, left), tail)
    assert kind == RELEASE
    return store.or_(store.temporal(EVENTUALLY, 0, lo - 1, left), tail)
