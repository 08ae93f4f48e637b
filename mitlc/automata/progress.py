"""Formula progression, the "after" function: what must hold from the next position on.

``step(form, letter)`` is the formula that the rest of the word must satisfy after ``letter``
has been read at the current position (Bacchus and Kabanza's progression; the ``af`` function
of Esparza, Křetínský and Sickert, JACM 2020), with bounded intervals shifted by one step:

* ``F[lo,hi] p``: ``lo > 0`` gives ``F[lo-1,hi-1] p``; ``lo = 0`` gives ``p' | F[0,hi-1] p``;
  a delay's last step ``F[1,1] p`` (``G[1,1] p``) gives ``p`` at the next letter, strong (weak):
  ``p`` itself where its value at the end of a trace is already the delay's
  (:meth:`~mitlc.automata.terms.TermStore.point`);
* ``G[lo,hi] p``: ``lo > 0`` gives ``G[lo-1,hi-1] p``; ``lo = 0`` gives ``p' & G[0,hi-1] p``;
* ``p U[lo,hi] q``: ``lo > 0`` gives ``p' & p U[lo-1,hi-1] q``; ``lo = 0`` gives
  ``q' | p' & p U[0,hi-1] q``;
* ``p R[lo,hi] q``: the dual, ``p' | p R[lo-1,hi-1] q`` and ``q' & (p' | p R[0,hi-1] q)``;

where ``p'`` is the progression of ``p`` and an interval ending below 0 contributes ``false``
(for ``F``, ``U``) or ``true`` (for ``G``, ``R``); unbounded intervals stay ``[0, inf)``.
"""

from __future__ import annotations

from collections.abc import Callable

from mitlc.automata.bdd import Diagrams
from mitlc.automata.terms import (
    ALWAYS,
    EVENTUALLY,
    INF,
    LIT,
    RELEASE,
    SEQUENTIAL_CUBES,
    UNTIL,
    Cube,
    TermStore,
)


class Progression:
    """Memoised progression over one term store.

    The progression of a form is computed once for all letters, as a decision diagram over the
    propositions whose terminals are the progressed forms (:meth:`split`, in the store's
    :class:`~mitlc.automata.bdd.Diagrams`): its terminals are the classes of letters the form
    tells apart. :meth:`step` reads it on one letter."""

    def __init__(self, store: TermStore) -> None:
        self.store = store
        self.diagrams = Diagrams()
        self._splits: dict[int, int] = {}
        self._atom_splits: dict[int, int] = {}
        self._form_cache: dict[tuple[int, int], int] = {}
        self._reads: dict[int, int] = {}

    def step(self, form: int, letter: int) -> int:
        """The progression of ``form`` through ``letter`` (bit ``i``: proposition ``i`` holds)."""
        reads = self._reads.get(form)
        letter &= self.reads(form) if reads is None else reads
        key = (form, letter)
        found = self._form_cache.get(key)
        if found is None:
            found = self.diagrams.evaluate(self.split(form), letter)
            self._form_cache[key] = found
        return found

    def reads(self, form: int) -> int:
        """The mask of the propositions whose value now can change the progression of ``form``."""
        found = self._reads.get(form)
        if found is None:
            found = 0
            for cube in self.store.forms[form]:
                for atom in cube:
                    found |= self._atom_reads(atom)
            self._reads[form] = found
        return found

    def _atom_reads(self, atom: int) -> int:
        kind, a, _, left, right = self.store.atoms[atom]
        if kind == LIT:
            return 1 << a
        if a > 0:  # a delayed operator reads nothing now, but an until's left operand
            return self.reads(left) if kind in (UNTIL, RELEASE) else 0
        operand_reads = self.reads(left)
        return operand_reads | self.reads(right) if kind in (UNTIL, RELEASE) else operand_reads

    def split(self, form: int) -> int:
        """The progression of ``form`` on every letter: a diagram whose terminals are forms.

        A form is the disjunction of its cubes' conjunctions of atoms; each atom's progression
        is combined as :meth:`TermStore.substitute` combines them for one letter (one cube at a
        time, or, past :data:`SEQUENTIAL_CUBES` cubes, the minimal cubes of their union), so
        every terminal is the form that substitution gives on the letters of its class."""
        found = self._splits.get(form)
        if found is None:
            found = self._splits[form] = self._split_form(form)
        return found

    def _split_form(self, form: int) -> int:
        store, d = self.store, self.diagrams
        cubes = store.forms[form]
        if len(cubes) == 1:
            (cube,) = cubes
            if len(cube) == 1:
                (only,) = cube
                return self._atom_split(only)
        if len(cubes) <= SEQUENTIAL_CUBES:
            # or_(false, x) is x: the first conjunction is where the disjunction starts
            result: int | None = None
            for cube in cubes:
                conjunction = self._conjoin(cube)
                result = (
                    conjunction if result is None else d.apply("or", store.or_, result, conjunction)
                )
            return d.leaf(store.false) if result is None else result
        union = d.leaf(frozenset())
        for cube in cubes:
            union = d.apply("union", _union(store), union, self._conjoin(cube))
        return d.map("absorb", store.union_of_cubes, union)

    def _conjoin(self, cube: frozenset[int]) -> int:
        store, d = self.store, self.diagrams
        conjunction: int | None = None  # and_(true, x) is x: the first atom's split starts it
        for atom in cube:
            split = self._atom_split(atom)
            conjunction = (
                split if conjunction is None else d.apply("and", store.and_, conjunction, split)
            )
        return d.leaf(store.true) if conjunction is None else conjunction

    def _atom_split(self, atom: int) -> int:
        found = self._atom_splits.get(atom)
        if found is None:
            found = self._atom_splits[atom] = self._compute(atom)
        return found

    def _compute(self, atom: int) -> int:
        """The progression of one atom (module docstring), as a diagram. It is made once per
        atom (:meth:`_atom_split`), so its diagram operations keep no memo (name ``None``)."""
        store, d = self.store, self.diagrams
        kind, lo, hi, left, right = store.atoms[atom]
        if kind == LIT:
            yes, no = d.leaf(store.true), d.leaf(store.false)
            return d.node(lo, no, yes) if hi else d.node(lo, yes, no)
        later_hi = hi if hi == INF else hi - 1
        if kind in (EVENTUALLY, ALWAYS):
            if lo == hi == 1:  # a delay's last step: its operand at the next letter
                return d.leaf(store.point(kind, left))
            if lo > 0:  # a shorter delay; a window keeps its last step
                return d.leaf(store.temporal(kind, lo - 1, later_hi, left, keep_point=lo != hi))
            now = self.split(left)
            if kind == EVENTUALLY:
                rest = (
                    store.false
                    if hi == 0
                    else store.temporal(kind, 0, later_hi, left, keep_point=True)
                )
                return d.map(None, lambda v: store.or_(v, rest), now)
            rest = (
                store.true if hi == 0 else store.temporal(kind, 0, later_hi, left, keep_point=True)
            )
            return d.map(None, lambda v: store.and_(v, rest), now)
        left_now = self.split(left)
        if kind == UNTIL:
            if lo > 0:
                shifted = store.temporal(kind, lo - 1, later_hi, left, right, keep_point=True)
                return d.map(None, lambda v: store.and_(v, shifted), left_now)
            rest = (
                store.false
                if hi == 0
                else store.temporal(kind, 0, later_hi, left, right, keep_point=True)
            )
            return d.apply(
                None,
                lambda q, p: store.or_(q, store.and_(p, rest)),
                self.split(right),
                left_now,
            )
        if lo > 0:
            shifted = store.temporal(kind, lo - 1, later_hi, left, right, keep_point=True)
            return d.map(None, lambda v: store.or_(v, shifted), left_now)
        rest = (
            store.true
            if hi == 0
            else store.temporal(kind, 0, later_hi, left, right, keep_point=True)
        )
        return d.apply(
            None,
            lambda q, p: store.and_(q, store.or_(p, rest)),
            self.split(right),
            left_now,
        )


def _union(store: TermStore) -> Callable[[frozenset[Cube], int], frozenset[Cube]]:
    def union(found: frozenset[Cube], conjunction: int) -> frozenset[Cube]:
        return found | store.forms[conjunction]

    return union
