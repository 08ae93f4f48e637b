"""Normal forms back to formulas: the readable obligation of a state."""

from __future__ import annotations

from functools import reduce

from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore
from mitlc.syntax import ast


def form_ast(store: TermStore, form: int) -> ast.Formula:
    """The formula of a normal form: a disjunction of conjunctions of atoms."""
    cubes = sorted(store.forms[form], key=lambda cube: (len(cube), sorted(cube)))
    if not cubes:
        return ast.FALSE
    disjuncts = [_cube_ast(store, cube) for cube in cubes]
    return reduce(ast.Or, disjuncts)


def form_text(store: TermStore, form: int) -> str:
    """The canonical text of a normal form (it parses with :func:`mitlc.syntax.parse`): what
    :func:`mitlc.syntax.to_text` prints for :func:`form_ast`, written directly (a state's text
    costs the length of its form, not a syntax tree; operands' texts are memoised)."""
    return _text_level(store, form)[0]


# Binding levels of mitlc.syntax.printer: a larger number binds tighter.
_OR, _AND, _UNTIL, _UNARY, _PRIMARY = 3, 4, 5, 6, 7


def _text_level(store: TermStore, form: int) -> tuple[str, int]:
    """The text of a form and its printer level (when it needs parentheses)."""
    found = store.texts.get(form)
    if found is not None:
        return found
    forms = store.forms[form]
    if not forms:
        result = ("false", _PRIMARY)
    elif len(forms) == 1:
        (cube,) = forms
        result = _cube_text(store, cube)
    else:
        cubes = sorted(forms, key=lambda cube: (len(cube), sorted(cube)))
        # A left-nested disjunction: U/R operands are parenthesised beside a connective.
        parts = []
        for cube in cubes:
            text, level = _cube_text(store, cube)
            parts.append(f"({text})" if level == _UNTIL else text)
        result = (" | ".join(parts), _OR)
    store.texts[form] = result
    return result


def _cube_text(store: TermStore, cube: frozenset[int]) -> tuple[str, int]:
    if len(cube) <= 1:
        return _atom_text_level(store, next(iter(cube))) if cube else ("true", _PRIMARY)
    atoms = [_atom_text_level(store, atom) for atom in sorted(cube)]
    return " & ".join(f"({t})" if level == _UNTIL else t for t, level in atoms), _AND


def _atom_text_level(store: TermStore, atom: int) -> tuple[str, int]:
    kind, lo, hi, left, right = store.atoms[atom]
    if kind == LIT:
        name = store.propositions[lo]
        return (name, _PRIMARY) if hi else ("!" + name, _UNARY)
    interval = "" if lo == 0 and hi == INF else f"[{lo},inf)" if hi == INF else f"[{lo},{hi}]"
    if kind in (EVENTUALLY, ALWAYS):
        operand = _wrapped(store, left, _UNARY)
        if kind == EVENTUALLY and lo == hi == 1:
            return f"X {operand}", _UNARY
        return f"{kind}{interval} {operand}", _UNARY
    assert kind in (UNTIL, RELEASE)
    left_text, right_text = _wrapped(store, left, _UNARY), _wrapped(store, right, _UNTIL)
    return f"{left_text} {kind}{interval} {right_text}", _UNTIL


def _wrapped(store: TermStore, form: int, context: int) -> str:
    text, level = _text_level(store, form)
    return f"({text})" if level < context else text


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
    """The text of one untimed atom (``to_text`` of its formula)."""
    return _atom_text_level(store, atom)[0]


def _operand(store: TermStore, form: int) -> str:
    text = form_text(store, form)
    return f"({text})" if " " in text else text
