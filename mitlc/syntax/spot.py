"""Formulas in Spot's LTL syntax, every bounded operator unrolled into ``X``.

Spot has no bounded operators, so each is written out by its definition: ``p U[a,b] q`` holds
when ``q`` holds at some delay ``j`` in ``[a,b]`` and ``p`` at every delay before ``j``;
``F_I q = true U_I q``, ``G_I q = !F_I !q``, ``p R_I q = !(!p U_I !q)``, and
``p U[a,inf) q = p & X p & ... & X^(a-1) p & X^a (p U q)``. The text grows with the bounds
(``F[0,k]`` has ``k + 1`` disjuncts). Used to check mitlc against Spot and to compare with it.
"""

from __future__ import annotations

from mitlc.syntax import ast


def _x(k: int, text: str) -> str:
    """``X^k text``."""
    return "X(" * k + text + ")" * k


def _all(parts: list[str]) -> str:
    return "(" + " & ".join(parts) + ")" if parts else "true"


def _any(parts: list[str]) -> str:
    return "(" + " | ".join(parts) + ")" if parts else "false"


def _until(interval: ast.Interval, p: str, q: str) -> str:
    """``p U_I q``: some ``j`` in ``I`` with ``q`` at ``j`` and ``p`` at every ``k < j``."""
    if interval.hi is None:
        prefix = [_x(k, p) for k in range(interval.lo)]
        return _all([*prefix, _x(interval.lo, f"({p} U {q})")])
    options = [
        _all([_x(j, q)] + [_x(k, p) for k in range(j)]) for j in range(interval.lo, interval.hi + 1)
    ]
    return _any(options)


def to_spot(formula: ast.Formula) -> str:
    """The formula in Spot's LTL syntax, every bounded operator unrolled into ``X``."""
    match formula:
        case ast.Bool(value):
            return "true" if value else "false"
        case ast.Atom(name):
            return '"' + name + '"'
        case ast.Not(operand):
            return f"!{to_spot(operand)}"
        case ast.Next(operand):
            return _x(1, to_spot(operand))
        case ast.Eventually(interval, operand):
            return _until(interval, "true", to_spot(operand))
        case ast.Always(interval, operand):
            return f"!{_until(interval, 'true', '!' + to_spot(operand))}"
        case ast.Until(interval, left, right):
            return _until(interval, to_spot(left), to_spot(right))
        case ast.Release(interval, left, right):
            return f"!{_until(interval, '!' + to_spot(left), '!' + to_spot(right))}"
        case ast.And(left, right):
            return f"({to_spot(left)} & {to_spot(right)})"
        case ast.Or(left, right):
            return f"({to_spot(left)} | {to_spot(right)})"
        case ast.Implies(left, right):
            return f"({to_spot(left)} -> {to_spot(right)})"
        case ast.Iff(left, right):
            return f"({to_spot(left)} <-> {to_spot(right)})"
    raise TypeError(f"not a formula: {formula!r}")


def unrolled_size(formula: ast.Formula) -> int:
    """``len(to_spot(formula))``, computed without building the text, which grows with the
    square of the bounds for until (``p U[k,2k] q`` repeats ``p`` about ``1.5 k^2`` times)."""
    match formula:
        case ast.Bool(value):
            return 4 if value else 5
        case ast.Atom(name):
            return len(name) + 2
        case ast.Not(operand):
            return 1 + unrolled_size(operand)
        case ast.Next(operand):
            return 3 + unrolled_size(operand)
        case ast.Eventually(interval, operand):
            return _until_size(interval, 4, unrolled_size(operand))
        case ast.Always(interval, operand):
            return 1 + _until_size(interval, 4, 1 + unrolled_size(operand))
        case ast.Until(interval, left, right):
            return _until_size(interval, unrolled_size(left), unrolled_size(right))
        case ast.Release(interval, left, right):
            return 1 + _until_size(interval, 1 + unrolled_size(left), 1 + unrolled_size(right))
        case ast.And(left, right) | ast.Or(left, right):
            return 5 + unrolled_size(left) + unrolled_size(right)
        case ast.Implies(left, right):
            return 6 + unrolled_size(left) + unrolled_size(right)
        case ast.Iff(left, right):
            return 7 + unrolled_size(left) + unrolled_size(right)
    raise TypeError(f"not a formula: {formula!r}")


def _join_size(sizes_sum: int, count: int, empty: int) -> int:
    """The length of ``_all``/``_any`` of ``count`` parts whose lengths add to ``sizes_sum``."""
    return 2 + sizes_sum + 3 * (count - 1) if count else empty


def _until_size(interval: ast.Interval, p: int, q: int) -> int:
    lo = interval.lo
    if interval.hi is None:
        prefix = 3 * lo * (lo - 1) // 2 + lo * p
        return _join_size(prefix + 3 * lo + p + q + 5, lo + 1, 4)
    total = 0
    for j in range(lo, interval.hi + 1):
        parts = 3 * j + q + 3 * j * (j - 1) // 2 + j * p
        total += _join_size(parts, j + 1, 4)
    return _join_size(total, interval.hi - lo + 1, 5)
