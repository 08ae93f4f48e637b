"""Normal forms back to formulas: the readable obligation of a state."""

from __future__ import annotations

from functools import reduce

from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore
from mitlc.syntax import ast, to_text


def form_ast(store: TermStore, form: int) -> ast.Formula:
    """The formula of a normal form: a disjunction of conjunctions of atoms."""
    cubes = sorted(store.forms[form], key=lambda cube: (len(cube), sorted(cube)))
    if not cubes:
        return ast.FALSE
    disjuncts = [_cube_ast(store, cube) for cube in cubes]
    return reduce(ast.Or, disjuncts)


def form_text(store: TermStore, form: int) -> str:
    """The canonical text of a normal form (it parses with :func:`mitlc.syntax.parse`)."""
    return to_text(form_ast(store, form))


def _cube_ast(store: TermStore, cube: frozenset[int]) -> ast.Formula:
    if not cube:
        return ast.TRUE
    return reduce(ast.And, [_atom_ast(store, atom) for atom in sorted(cube)])


def _atom_ast(store: TermStore, atom: int) -> ast.Formula:
    kind, lo, hi, left, right = store.atoms[atom]
    if kind == LIT:
        name = ast.Atom(store.propositions[lo])
        return name if hi else ast.Not(name)
    interval = ast.Interval(lo, None if hi == INF else hi)
    if kind == EVENTUALLY and lo == hi == 1:
        return ast.Next(form_ast(store, left))
    if kind == EVENTUALLY:
        return ast.Eventually(interval, form_ast(store, left))
    if kind == ALWAYS:
        return ast.Always(interval, form_ast(store, left))
    if kind == UNTIL:
        return ast.Until(interval, form_ast(store, left), form_ast(store, right))
    assert kind == RELEASE
    return ast.Release(interval, form_ast(store, left), form_ast(store, right))


def timed_atom_text(
    store: TermStore, kind: str, left: int, right: int, lo: int, hi: int, clock: int
) -> str:
    """A bounded atom whose interval ``[lo,hi]`` is measured from the last reset of a clock,
    written ``F[5,10]@x0 a``, ``!a U[5,10]@x0 a``."""
    interval = f"[{lo},{hi}]@x{clock}"
    if kind in (EVENTUALLY, ALWAYS):
        return f"{kind}{interval} {_operand(store, left)}"
    return f"{_operand(store, left)} {kind}{interval} {_operand(store, right)}"


def atom_text(store: TermStore, atom: int) -> str:
    """The text of one untimed atom."""
    return to_text(_atom_ast(store, atom))


def _operand(store: TermStore, form: int) -> str:
    text = form_text(store, form)
    return f"({text})" if " " in text else text
