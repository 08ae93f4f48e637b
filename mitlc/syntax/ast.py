"""The MITL abstract syntax tree: immutable nodes with source spans.

Discrete-time MITL over words of sets of atomic propositions (DESIGN.md, "MITL, as mitlc reads
it"). Every temporal operator carries an :class:`Interval` of integer delays; an operator written
without one has ``[0, inf)``.

Spans record where a node was written. They never take part in equality or hashing, so a formula
parsed from its canonical printout compares equal to the original.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TypeAlias


@dataclass(frozen=True, slots=True)
class Span:
    """A region of source text: character offsets, and the 1-based line and column of its start."""

    start: int
    end: int
    line: int
    column: int


NO_SPAN = Span(0, 0, 0, 0)


def _span() -> Span:
    span: Span = field(default=NO_SPAN, compare=False, hash=False, repr=False)
    return span


@dataclass(frozen=True, slots=True)
class Interval:
    """A closed integer interval ``[lo, hi]`` of delays; ``hi is None`` means ``[lo, inf)``."""

    lo: int = 0
    hi: int | None = None

    def __post_init__(self) -> None:
        if self.lo < 0:
            raise ValueError(f"interval lower bound {self.lo} is negative")
        if self.hi is not None and self.hi < self.lo:
            raise ValueError(f"interval [{self.lo},{self.hi}] is empty")

    @property
    def is_unbounded(self) -> bool:
        """True for ``[lo, inf)``."""
        return self.hi is None

    @property
    def is_trivial(self) -> bool:
        """True for ``[0, inf)``, the interval of an operator written without one."""
        return self.lo == 0 and self.hi is None

    def __contains__(self, delay: object) -> bool:
        if not isinstance(delay, int):
            return False
        return self.lo <= delay and (self.hi is None or delay <= self.hi)

    def __str__(self) -> str:
        return f"[{self.lo},inf)" if self.hi is None else f"[{self.lo},{self.hi}]"


UNBOUNDED = Interval(0, None)


@dataclass(frozen=True, slots=True)
class Bool:
    """The constant ``true`` or ``false``."""

    value: bool
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Atom:
    """An atomic proposition such as ``a`` or ``printer``."""

    name: str
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Not:
    """Negation ``!operand``."""

    operand: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Next:
    """``X operand``: the operand holds at the next position."""

    operand: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Eventually:
    """``F_I operand``: the operand holds at some position whose delay lies in ``interval``."""

    interval: Interval
    operand: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Always:
    """``G_I operand``: the operand holds at every position whose delay lies in ``interval``."""

    interval: Interval
    operand: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class And:
    """Conjunction ``left & right``."""

    left: Formula
    right: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Or:
    """Disjunction ``left | right``."""

    left: Formula
    right: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Implies:
    """Implication ``left -> right``."""

    left: Formula
    right: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Iff:
    """Equivalence ``left <-> right``."""

    left: Formula
    right: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Until:
    """``left U_I right``: right holds at a delay in ``interval``, left at every position before."""

    interval: Interval
    left: Formula
    right: Formula
    span: Span = _span()


@dataclass(frozen=True, slots=True)
class Release:
    """``left R_I right``, the dual of until: ``!(!left U_I !right)``."""

    interval: Interval
    left: Formula
    right: Formula
    span: Span = _span()


Formula: TypeAlias = (
    Bool | Atom | Not | Next | Eventually | Always | And | Or | Implies | Iff | Until | Release
)
Unary: TypeAlias = Not | Next | Eventually | Always
Binary: TypeAlias = And | Or | Implies | Iff | Until | Release

TRUE = Bool(True)
FALSE = Bool(False)


def children(formula: Formula) -> tuple[Formula, ...]:
    """The direct subformulas of ``formula``, left to right."""
    match formula:
        case Bool() | Atom():
            return ()
        case Not(operand) | Next(operand) | Eventually(_, operand) | Always(_, operand):
            return (operand,)
        case And(left, right) | Or(left, right) | Implies(left, right) | Iff(left, right):
            return (left, right)
        case Until(_, left, right) | Release(_, left, right):
            return (left, right)
    raise TypeError(f"not a formula: {formula!r}")


def subformulas(formula: Formula) -> Iterator[Formula]:
    """Every subformula of ``formula`` (itself included), children before parents."""
    for child in children(formula):
        yield from subformulas(child)
    yield formula


def atoms(formula: Formula) -> tuple[str, ...]:
    """The atomic propositions of ``formula``, sorted and without repetition."""
    return tuple(sorted({f.name for f in subformulas(formula) if isinstance(f, Atom)}))


def size(formula: Formula) -> int:
    """The number of nodes of ``formula``."""
    return sum(1 for _ in subformulas(formula))


def intervals(formula: Formula) -> Iterator[Interval]:
    """The intervals of the temporal operators of ``formula``, children first."""
    for f in subformulas(formula):
        if isinstance(f, Eventually | Always | Until | Release):
            yield f.interval
