"""Formula progression, the "after" function: what must hold from the next position on.

``step(form, letter)`` is the formula that the rest of the word must satisfy after ``letter``
has been read at the current position (Bacchus and Kabanza's progression; the ``af`` function
of Esparza, Křetínský and Sickert, JACM 2020), with bounded intervals shifted by one step:

* ``F[lo,hi] p``: ``lo > 0`` gives ``F[lo-1,hi-1] p``; ``lo = 0`` gives ``p' | F[0,hi-1] p``;
* ``G[lo,hi] p``: ``lo > 0`` gives ``G[lo-1,hi-1] p``; ``lo = 0`` gives ``p' & G[0,hi-1] p``;
* ``p U[lo,hi] q``: ``lo > 0`` gives ``p' & p U[lo-1,hi-1] q``; ``lo = 0`` gives
  ``q' | p' & p U[0,hi-1] q``;
* ``p R[lo,hi] q``: the dual, ``p' | p R[lo-1,hi-1] q`` and ``q' & (p' | p R[0,hi-1] q)``;

where ``p'`` is the progression of ``p`` and an interval ending below 0 contributes ``false``
(for ``F``, ``U``) or ``true`` (for ``G``, ``R``); unbounded intervals stay ``[0, inf)``.
"""

from __future__ import annotations

from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore


class Progression:
    """Memoised progression over one term store."""

    def __init__(self, store: TermStore) -> None:
        self.store = store
        self._form_cache: dict[tuple[int, int], int] = {}
        self._atom_cache: dict[tuple[int, int], int] = {}
        self._reads: dict[int, int] = {}

    def step(self, form: int, letter: int) -> int:
        """The progression of ``form`` through ``letter`` (bit ``i``: proposition ``i`` holds)."""
        reads = self._reads.get(form)
        letter &= self.reads(form) if reads is None else reads
        key = (form, letter)
        found = self._form_cache.get(key)
        if found is None:
            found = self.store.substitute(form, lambda atom: self._atom_step(atom, letter))
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

    def _atom_step(self, atom: int, letter: int) -> int:
        key = (atom, letter)
        found = self._atom_cache.get(key)
        if found is None:
            found = self._compute(atom, letter)
            self._atom_cache[key] = found
        return found

    def _compute(self, atom: int, letter: int) -> int:
        store = self.store
        kind, lo, hi, left, right = store.atoms[atom]
        if kind == LIT:
            return store.true if bool(letter >> lo & 1) == bool(hi) else store.false
        later_hi = hi if hi == INF else hi - 1
        if kind in (EVENTUALLY, ALWAYS):
            if lo > 0:  # a delay F[a,a] p ends in p itself; a window keeps its last step
                return store.temporal(kind, lo - 1, later_hi, left, keep_point=lo != hi)
            now = self.step(left, letter)
            if kind == EVENTUALLY:
                rest = (
                    store.false
                    if hi == 0
                    else store.temporal(kind, 0, later_hi, left, keep_point=True)
                )
                return store.or_(now, rest)
            rest = (
                store.true if hi == 0 else store.temporal(kind, 0, later_hi, left, keep_point=True)
            )
            return store.and_(now, rest)
        left_now = self.step(left, letter)
        if kind == UNTIL:
            if lo > 0:
                shifted = store.temporal(kind, lo - 1, later_hi, left, right, keep_point=True)
                return store.and_(left_now, shifted)
            rest = (
                store.false
                if hi == 0
                else store.temporal(kind, 0, later_hi, left, right, keep_point=True)
            )
            return store.or_(self.step(right, letter), store.and_(left_now, rest))
        if lo > 0:
            shifted = store.temporal(kind, lo - 1, later_hi, left, right, keep_point=True)
            return store.or_(left_now, shifted)
        rest = (
            store.true
            if hi == 0
            else store.temporal(kind, 0, later_hi, left, right, keep_point=True)
        )
        return store.and_(self.step(right, letter), store.or_(left_now, rest))
