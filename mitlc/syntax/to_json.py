"""The AST as plain JSON-ready data (``mitlc parse --json``): one object per node, with spans."""

from __future__ import annotations

from typing import Any

from mitlc.syntax import ast

_OPS: dict[type, str] = {
    ast.Bool: "bool",
    ast.Atom: "atom",
    ast.Not: "not",
    ast.Next: "next",
    ast.Eventually: "eventually",
    ast.Always: "always",
    ast.And: "and",
    ast.Or: "or",
    ast.Implies: "implies",
    ast.Iff: "iff",
    ast.Until: "until",
    ast.Release: "release",
}


def ast_to_data(formula: ast.Formula) -> dict[str, Any]:
    """A nested dict for ``formula``: ``op``, its operands, ``interval`` and ``span``."""
    data: dict[str, Any] = {"op": _OPS[type(formula)]}
    match formula:
        case ast.Bool(value):
            data["value"] = value
        case ast.Atom(name):
            data["name"] = name
        case ast.Not(operand) | ast.Next(operand):
            data["operand"] = ast_to_data(operand)
        case ast.Eventually(interval, operand) | ast.Always(interval, operand):
            data["interval"] = [interval.lo, interval.hi]
            data["operand"] = ast_to_data(operand)
        case ast.Until(interval, left, right) | ast.Release(interval, left, right):
            data["interval"] = [interval.lo, interval.hi]
            data["left"], data["right"] = ast_to_data(left), ast_to_data(right)
        case (
            ast.And(left, right)
            | ast.Or(left, right)
            | ast.Implies(left, right)
            | ast.Iff(left, right)
        ):
            data["left"], data["right"] = ast_to_data(left), ast_to_data(right)
    span = formula.span
    if span != ast.NO_SPAN:
        data["span"] = {
            "start": span.start,
            "end": span.end,
            "line": span.line,
            "column": span.column,
        }
    return data
