"""Naming automaton states by their obligation: ``ObligationPattern.parse(text).matches(ob)``.

A cost rule of a world file (:mod:`mitlc.worlds.costs`) names the automaton transitions it
prices by the obligation of their source state, written as ``mitlc compile`` prints a location
of the T-LDGBA (``F[0,5]@x0 b``), with or without its clock names. A location stands for the
digital states that differ only in the time elapsed since its bounded operators were spawned:
at clock value ``v`` a top-level operator written ``F[lo,hi]@x`` is ``F[max(lo - v, 0), hi - v]``
in the digital state's obligation (:mod:`mitlc.automata.fold`). So a pattern matches a digital
obligation when both are the same formula but for the intervals of their top-level temporal
operators (those not under another temporal operator), each of which may be the pattern's
shifted by some ``v`` from ``0`` to ``hi``; operators written with the same clock shift by the
same ``v``, operators written without one shift independently. Everything under a temporal
operator must be equal. Both sides are compared in negation normal form with ``->`` and
``<->`` expanded (:mod:`mitlc.automata.normalize` writes obligations so), and conjunctions and
disjunctions as multisets: their order and parentheses do not matter.

A *letter formula* (a rule's ``when``) is a Boolean formula over propositions, read on one
letter (:func:`letter_holds`).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, TypeAlias

from mitlc.semantics import holds_finite
from mitlc.syntax import ast, parse

Node: TypeAlias = tuple[Any, ...]
"""A formula as nested tuples: ``("and", children)``, ``("or", children)`` (flattened),
``(op, lo, hi, clock, operand...)`` for ``F G U R`` (``hi`` is ``None`` for ``inf``),
``("X", operand)``, ``("atom", name)``, ``("not", atom)``, ``("bool", value)``."""

CLOCK = re.compile(r"@x\d+")
"""A clock name after an interval, as ``mitlc compile`` prints a location's obligation."""
BRACKET = re.compile(r"\[\s*(\d+)\s*,\s*(\d+|inf)\s*[\])](\s*@x\d+)?")
"""An interval written in a formula, and the clock after it if any."""


def without_clocks(text: str) -> str:
    """``text`` with each clock name (``@x0``) blanked out, column positions kept."""
    return CLOCK.sub(lambda m: " " * len(m.group()), text)


@dataclass(frozen=True, slots=True)
class ObligationPattern:
    """A location's obligation (see the module docstring), parsed."""

    text: str
    node: Node

    @staticmethod
    def parse(text: str, filename: str = "<obligation>") -> ObligationPattern:
        """The pattern of ``text``; a :class:`mitlc.errors.SpecError` if it does not parse."""
        formula = parse(without_clocks(text), filename)
        clocks = [
            m.group(3).strip() if m.group(3) else None
            for m in BRACKET.finditer(text)
            if not (m.group(1) == "0" and m.group(2) == "inf")
        ]
        return ObligationPattern(text, _nnf(formula, True, _Clocks(clocks)))

    def atoms(self) -> set[str]:
        """The propositions the pattern names."""
        return set(_atoms(self.node))

    def matches(self, obligation: str) -> bool:
        """Whether a digital state of obligation ``obligation`` (its text) is an instance."""
        return next(_match(self.node, _obligation(obligation), {}, top=True), None) is not None


@lru_cache(maxsize=4096)
def _obligation(text: str) -> Node:
    """A digital state's obligation, parsed (states are asked about once per rule)."""
    return _nnf(parse(text, "<obligation>"), True, _Clocks([]))


class _Clocks:
    """The clocks of a pattern's intervals, handed out in the order they are written."""

    def __init__(self, clocks: list[str | None]) -> None:
        self.clocks, self.next = clocks, 0

    def take(self, interval: ast.Interval) -> str | None:
        if interval.is_trivial:
            return None
        found = self.clocks[self.next] if self.next < len(self.clocks) else None
        self.next += 1
        return found


def _nnf(f: ast.Formula, positive: bool, clocks: _Clocks) -> Node:
    """``f`` (``!f`` when not ``positive``) in negation normal form, read in text order so that
    each interval takes its clock."""
    match f:
        case ast.Bool(value):
            return ("bool", value == positive)
        case ast.Atom(name):
            return ("atom", name) if positive else ("not", ("atom", name))
        case ast.Not(operand):
            return _nnf(operand, not positive, clocks)
        case ast.Next(operand):
            return ("X", _nnf(operand, positive, clocks))
        case ast.And(left, right) | ast.Or(left, right):
            kind = "and" if isinstance(f, ast.And) == positive else "or"
            return _flat(kind, [_nnf(left, positive, clocks), _nnf(right, positive, clocks)])
        case ast.Implies(left, right):
            return _nnf(ast.Or(ast.Not(left), right), positive, clocks)
        case ast.Iff(left, right):
            a, b = _nnf(left, True, clocks), _nnf(right, True, clocks)
            na, nb = _negate(a), _negate(b)
            if positive:
                return _flat("or", [_flat("and", [a, b]), _flat("and", [na, nb])])
            return _flat("or", [_flat("and", [a, nb]), _flat("and", [na, b])])
        case ast.Eventually(interval, operand) | ast.Always(interval, operand):
            kind = "F" if isinstance(f, ast.Eventually) == positive else "G"
            clock = clocks.take(interval)
            return (kind, interval.lo, interval.hi, clock, _nnf(operand, positive, clocks))
        case ast.Until(interval, left, right) | ast.Release(interval, left, right):
            kind = "U" if isinstance(f, ast.Until) == positive else "R"
            first = _nnf(left, positive, clocks)
            clock = clocks.take(interval)
            return (kind, interval.lo, interval.hi, clock, first, _nnf(right, positive, clocks))
    raise TypeError(f"not a formula: {f!r}")


def _negate(node: Node) -> Node:
    """The negation normal form of ``!node`` (``node`` in negation normal form)."""
    kind = node[0]
    dual = {"and": "or", "or": "and", "F": "G", "G": "F", "U": "R", "R": "U"}
    if kind in ("and", "or"):
        return _flat(dual[kind], [_negate(c) for c in node[1]])
    if kind in ("F", "G"):
        return (dual[kind], *node[1:4], _negate(node[4]))
    if kind in ("U", "R"):
        return (dual[kind], *node[1:4], _negate(node[4]), _negate(node[5]))
    if kind == "X":
        return ("X", _negate(node[1]))
    if kind == "bool":
        return ("bool", not node[1])
    return node[1] if kind == "not" else ("not", node)


def _flat(kind: str, children: list[Node]) -> Node:
    """A conjunction or disjunction, its nested ones of the same kind flattened."""
    out: list[Node] = []
    for child in children:
        out.extend(child[1] if child[0] == kind else (child,))
    return (kind, tuple(out))


def _atoms(node: Node) -> Iterator[str]:
    if node[0] == "atom":
        yield node[1]
    for part in node[1:]:
        if isinstance(part, tuple):
            if part and isinstance(part[0], str):
                yield from _atoms(part)
            else:
                for child in part:
                    yield from _atoms(child)


def _key(node: Node) -> Node:
    """``node`` without clocks, conjunctions and disjunctions sorted: equal keys are the same
    formula up to the order of their operands."""
    kind = node[0]
    if kind in ("and", "or"):
        return (kind, tuple(sorted((_key(c) for c in node[1]), key=repr)))
    if kind in ("F", "G", "U", "R"):
        return (kind, node[1], node[2], *(_key(c) for c in node[4:]))
    if kind in ("X", "not"):
        return (kind, _key(node[1]))
    return node


def _shape(node: Node) -> Node:
    """:func:`_key` of a top-level operator without its interval (what a shift keeps)."""
    if node[0] in ("F", "G", "U", "R"):
        return (node[0], *(_key(c) for c in node[4:]))
    return _key(node)


def _match(
    pattern: Node, other: Node, clocks: dict[str, int], *, top: bool
) -> Iterator[dict[str, int]]:
    """The clock values under which ``other`` is an instance of ``pattern`` (see the module
    docstring), extending ``clocks``; none when it is not."""
    kind = pattern[0]
    if kind != other[0]:
        return
    if top and kind in ("and", "or"):
        yield from _match_all(list(pattern[1]), list(other[1]), clocks)
    elif top and kind in ("F", "G", "U", "R"):
        if _shape(pattern) != _shape(other):
            return
        value = _shift(pattern[1], pattern[2], other[1], other[2])
        clock = pattern[3]
        if value is None or (clock is not None and clocks.get(clock, value) != value):
            return
        yield clocks if clock is None else {**clocks, clock: value}
    elif _key(pattern) == _key(other):
        yield clocks


def _match_all(
    patterns: list[Node], others: list[Node], clocks: dict[str, int]
) -> Iterator[dict[str, int]]:
    """The clock values under which ``others`` are instances of ``patterns``, one each."""
    if len(patterns) != len(others):
        return
    if not patterns:
        yield clocks
        return
    first, rest = patterns[0], patterns[1:]
    shape = _shape(first)
    for j, other in enumerate(others):
        if _shape(other) != shape and first[0] not in ("and", "or"):
            continue
        for found in _match(first, other, clocks, top=True):
            yield from _match_all(rest, others[:j] + others[j + 1 :], found)


def _shift(lo: int, hi: int | None, lo2: int, hi2: int | None) -> int | None:
    """The ``v`` with ``[lo2, hi2] = [max(lo - v, 0), hi - v]``, ``0 <= v <= hi``; ``None``
    when there is none (an unbounded interval shifts only by 0)."""
    if hi is None or hi2 is None:
        return 0 if (lo, hi) == (lo2, hi2) else None
    value = hi - hi2
    return value if 0 <= value <= hi and lo2 == max(lo - value, 0) else None


def letter_formula(text: str, filename: str = "<when>") -> ast.Formula:
    """A letter formula (a Boolean formula over propositions), parsed; a
    :class:`mitlc.errors.SpecError` if it does not parse, a ``ValueError`` naming the first
    temporal operator if it has one."""
    formula = parse(text, filename)
    for f in ast.subformulas(formula):
        if isinstance(f, ast.Next | ast.Eventually | ast.Always | ast.Until | ast.Release):
            raise ValueError(f"a letter formula has no temporal operator, found {_name(f)}")
    return formula


def _name(f: ast.Formula) -> str:
    """A temporal operator as written."""
    names = {ast.Next: "X", ast.Eventually: "F", ast.Always: "G", ast.Until: "U"}
    return names.get(type(f), "R")


def letter_holds(formula: ast.Formula, true: set[str] | frozenset[str]) -> bool:
    """Whether the letter formula ``formula`` (no temporal operator: :func:`letter_formula`
    checks it) holds in the letter where exactly ``true`` hold: the finite-trace semantics
    (:func:`mitlc.semantics.holds_finite`) on that one letter."""
    return holds_finite(formula, [frozenset(true)])
