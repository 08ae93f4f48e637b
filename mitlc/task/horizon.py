"""How many steps a bounded task needs to be decided, and the note when a horizon is shorter.

A formula without unbounded operators only reads a bounded prefix of the word (Koymans,
"Specifying real-time properties with metric temporal logic", Real-Time Systems 2(4), 1990: the
*temporal depth*): ``p`` reads position 0, ``X φ`` one more than ``φ``, ``F[a,b] φ`` and
``G[a,b] φ`` ``b`` more than ``φ``, and ``φ U[a,b] ψ`` and ``φ R[a,b] ψ`` ``b`` more than the
deeper of the two. Its truth on every word is known once positions ``0 .. depth`` are read, that
is after ``depth + 1`` world steps (a step reads the position it leaves). An episode whose
horizon is shorter may stop with the task still pending, and is then judged on the trace it read
(:func:`mitlc.task.rules.success`: a deadline still open fails).
"""

from __future__ import annotations

from mitlc.syntax import ast


def temporal_depth(formula: ast.Formula) -> int | None:
    """The last position ``formula`` reads (see the module docstring); ``None`` when it has
    an unbounded operator."""
    depth: dict[ast.Formula, int | None] = {}
    for node in ast.subformulas(formula):  # children first
        if node in depth:
            continue
        inner = [depth[child] for child in ast.children(node)]
        if any(d is None for d in inner):
            depth[node] = None
            continue
        deepest = max((d for d in inner if d is not None), default=0)
        match node:
            case ast.Next():
                depth[node] = deepest + 1
            case (
                ast.Eventually(interval)
                | ast.Always(interval)
                | ast.Until(interval)
                | ast.Release(interval)
            ):
                depth[node] = None if interval.hi is None else deepest + interval.hi
            case _:
                depth[node] = deepest
    return depth[formula]


def decision_steps(formula: ast.Formula) -> int | None:
    """The world steps after which a bounded ``formula`` is decided on every word
    (:func:`temporal_depth` plus one); ``None`` for a formula with an unbounded operator."""
    depth = temporal_depth(formula)
    return None if depth is None else depth + 1


def short_horizon_note(formula: ast.Formula, horizon: int) -> str | None:
    """A one-line note when ``horizon`` is shorter than the steps the task needs to be
    decided, or ``None``."""
    needed = decision_steps(formula)
    if needed is None or horizon >= needed:
        return None
    return (
        f"note: the horizon ({horizon} steps) is shorter than the {needed} steps the task needs "
        "to be decided; an episode still pending then is judged on the trace it read (a "
        "deadline still open fails)"
    )
