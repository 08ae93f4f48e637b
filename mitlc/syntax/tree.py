"""A readable indented view of the AST (``mitlc parse`` without ``--json``)."""

from __future__ import annotations

from mitlc.syntax import ast
from mitlc.syntax.printer import interval_text


def node_label(formula: ast.Formula) -> str:
    """One line naming a node: its kind, interval or name, and where it was written."""
    match formula:
        case ast.Bool(value):
            head = f"Bool {'true' if value else 'false'}"
        case ast.Atom(name):
            head = f"Atom {name}"
        case (
            ast.Eventually(interval)
            | ast.Always(interval)
            | ast.Until(interval)
            | ast.Release(interval)
        ):
            head = f"{type(formula).__name__} {interval_text(interval) or '[0,inf)'}"
        case _:
            head = type(formula).__name__
    span = formula.span
    return head if span == ast.NO_SPAN else f"{head}  @{span.line}:{span.column}"


def tree_text(formula: ast.Formula) -> str:
    """The AST drawn as an indented tree, one node a line."""
    lines: list[str] = []
    _draw(formula, "", "", lines)
    return "\n".join(lines)


def _draw(formula: ast.Formula, lead: str, child_lead: str, lines: list[str]) -> None:
    lines.append(lead + node_label(formula))
    kids = ast.children(formula)
    for index, kid in enumerate(kids):
        last = index == len(kids) - 1
        _draw(
            kid,
            child_lead + ("└── " if last else "├── "),
            child_lead + ("    " if last else "│   "),
            lines,
        )
