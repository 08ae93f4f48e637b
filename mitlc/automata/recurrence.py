"""A deterministic automaton for ``S & C & G χ_1 & ... & G χ_n``: a breakpoint construction.

When the formula is a conjunction of a safety part ``S`` (no unbounded F or U), a co-safety
part ``C`` (no unbounded G or R) and recurrences ``G χ_i`` whose operands are co-safety, no
guess is needed. ``G χ`` holds iff the obligation ``χ`` started at every position is eventually
met; for each ``χ_i`` the state keeps two conjunctions of pending tokens, in the manner of
Miyano and Hayashi's breakpoint (Theor. Comput. Sci. 32, 1984): ``B``, the tokens started
before the last breakpoint, and ``N``, those started since. Reading a letter,
``B' = af(B)`` and ``N' = af(N & χ)``; a token that fails sends the run to the sink; when ``B'``
is ``true`` every token of the old batch was met, the step is in acceptance set ``i``, and
``N'`` becomes the batch. ``S`` fails into the sink; ``C``, once met, marks the last set on
every step. Examples: ``G F a``, ``G (req -> F done)``, ``G a & F b``, ``G F a & G F b``.

A *renewing* ``χ`` (a disjunction of ``F φ`` with ``φ`` propositional, as in ``G F a`` or
``G (F a | F b)``) needs no tokens: its progression is ``true`` on a letter satisfying some
``φ`` and ``χ`` itself on any other, so every pending token is met at the same step, and
``G χ`` holds iff such letters come infinitely often. Its set is marked on those letters and
its ``B`` and ``N`` stay ``true`` (the generalized Büchi automaton of ``G F φ_1 & ... & G F
φ_n`` with one state, instead of ``3^n``).

An *eventual* ``χ`` is a disjunction of ``F ψ`` whose ``ψ`` owes only strong obligations (no
``G`` or ``R`` atom in its closure: ``G F (a & F b)``, ``G F (a U b)``, ``G F (a & X b)``; every
renewing ``χ`` is one). A finite trace owes one completed ``χ`` (the episode's reading of ``G F
ψ``, :mod:`mitlc.semantics.episode`): its set must have been seen, and its pending tokens, the
renewed obligations, are not owed at the end (:attr:`Recurrence.round_sets`,
:meth:`Recurrence.owed_at_end`, :mod:`mitlc.automata.ends`). The first batch holds the token of
position 0 alone, so the set is first marked exactly when ``χ`` is met from position 0; a pending
token of strong obligations fails at the end, so "the set was seen" is the LTLf value of ``χ``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from mitlc.automata.accepting import closure, unbounded_atoms
from mitlc.automata.terms import ALWAYS, EVENTUALLY, INF, LIT, RELEASE, UNTIL, TermStore


@dataclass(frozen=True, slots=True)
class Recurrence:
    """The split ``S & C & G chi_1 & ... & G chi_n`` of a formula."""

    safety: int
    cosafety: int
    chis: tuple[int, ...]
    renewing: tuple[bool, ...]
    """Per ``chi``: whether it is renewing (module docstring)."""
    eventual: tuple[bool, ...]
    """Per ``chi``: whether it is eventual (module docstring; every renewing one is)."""

    cosafety_set_needed: bool
    """Whether a co-safety part is owed (then it has the last acceptance set)."""

    @property
    def round_sets(self) -> int:
        """The mask of the eventual recurrences' acceptance sets: those a finite trace owes."""
        return sum(1 << i for i, eventual in enumerate(self.eventual) if eventual)

    @property
    def num_sets(self) -> int:
        """One set per recurrence, and one for a co-safety part."""
        return len(self.chis) + int(self.cosafety_set_needed)

    def start(self, store: TermStore) -> tuple[int, ...]:
        """The forms ``(S, C, B_1, N_1, ..., B_n, N_n)`` of the initial state.

        The first batch holds the token of position 0 (``B_i = chi_i``, which ``G chi_i`` owes
        anyway), so the first mark is earned, not given: an empty first batch would mark every
        set on the first step, and a round would look complete before anything happened.
        """
        tokens = [
            form
            for chi, renewing in zip(self.chis, self.renewing, strict=True)
            for form in ((store.true, store.true) if renewing else (chi, store.true))
        ]
        return (self.safety, self.cosafety, *tokens)

    def read_forms(self, store: TermStore, forms: tuple[int, ...]) -> list[int]:
        """The forms whose progressions :meth:`advance` reads: ``S``, ``C``, then per
        ``chi_i`` either ``chi_i`` (renewing) or ``B_i`` and ``N_i & chi_i``."""
        read = [forms[0], forms[1]]
        for i, chi in enumerate(self.chis):
            if self.renewing[i]:
                read.append(chi)
            else:
                read += [forms[2 + 2 * i], store.and_(forms[3 + 2 * i], chi)]
        return read

    def advance(
        self, store: TermStore, progressed: Sequence[int]
    ) -> tuple[tuple[int, ...], int] | None:
        """The successor forms and marks, given the progressions of :meth:`read_forms`
        through a letter (in their order); ``None`` for the sink."""
        safety, cosafety = progressed[0], progressed[1]
        if store.false in (safety, cosafety):
            return None
        marks = 0
        tokens: list[int] = []
        position = 2
        for i in range(len(self.chis)):
            if self.renewing[i]:
                if progressed[position] == store.true:
                    marks |= 1 << i
                tokens += [store.true, store.true]
                position += 1
                continue
            batch, fresh = progressed[position], progressed[position + 1]
            position += 2
            if store.false in (batch, fresh):
                return None
            if batch == store.true:
                marks |= 1 << i
                batch, fresh = fresh, store.true
            tokens += [batch, fresh]
        if self.cosafety_set_needed and cosafety == store.true:
            marks |= 1 << len(self.chis)
        return (safety, cosafety, *tokens), marks

    def obligation(self, store: TermStore, forms: tuple[int, ...]) -> int:
        """What a state owes: ``S & C``, the pending tokens, and every ``G chi``."""
        always = [store.temporal(ALWAYS, 0, INF, chi) for chi in self.chis]
        return store.all_of((*forms, *always))

    def owed_at_end(self, store: TermStore, forms: tuple[int, ...]) -> int:
        """What a stop in a state owes (module docstring): ``S & C`` and the pending tokens of
        the recurrences that are not eventual (an unanswered request of ``G (a -> F b)``)."""
        tokens = [
            form
            for i, eventual in enumerate(self.eventual)
            if not eventual
            for form in forms[2 + 2 * i : 4 + 2 * i]
        ]
        return store.all_of((forms[0], forms[1], *tokens))


def _has(store: TermStore, form: int, kinds: tuple[str, ...]) -> bool:
    for atom in closure(store, form):
        kind, lo, hi, _, _ = store.atoms[atom]
        if kind in kinds and lo == 0 and hi == INF:
            return True
    return False


def split_recurrence(store: TermStore, root: int) -> Recurrence | None:
    """The split of ``root`` (see the module docstring), or ``None`` when it has another shape.

    The atoms common to every cube of ``root`` are the parts, and the disjunction of what
    remains of the cubes one more (``G F a & (b | F[2,inf) c)``: the recurrence, and a
    co-safety part)."""
    cubes = store.forms[root]
    if not cubes:
        return None
    cube = frozenset.intersection(*cubes)
    chis: list[int] = []
    safety, cosafety = [], []
    rest = store.any_of(store.all_of(map(store.atom_form, other - cube)) for other in cubes)
    forms = [(store.atom_form(atom), store.atoms[atom]) for atom in sorted(cube)]
    if rest != store.true:  # the atoms not common to every cube: one more part
        forms.append((rest, ("", 0, 0, 0, 0)))
    for form, (kind, lo, hi, left, _) in forms:
        if not _has(store, form, (EVENTUALLY, UNTIL)):
            safety.append(form)
        elif not _has(store, form, (ALWAYS, RELEASE)):
            cosafety.append(form)
        elif kind == ALWAYS and lo == 0 and hi == INF and not unbounded_atoms(store, left)[1]:
            chis.extend(_conjuncts(store, left))
        else:
            return None
    rest = store.all_of(cosafety)
    renewing = tuple(_is_eventual(store, chi, propositional=True) for chi in chis)
    eventual = tuple(_is_eventual(store, chi, propositional=False) for chi in chis)
    return Recurrence(
        store.all_of(safety), rest, tuple(chis), renewing, eventual, rest != store.true
    )


def _is_eventual(store: TermStore, chi: int, *, propositional: bool) -> bool:
    """Whether ``chi`` is a disjunction of ``F ψ`` with ``ψ`` propositional (renewing), or
    else with no ``G`` or ``R`` atom in ``ψ``'s closure (eventual)."""
    allowed = (LIT,) if propositional else (LIT, EVENTUALLY, UNTIL)
    for cube in store.forms[chi]:
        if len(cube) != 1:
            return False
        (atom,) = cube
        kind, lo, hi, operand, _ = store.atoms[atom]
        if kind != EVENTUALLY or lo != 0 or hi != INF:
            return False
        if any(store.atoms[a][0] not in allowed for a in closure(store, operand)):
            return False
    return bool(store.forms[chi])


def _conjuncts(store: TermStore, form: int) -> list[int]:
    """``G (x & y)`` is ``G x & G y``: one breakpoint each is smaller than one for both."""
    cubes = store.forms[form]
    if len(cubes) != 1:
        return [form]
    (cube,) = cubes
    return [store.atom_form(a) for a in sorted(cube)]
