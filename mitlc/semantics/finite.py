"""The reference semantics of MITL on finite traces, and the evaluator shared with lassos.

Discrete time, pointwise (DESIGN.md, "MITL, as mitlc reads it"). A word is a sequence of
letters; a letter is the set of propositions true at that position, and position 0 is the first.

* ``(w,i) |= p U_I q`` iff some ``j >= i`` has ``j - i`` in ``I``, ``(w,j) |= q`` and
  ``(w,k) |= p`` for every ``i <= k < j``;
* ``F_I q = true U_I q``, ``G_I q = !F_I !q``, ``p R_I q = !(!p U_I !q)``;
* ``X q`` holds at ``i`` iff ``q`` holds at ``i + 1``.

On a finite trace of ``n`` letters the positions past the end are neutral, as in rtamt's
discrete-time offline semantics: ``U_I`` and ``F_I`` look for ``j`` in ``[i+lo, i+hi]`` and
``[0, n)`` only (none there: false), ``G_I`` and ``R_I`` are their duals (none there: true,
``G[k,k] q`` included), and ``X q`` is LTLf's strong next (De Giacomo and Vardi, IJCAI 2013),
``F[1,1] q``: false at the last position. Negation is exact, so ``!X q`` (the weak next of
``!q``) is true there.

The evaluator works bottom-up over the distinct subformulas, one truth vector per subformula,
on a :class:`Timeline` of canonical positions: a finite trace has nothing after its last position;
a lasso (:mod:`mitlc.semantics.lasso`) continues from its last position at the loop's start.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TypeAlias

from mitlc.errors import MitlcError
from mitlc.syntax import ast

Letter: TypeAlias = frozenset[str]
"""The propositions true at one position."""

Truth: TypeAlias = tuple[bool, ...]
"""A truth value per canonical position."""

_Distances: TypeAlias = list[int | None]


class SemanticsError(MitlcError, ValueError):
    """A word or a position the semantics cannot evaluate: an empty trace, an empty loop, a
    position outside the trace or a negative one."""


# --- the timeline ---------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Timeline:
    """The canonical positions ``0 .. size-1`` of a word and what follows the last of them.

    ``loop_start is None``: a finite trace, nothing follows. Otherwise the word is infinite and
    position ``size`` is position ``loop_start`` again (a lasso with period ``size - loop_start``).
    """

    size: int
    loop_start: int | None = None

    def canonical(self, position: int) -> int | None:
        """The canonical position of ``position >= 0``; ``None`` past the end of a finite trace."""
        if position < self.size:
            return position
        if self.loop_start is None:
            return None
        period = self.size - self.loop_start
        return self.loop_start + (position - self.loop_start) % period


def distances(values: Truth, timeline: Timeline) -> _Distances:
    """For each canonical position ``c``, the least ``d >= 0`` with ``values`` true at ``c + d``.

    ``None`` when there is none: before the end of a finite trace, or ever on a lasso. One backward
    sweep; on a lasso a first sweep over the loop alone finds the distance at the loop's start,
    which is exact because the loop from its start spans a whole period.
    """
    after_last: int | None = None  # the distance at the position that follows the last one
    if timeline.loop_start is not None:
        for c in range(timeline.size - 1, timeline.loop_start - 1, -1):
            after_last = _step_back(values[c], after_last)
    result: _Distances = [None] * timeline.size
    d = after_last
    for c in range(timeline.size - 1, -1, -1):
        d = _step_back(values[c], d)
        result[c] = d
    return result


def _step_back(value: bool, next_distance: int | None) -> int | None:
    if value:
        return 0
    return None if next_distance is None else next_distance + 1


# --- the evaluator --------------------------------------------------------------------------------


def evaluate_on(formula: ast.Formula, letters: Sequence[Letter], timeline: Timeline) -> Truth:
    """The truth of ``formula`` at each canonical position of ``timeline`` (letters are per
    canonical position). Bottom-up over the distinct subformulas, memoised by subformula
    (equal subformulas, spans aside, are evaluated once), without recursion.
    """
    if len(letters) != timeline.size:
        raise SemanticsError(f"{len(letters)} letters for a timeline of {timeline.size} positions")
    memo: dict[ast.Formula, Truth] = {}
    for node in _children_first(formula):
        if node not in memo:
            memo[node] = _evaluate_node(node, memo, letters, timeline)
    return memo[formula]


def _children_first(formula: ast.Formula) -> Iterator[ast.Formula]:
    """Every subformula occurrence, children before parents (an iterative post-order)."""
    stack: list[tuple[ast.Formula, bool]] = [(formula, False)]
    while stack:
        node, expanded = stack.pop()
        if expanded:
            yield node
            continue
        stack.append((node, True))
        stack.extend((child, False) for child in reversed(ast.children(node)))


def _evaluate_node(
    node: ast.Formula, memo: dict[ast.Formula, Truth], letters: Sequence[Letter], line: Timeline
) -> Truth:
    """The truth vector of ``node``, given those of its children in ``memo``."""
    size = line.size
    match node:
        case ast.Bool(value):
            return (value,) * size
        case ast.Atom(name):
            return tuple(name in letter for letter in letters)
        case ast.Not(operand):
            return tuple(not v for v in memo[operand])
        case ast.And(left, right):
            return tuple(x and y for x, y in zip(memo[left], memo[right], strict=True))
        case ast.Or(left, right):
            return tuple(x or y for x, y in zip(memo[left], memo[right], strict=True))
        case ast.Implies(left, right):
            return tuple(not x or y for x, y in zip(memo[left], memo[right], strict=True))
        case ast.Iff(left, right):
            return tuple(x == y for x, y in zip(memo[left], memo[right], strict=True))
        case ast.Next(operand):
            return _next(memo[operand], line)
        case ast.Eventually(interval, operand):
            return until((True,) * size, memo[operand], interval, line)
        case ast.Always(interval, operand):
            return _negate(until((True,) * size, _negate(memo[operand]), interval, line))
        case ast.Until(interval, left, right):
            return until(memo[left], memo[right], interval, line)
        case ast.Release(interval, left, right):
            return _negate(until(_negate(memo[left]), _negate(memo[right]), interval, line))
    raise TypeError(f"not a formula: {node!r}")


def _negate(values: Truth) -> Truth:
    return tuple(not v for v in values)


def _next(operand: Truth, line: Timeline) -> Truth:
    """``X q``: ``q`` at the following position; false at the last position of a finite trace
    (strong)."""
    result = []
    for i in range(line.size):
        following = line.canonical(i + 1)
        result.append(False if following is None else operand[following])
    return tuple(result)


def until(left: Truth, right: Truth, interval: ast.Interval, line: Timeline) -> Truth:
    """``p U_I q`` at every canonical position, from the truth vectors of ``p`` and ``q``.

    Only the earliest ``j >= i + lo`` at which ``q`` holds matters: ``p`` must hold on
    ``[i, j)``, which only gets harder as ``j`` grows. So ``p U_I q`` holds at ``i`` iff that
    ``j`` exists (within a finite trace), ``j <= i + hi``, and the first position ``>= i`` where
    ``p`` fails is not before ``j``. With the distances to the next ``q`` and to the next ``!p``
    this is O(1) per position whatever the bounds; on a lasso it is exact for unbounded and huge
    intervals alike, since a position and its canonical one have the same future.
    """
    to_right = distances(right, line)
    to_left_failure = distances(_negate(left), line)
    lo, hi = interval.lo, interval.hi
    result = []
    for i in range(line.size):
        start = line.canonical(i + lo)
        wait = None if start is None else to_right[start]
        if wait is None:
            result.append(False)
            continue
        j = i + lo + wait
        failure = to_left_failure[i]
        result.append((hi is None or j <= i + hi) and (failure is None or i + failure >= j))
    return tuple(result)


# --- finite traces --------------------------------------------------------------------------------


def evaluate_finite(formula: ast.Formula, trace: Sequence[Letter]) -> Truth:
    """The truth of ``formula`` at every position ``0 .. n-1`` of the finite ``trace``.

    Pointwise discrete-time semantics with rtamt's end-of-trace conventions (module docstring):
    positions past the end are neutral for ``U_I``/``F_I`` (false when none is left) and
    ``G_I``/``R_I`` (true when none is left), and ``X q`` is false at the last position.
    Raises :class:`SemanticsError` for an empty trace.
    """
    if not trace:
        raise SemanticsError("a finite trace needs at least one letter")
    return evaluate_on(formula, trace, Timeline(len(trace)))


def holds_finite(formula: ast.Formula, trace: Sequence[Letter], position: int = 0) -> bool:
    """Whether ``(trace, position) |= formula`` (see :func:`evaluate_finite`).

    Raises :class:`SemanticsError` unless ``0 <= position < len(trace)``.
    """
    if not 0 <= position < len(trace):
        raise SemanticsError(f"position {position} is outside a trace of {len(trace)} letters")
    return evaluate_finite(formula, trace)[position]
