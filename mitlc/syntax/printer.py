"""The canonical printer: ``to_text(formula) -> str``, whose output parses back to the same AST.

ASCII operators, intervals written closed (``[5,10]``, ``[5,inf)``) and left out when they are
``[0,inf)``, and the fewest parentheses the precedence and associativity of the grammar allow:
``<->`` (left), ``->`` (right), ``|`` (left), ``&`` (left), ``U``/``R`` (right), unary;
an until or release beside a Boolean connective is parenthesised for the reader.
"""

from __future__ import annotations

from mitlc.syntax import ast

# Binding strength of each level; a larger number binds tighter.
_IFF, _IMPLIES, _OR, _AND, _UNTIL, _UNARY, _PRIMARY = range(1, 8)

_BINARY: dict[type, tuple[int, str, bool]] = {
    # node type: (level, operator, right-associative)
    ast.Iff: (_IFF, "<->", False),
    ast.Implies: (_IMPLIES, "->", True),
    ast.Or: (_OR, "|", False),
    ast.And: (_AND, "&", False),
    ast.Until: (_UNTIL, "U", True),
    ast.Release: (_UNTIL, "R", True),
}


def to_text(formula: ast.Formula) -> str:
    """The canonical text of ``formula``."""
    return _print(formula, 0)


def interval_text(interval: ast.Interval) -> str:
    """``""`` for ``[0,inf)``, else ``[lo,hi]`` or ``[lo,inf)``."""
    return "" if interval.is_trivial else str(interval)


def _level(formula: ast.Formula) -> int:
    if isinstance(formula, ast.Bool | ast.Atom):
        return _PRIMARY
    if isinstance(formula, ast.Not | ast.Next | ast.Eventually | ast.Always):
        return _UNARY
    return _BINARY[type(formula)][0]


def _print(formula: ast.Formula, context: int) -> str:
    text = _print_bare(formula)
    return f"({text})" if _level(formula) < context else text


def _print_bare(formula: ast.Formula) -> str:
    match formula:
        case ast.Bool(value):
            return "true" if value else "false"
        case ast.Atom(name):
            return name
        case ast.Not(operand):
            return "!" + _print(operand, _UNARY)
        case ast.Next(operand):
            return "X " + _print(operand, _UNARY)
        case ast.Eventually(interval, operand):
            return f"F{interval_text(interval)} {_print(operand, _UNARY)}"
        case ast.Always(interval, operand):
            return f"G{interval_text(interval)} {_print(operand, _UNARY)}"
        case ast.Until(interval, left, right) | ast.Release(interval, left, right):
            level, op, _ = _BINARY[type(formula)]
            left_text, right_text = _print(left, level + 1), _print(right, level)
            return f"{left_text} {op}{interval_text(interval)} {right_text}"
        case (
            ast.And(left, right)
            | ast.Or(left, right)
            | ast.Implies(left, right)
            | ast.Iff(left, right)
        ):
            level, op, right_assoc = _BINARY[type(formula)]
            # Beside a Boolean connective an until or release is parenthesised, as Spot does:
            # `(!a U[5,10] a) & (!b U[15,20] b)` reads better than the bare minimum.
            left_level = _UNARY if isinstance(left, ast.Until | ast.Release) else level
            right_level = _UNARY if isinstance(right, ast.Until | ast.Release) else level
            if right_assoc:
                left_level = max(left_level, level + 1)
            else:
                right_level = max(right_level, level + 1)
            return f"{_print(left, left_level)} {op} {_print(right, right_level)}"
    raise TypeError(f"not a formula: {formula!r}")
