"""The explicit per-letter translation, as mitlc computed it before letters were symbolic: a
test oracle for :mod:`mitlc.automata.progress` and the symbolic translation.

:class:`ExplicitProgression` progresses a form through one letter at a time, atom by atom
(Bacchus and Kabanza's progression, the rules of :mod:`mitlc.automata.progress`), with no
decision diagram. :func:`explicit_rules` gives the rules of a translation over its own term
store with that progression, so that their keys compare with the translation's.
"""

from __future__ import annotations

import dataclasses

from mitlc.automata.keys import Rules
from mitlc.automata.ldba import Translation
from mitlc.automata.progress import Progression
from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore
from mitlc.syntax import ast


class ExplicitProgression(Progression):
    """Progression letter by letter (see the module docstring)."""

    def __init__(self, store: TermStore) -> None:
        super().__init__(store)
        self._explicit: dict[tuple[int, int], int] = {}

    def step(self, form: int, letter: int) -> int:
        letter &= self.reads(form)
        found = self._explicit.get((form, letter))
        if found is None:
            found = self.store.substitute(form, lambda atom: self._atom(atom, letter))
            self._explicit[(form, letter)] = found
        return found

    def _atom(self, atom: int, letter: int) -> int:
        store = self.store
        kind, lo, hi, left, right = store.atoms[atom]
        if kind == LIT:
            return store.true if bool(letter >> lo & 1) == bool(hi) else store.false
        later_hi = hi if hi == INF else hi - 1
        if kind in (EVENTUALLY, ALWAYS):
            if lo == hi == 1:  # a delay's last step: strong or weak, at the next letter
                return store.point(kind, left)
            if lo > 0:
                return store.temporal(kind, lo - 1, later_hi, left, keep_point=lo != hi)
            now = self.step(left, letter)
            if hi == 0:
                return now
            rest = store.temporal(kind, 0, later_hi, left, keep_point=True)
            return store.or_(now, rest) if kind == EVENTUALLY else store.and_(now, rest)
        left_now = self.step(left, letter)
        if lo > 0:
            shifted = store.temporal(kind, lo - 1, later_hi, left, right, keep_point=True)
            if kind == UNTIL:
                return store.and_(left_now, shifted)
            return store.or_(left_now, shifted)
        right_now = self.step(right, letter)
        if kind == UNTIL:
            if hi == 0:
                return right_now
            rest = store.temporal(kind, 0, later_hi, left, right, keep_point=True)
            return store.or_(right_now, store.and_(left_now, rest))
        assert kind == RELEASE
        if hi == 0:
            return right_now
        rest = store.temporal(kind, 0, later_hi, left, right, keep_point=True)
        return store.and_(right_now, store.or_(left_now, rest))


def explicit_rules(formula: ast.Formula, translation: Translation) -> Rules:
    """The rules of ``formula`` over ``translation``'s term store, progressing explicitly."""
    rules = Rules.of(formula, translation.store)
    return dataclasses.replace(rules, progression=ExplicitProgression(translation.store))
