"""The success of an episode, from the formula and the trace alone: the reference reading.

An episode reads a finite trace, one letter per world step, and stops; it succeeds when
(docs/episodes.md):

* the formula holds on the finite trace read, in LTLf with windows
  (:func:`mitlc.semantics.finite.evaluate_finite`: ``X``, ``F``, ``U`` strong; ``G``, ``R``
  weak; ``[lo, inf)`` runs to the last letter);
* except that a **recurrence** ``G χ`` that stands in the formula under ``&`` and ``|`` only
  (as ``G F β``, ``G (F β1 | F β2)`` or a conjunct of ``G (F β & ...)``, also reached through
  negations, ``!F G !β``), where ``χ`` is a disjunction of ``F ψ`` and ``ψ`` owes only
  strong obligations (:func:`_strong`: ``β`` propositional, ``a & F b``, ``a U b``, ``a & X
  b``; no ``G`` or ``R`` but on a single point), reads as ``χ``: ``ψ`` has been met at least
  once. On a finite trace the LTLf value of ``G F β`` is ``β`` at the last letter (of ``G F (a
  & F b)``, ``a`` and ``b`` at the last letter), which would turn a patrol into a question of
  where the episode was cut; the episode reads a round, and the number of completed rounds is
  reported beside success. Every other obligation is owed as LTLf says: a request of ``G (a ->
  F b)`` not yet answered fails.

This module does not look at any automaton: it is the reference that the task monitor, the
gymnasium wrapper, the simulators and the checker are compared with (tests/test_episode_reading.py).
"""

from __future__ import annotations

from collections.abc import Sequence

from mitlc.semantics.finite import Letter, holds_finite
from mitlc.syntax import ast


def episode_formula(formula: ast.Formula) -> ast.Formula:
    """``formula`` with its top-level renewing recurrences read as rounds (module docstring):
    a formula whose LTLf value on a finite trace is the episode's success."""
    return _rewrite(formula, True)


def episode_success(formula: ast.Formula, trace: Sequence[Letter]) -> bool:
    """Whether an episode that read ``trace`` (at least one letter) succeeds (module
    docstring)."""
    return holds_finite(episode_formula(formula), trace)


def _rewrite(f: ast.Formula, positive: bool) -> ast.Formula:
    """``f`` (``!f`` when not ``positive``) with the recurrences at the top read as rounds."""
    match f:
        case ast.Not(operand):
            return _rewrite(operand, not positive)
        case ast.And(left, right) | ast.Or(left, right):
            both = (_rewrite(left, positive), _rewrite(right, positive))
            return ast.And(*both) if isinstance(f, ast.And) == positive else ast.Or(*both)
        case ast.Implies(left, right):
            if positive:
                return ast.Or(_rewrite(left, False), _rewrite(right, True))
            return ast.And(_rewrite(left, True), _rewrite(right, False))
    always = _unbounded_operand(f, ast.Always if positive else ast.Eventually)
    if always is not None:
        parts = [
            part if _renewing(part) else ast.Always(ast.Interval(), part)
            for part in _conjuncts(always, positive)
        ]
        if any(_renewing(part) for part in parts):
            result = parts[0]
            for part in parts[1:]:
                result = ast.And(result, part)
            return result
    return f if positive else ast.Not(f)


def _unbounded_operand(f: ast.Formula, kind: type) -> ast.Formula | None:
    """The operand of ``f`` when it is ``kind`` (``G`` or ``F``) on ``[0, inf)``."""
    if (
        isinstance(f, kind)
        and isinstance(f, ast.Always | ast.Eventually)
        and f.interval.lo == 0
        and f.interval.hi is None
    ):
        return f.operand
    return None


def _conjuncts(f: ast.Formula, positive: bool) -> list[ast.Formula]:
    """The conjuncts of ``f`` (of ``!f`` when not ``positive``), each as a formula."""
    match f:
        case ast.Not(operand):
            return _conjuncts(operand, not positive)
        case ast.And(left, right) if positive:
            return _conjuncts(left, True) + _conjuncts(right, True)
        case ast.Or(left, right) if not positive:
            return _conjuncts(left, False) + _conjuncts(right, False)
        case ast.Implies(left, right) if not positive:
            return _conjuncts(left, True) + _conjuncts(right, False)
    return [f if positive else ast.Not(f)]


def _renewing(f: ast.Formula, positive: bool = True) -> bool:
    """Whether ``f`` (``!f``) is a disjunction of ``F ψ`` on ``[0, inf)``, ``ψ`` strong."""
    match f:
        case ast.Not(operand):
            return _renewing(operand, not positive)
        case ast.Or(left, right) if positive:
            return _renewing(left, True) and _renewing(right, True)
        case ast.And(left, right) if not positive:
            return _renewing(left, False) and _renewing(right, False)
        case ast.Implies(left, right) if positive:
            return _renewing(left, False) and _renewing(right, True)
    inner = _unbounded_operand(f, ast.Eventually if positive else ast.Always)
    return inner is not None and _strong(inner, True)


def _strong(f: ast.Formula, positive: bool) -> bool:
    """Whether ``f`` (``!f``) owes only strong obligations: in negation normal form, no ``G``,
    ``R`` or weak next, but on the single point ``[0, 0]`` (where ``G`` and ``R`` are their
    operand, and ``F`` and ``U`` too)."""
    match f:
        case ast.Bool() | ast.Atom():
            return True
        case ast.Not(operand):
            return _strong(operand, not positive)
        case ast.And(left, right) | ast.Or(left, right):
            return _strong(left, positive) and _strong(right, positive)
        case ast.Implies(left, right):
            return _strong(left, not positive) and _strong(right, positive)
        case ast.Iff(left, right):
            return all(_strong(g, p) for g in (left, right) for p in (True, False))
        case ast.Next(operand):
            return positive and _strong(operand, True)
        case ast.Eventually(interval, operand) | ast.Always(interval, operand):
            point = interval.lo == 0 and interval.hi == 0
            strong = isinstance(f, ast.Eventually) == positive
            return (point or strong) and _strong(operand, positive)
        case ast.Until(interval, left, right) | ast.Release(interval, left, right):
            if interval.lo == 0 and interval.hi == 0:
                return _strong(right, positive)
            strong = isinstance(f, ast.Until) == positive
            return strong and _strong(left, positive) and _strong(right, positive)
    return False
