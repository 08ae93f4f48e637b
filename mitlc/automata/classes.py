"""The classes of letters that several rows tell apart together: ``Shapes.classes(rows)``.

A location of the T-LDGBA covers several digital states, each with its :class:`Row`; an edge's
letters must take the same transition of every one of them. Those classes are the distinct
tuples ``(rows[0].transition(l), rows[1].transition(l), ...)`` over the letters ``l``; they
depend on the rows' *shapes* (which letters take which transition), not on where the
transitions lead. They are computed, in increasing order of their least letter, by the
cheapest of three exact ways:

* one shape: its transitions are the classes and its paths their cubes;
* few letters (the rows read at most :data:`SMALL_READS` propositions together): each valuation
  of those propositions is read through every shape;
* otherwise the shapes' decision diagrams are combined (:meth:`Diagrams.apply`) and the
  classes are the terminals of the combination (Bryant 1986, as in :mod:`mitlc.automata.bdd`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, TypeAlias

from mitlc.automata.bdd import Diagrams
from mitlc.automata.digital import Row
from mitlc.automata.labels import Letters, submasks

SMALL_READS = 4
"""Rows that read at most this many propositions together are read letter by letter."""


class LetterClasses(NamedTuple):
    """The classes of letters some rows tell apart, by least letter."""

    position: tuple[int, ...]
    """Per row: the position of its shape in each class's transitions."""
    transitions: tuple[tuple[int, ...], ...]
    """Per class: the transition each shape takes on its letters."""
    cubes: tuple[tuple[tuple[int, int], ...], ...]
    """Per class: its letters, as disjoint cubes ``(care, value)``."""
    letters: tuple[Letters, ...]
    """Per class: its letters."""


_Classes: TypeAlias = tuple[
    tuple[tuple[int, ...], ...], tuple[tuple[tuple[int, int], ...], ...], tuple[Letters, ...]
]
"""The transitions, cubes and letters of some classes (:class:`LetterClasses`)."""


_EVERY_LETTER: _Classes = (((0,),), (((0, 0),),), (Letters.everything(),))


def _shape(row: Row) -> tuple[int, tuple[tuple[int, int, int], ...]]:
    return row.root, row.tests


class Shapes:
    """Rows' shapes, each made once as a diagram of one store (terminal ``k``: transition
    ``k``), for the classes of any group of rows."""

    def __init__(self) -> None:
        self._diagrams: Diagrams | None = None  # made when first needed
        self._nodes: dict[tuple[int, tuple[tuple[int, int, int], ...]], int] = {}
        self._single: dict[tuple[int, tuple[tuple[int, int, int], ...]], _Classes] = {}
        self._several: dict[tuple[tuple[int, tuple[tuple[int, int, int], ...]], ...], _Classes] = {}

    def classes(self, rows: Sequence[Row]) -> LetterClasses:
        """The classes of letters ``rows`` tell apart together (module docstring)."""
        first = rows[0]
        if len(rows) == 1:  # most locations: one state
            return self._of_one(first, (0,))
        distinct: dict[tuple[int, tuple[tuple[int, int, int], ...]], int] = {}
        shapes: list[Row] = []
        position = []
        for row in rows:
            shape = _shape(row)
            found = distinct.get(shape)
            if found is None:
                found = distinct[shape] = len(shapes)
                shapes.append(row)
            position.append(found)
        if len(shapes) == 1:
            return self._of_one(shapes[0], tuple(position))
        key = tuple(distinct)
        several = self._several.get(key)
        if several is None:  # locations of one automaton often share their states' shapes
            reads = 0
            for row in shapes:
                reads |= row.reads
            if reads.bit_count() <= SMALL_READS:
                several = self._several[key] = _by_letter(shapes, reads)
            else:
                several = self._several[key] = self._by_diagram(shapes)
        return LetterClasses(tuple(position), *several)

    def _of_one(self, row: Row, position: tuple[int, ...]) -> LetterClasses:
        """One shape: its transitions are the classes, its paths their cubes (made once)."""
        tests = row.tests
        if not tests:  # the same transition on every letter
            return LetterClasses(position, *_EVERY_LETTER)
        if len(tests) == 1:  # one proposition read: its two values
            var, low, high = tests[0]
            bit = 1 << var
            return LetterClasses(
                position,
                ((~low,), (~high,)),
                (((bit, 0),), ((bit, bit),)),
                (Letters(bit, frozenset((0,))), Letters(bit, frozenset((bit,)))),
            )
        single = self._single.get(_shape(row))
        if single is None:
            cubes = tuple(row.cubes())
            transitions = tuple((k,) for k in range(len(cubes)))
            letters = tuple(map(Letters.of_cubes, cubes))
            single = self._single[_shape(row)] = (transitions, cubes, letters)
        return LetterClasses(position, *single)

    def _by_diagram(self, shapes: list[Row]) -> _Classes:
        if self._diagrams is None:
            self._diagrams = Diagrams()
        d = self._diagrams
        together = d.leaf(())
        for row in shapes:
            node = self._nodes.get(_shape(row))
            if node is None:
                node = self._nodes[_shape(row)] = row.into(d, lambda k: k)
            together = d.apply("tuple", lambda t, k: (*t, k), together, node)
        order = {each: i for i, (each, _) in enumerate(d.classes(together))}
        cubes: list[list[tuple[int, int]]] = [[] for _ in order]
        for care, value, each in d.paths(together):
            cubes[order[each]].append((care, value))
        return tuple(order), tuple(map(tuple, cubes)), tuple(map(Letters.of_cubes, cubes))


def _by_letter(shapes: list[Row], reads: int) -> _Classes:
    letters = list(submasks(reads))  # ascending: classes by least letter
    columns = [[row.transition(letter) for letter in letters] for row in shapes]
    order: dict[tuple[int, ...], int] = {}
    members: list[list[int]] = []
    for letter, each in zip(letters, zip(*columns, strict=True), strict=True):
        found = order.get(each)
        if found is None:
            found = order[each] = len(members)
            members.append([])
        members[found].append(letter)
    return (
        tuple(order),
        tuple(tuple((reads, letter) for letter in each) for each in members),
        tuple(Letters.of(reads, each) for each in members),
    )
